"""Steps 2-3 of :func:`~bayes_update.core.posterior.sampler.sample`: the likelihood's scales,
the MAP and its Laplace covariance with the curvature adjustment; and the two alone at a
given point (:func:`laplace_at`, what ``calibrate`` reports as each parameter's sd)."""

from __future__ import annotations

import dataclasses
from concurrent.futures import Executor

import numpy as np

from bayes_update.core.adjustment import curvature_adjustment, own_points
from bayes_update.core.checks import ModelFitError, fit_warnings, output_errors, severe_misfit
from bayes_update.core.likelihood import Likelihood, errors_at_mode, estimate_likelihood
from bayes_update.core.logs import info
from bayes_update.core.posterior.laplace import find_map, local_box, map_result
from bayes_update.core.posterior.run import Run, step_seeds
from bayes_update.core.posterior.settings import PosteriorSettings
from bayes_update.core.posterior.target import (
    Evaluate,
)
from bayes_update.core.problem import Problem
from bayes_update.core.steps import StepLog
from bayes_update.data.dataset import Dataset


def laplace_at(
    dataset: Dataset,
    problem: Problem,
    theta: dict,
    settings: PosteriorSettings | None = None,
    *,
    executor: Executor | None = None,
    log=info,
) -> dict:
    """Steps 2-3 of :func:`sample` from ``theta`` (e.g. a calibration's best point): the
    likelihood's scales measured there (noise replicates with the force's noise, the model
    error against ``refined()``), the MAP and its Laplace covariance with the curvature
    adjustment (the tests' disagreement counted).  What :func:`calibrate_model
    <bayes_update.core.calibrate.calibrate_model>` reports as each parameter's sd: an sd
    from the white-noise Gauss-Newton covariance of the fit alone was 9-20x below the scatter
    of its estimates over noise realisations, and 20-150x below their error about the truth,
    on laboratory-like records (coloured noise, a model of 0.1 % discretisation error).

    Returns ``{"mode": {name: value}, "sd": {name: sd}, "covariance": (d, d) internal
    coordinates, "n_model_runs": int, "runs": {step: runs}}`` (units the model's)."""
    from bayes_update.core.identifiability import parameter_sd

    # the fit's own point, never a coarse one: no fit check (calibrate reports its misfit itself)
    settings = dataclasses.replace(settings or PosteriorSettings.quick(), coarse_start=False)
    seeds = step_seeds(settings.seed)
    steps = StepLog()
    run = Run(dataset, problem, problem.space, settings, executor, None, False, log, steps, seeds)
    problem.space.check(theta, "theta")
    lik = likelihood_step(run, theta, None)
    mp, _, adj, _ = mode_step(run, lik, theta)
    cov = adj.covariance(mp.covariance) if adj is not None else mp.covariance
    return {
        "mode": problem.space.to_parameters(mp.x),
        "sd": parameter_sd(problem.space, mp.x, cov),
        "covariance": cov,
        "n_model_runs": sum(steps.runs.values()),
        "runs": dict(steps.runs),
    }


def fit_check(run: Run, theta, where: str) -> None:
    """Does the model fit at all?  A model of the wrong form is told here (after the
    start, or after the MAP when the start is coarse: it fits only part of the
    parameters), not after the design."""
    errors = output_errors(run.problem, theta, executor=run.pool)
    run.steps.add_runs(len(errors))
    run.warnings = fit_warnings(run.problem, theta, errors)
    for w in run.warnings:
        run.log(f"WARNING: {w}")
    severe = severe_misfit(errors, run.problem)
    if severe:
        raise ModelFitError(
            f"the model cannot fit the data: at its best {where} it misses "
            + "; ".join(
                f"test {k} by {100 * e:.0f} % of its rms (noise allows {100 * f:.1f} %)" for k, (e, f) in severe.items()
            )
            + ". A posterior of this model would describe nothing real: check the model's form and units and "
            "the data set's roles, or run `bayes-update discrepancy` with the effects the model may miss"
        )


def likelihood_step(run: Run, start, likelihood) -> Likelihood:
    """2. likelihood scales at the start (unless given)."""
    s, stages = run.settings, run.problem.stages
    with run.steps("likelihood_scales"):
        if likelihood is None:
            lik = estimate_likelihood(
                run.problem,
                start,
                model_error=s.model_error,
                n_replicates=s.n_replicates,
                seed=run.seeds.likelihood,
                space=run.space,
                model_replicates=s.model_replicates,
                executor=run.pool,
            )
            run.steps.add_runs(lik.n_model_runs)
        else:
            if set(likelihood.stages) != set(stages):
                raise ValueError(f"the likelihood covers stages {likelihood.stages}, the data {stages}")
            lik = likelihood
    for st, sc in lik.scales.items():
        run.log(
            f"likelihood {st} at the start: noise sd {100 * sc.noise_sd:.3f} % per direction of the "
            f"parameters' span ({sc.span_rank}), model error {100 * sc.model_error:.3f} %, s = {100 * sc.sd:.3f} %"
        )
    return lik


def mode_step(run: Run, lik: Likelihood, start, remeasure: bool = True):
    """3. MAP, Laplace covariance, local box and the curvature adjustment; the
    model errors of a measured likelihood (discretisation and model form) measured
    at the MAP (:func:`rescaled`) and the mode and its Laplace covariance
    following them."""
    space, s = run.space, run.settings
    with run.steps("map_laplace"):
        ev = Evaluate(run.problem, space, run.problem.stages)
        mp = find_map(
            ev, lik, space.to_internal(start), run.pool, s.map_max_evaluations, progress=False, frugal=s.frugal_map
        )
        run.steps.add_runs(len(run.problem.stages) * mp.n_evaluations)
        if s.coarse_start:
            fit_check(run, space.to_parameters(mp.x), "MAP (from a coarse start)")
        if remeasure and mp.mode is not None and s.model_error:
            lik, mp = rescaled(run, lik, mp)
        box = local_box(space, mp.x, mp.covariance, s.box_sd)
    run.log(
        "MAP: "
        + ", ".join(f"{n} = {v:.4g} {space.units[n]}" for n, v in zip(space.coordinate_names, mp.x))
        + "; Laplace sd: "
        + ", ".join(f"{v:.3g}" for v in np.sqrt(np.diag(mp.covariance)))
    )
    adj = None
    if s.curvature_adjustment and mp.mode is not None:
        adj = curvature_adjustment(
            lik,
            mp.mode.jacobian,
            mp.x,
            np.diff(space.box(), axis=1)[:, 0],
            run.problem.stages,
            names=space.coordinate_names,
            residual=mp.mode.residual,
        )
        if adj is not None:
            run.log(
                "curvature adjustment: error variance / likelihood's along the parameters' directions "
                + ", ".join(f"{v:.2f}" for v in adj.variance_ratios)
                + "; sd x "
                + ", ".join(f"{n} {v:.2f}" for n, v in zip(space.coordinate_names, adj.sd_ratios))
            )
            if adj.between_tests:
                b = adj.between_tests
                run.log(
                    f"the tests disagree beyond their errors (chi^2 {b['chi2']:.1f} > {b['chi2_limit']:.1f}): "
                    "their spread counts as model-form error, sd between tests "
                    + ", ".join(f"{n} {v:.3g}" for n, v in b["between_test_sd"].items())
                )
    return mp, box, adj, lik


#: the mode is searched again with the scales measured at it when, under them, a Gauss-Newton
#: step from it would move it by more than this many sd (the scales change the stages' relative
#: weights: a stage the model misses in form weighs less; where the tests disagree, a small
#: change of weights moves the mode by many of the tests' own sd)
REWEIGHT_SHIFT_SD = 0.1


def rescaled(run: Run, lik: Likelihood, mp):
    """(the likelihood with its model errors measured at the MAP, the MAP result for it):
    the discretisation and model-form errors at the mode
    (:func:`~bayes_update.core.likelihood.errors_at_mode`, one run per stage); the mode's
    residual and Jacobian rescaled to the new scales, and the mode searched again from
    there where the stages' relative weights moved (:data:`REWEIGHT_FACTOR`)."""
    from bayes_update.core.mode import ResidualFunction, SpacePoint, find_mode
    from bayes_update.core.posterior.laplace import FRUGAL_TOLERANCE

    problem, stages, space = run.problem, run.problem.stages, run.space
    n = [problem.output(st, problem.reference_components(st)).size for st in stages]
    own = own_points(mp.mode.jacobian, mp.mode.residual, n, mp.x, space.box())
    new = errors_at_mode(
        problem,
        lik,
        space.to_parameters(mp.x),
        mp.mode.residual,
        mp.mode.jacobian,
        executor=run.pool,
        seed=run.seeds.likelihood,
        own_points={st: space.to_parameters(x) for st, x in zip(stages, own)},
    )
    if new is lik:
        return lik, mp
    # per stage a run at the MAP and one at its own best point, and the refined model's at the MAP
    run.steps.add_runs(len(stages) * (2 + (problem.refined_model() is not None)))
    ratios = np.array([lik.scales[st].sd / new.scales[st].sd for st in stages])
    factor = np.concatenate([np.full(k, f) for k, f in zip(n, ratios)])
    mode = dataclasses.replace(
        mp.mode,
        residual=mp.mode.residual * factor,
        jacobian=mp.mode.jacobian * factor[:, None],
        cost=0.5 * float(np.sum((mp.mode.residual * factor) ** 2)),
    )
    run.log(
        "at the MAP: "
        + "; ".join(
            f"{st} model error {100 * new.scales[st].model_error:.3f} %, "
            f"model form {100 * new.scales[st].model_form_sd:.3f} "
            f"% per direction (noise {100 * new.scales[st].noise_sd:.3f} %): s {100 * lik.scales[st].sd:.3f} -> "
            f"{100 * new.scales[st].sd:.3f} %"
            for st in stages
        )
    )
    n_evaluations = mp.n_evaluations
    step = np.linalg.lstsq(mode.jacobian, -mode.residual, rcond=None)[0]
    shift = float(np.linalg.norm(mode.jacobian @ step))  # in sd of the Laplace approximation
    if shift > REWEIGHT_SHIFT_SD:
        box = space.box()
        fun = ResidualFunction(
            problem, stages, tuple(new.scales[st].sd for st in stages), SpacePoint(space, problem.model)
        )
        mode = find_mode(
            fun,
            [mp.x],
            box[:, 0],
            box[:, 1],
            1e-4 * (box[:, 1] - box[:, 0]),
            run.pool,
            max_iterations=max(5, run.settings.map_max_evaluations // (3 * (len(mp.x) + 1))),
            cost_tolerance=FRUGAL_TOLERANCE,
            central=False,
            known=(mp.x, mode.residual, mode.jacobian),
        )
        run.steps.add_runs(len(stages) * mode.n_evaluations)
        n_evaluations += mode.n_evaluations
        run.log(
            f"the stages' weights moved (x {ratios.max() / ratios.min():.3f}; a step of {shift:.2f} sd): "
            f"the MAP searched again ({mode.n_evaluations} evaluations)"
        )
    return new, map_result(mode, space, space.box(), n_evaluations)
