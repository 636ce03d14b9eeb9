"""The pipeline of :func:`sample` (the package docstring)."""

from __future__ import annotations

import dataclasses
import warnings
from concurrent.futures import Executor
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from bayes_update.core.adjustment import curvature_adjustment, own_points
from bayes_update.core.calibrate import find_start, problem_for
from bayes_update.core.checks import ModelFitError, fit_warnings, output_errors, severe_misfit
from bayes_update.core.kept_start import kept_start
from bayes_update.core.likelihood import Likelihood, errors_at_mode, estimate_likelihood, likelihood_runs
from bayes_update.core.logs import info
from bayes_update.core.model import ModelSpecError
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior.design import build_surrogates, gauss_newton_means
from bayes_update.core.posterior.laplace import capped_covariance, find_map, local_box, map_result
from bayes_update.core.posterior.mcmc import (
    XSampler,
    add_posterior_predictive,
    chain_diagnostics,
    fraction_outside_box,
    initial_walkers,
    run_emcee,
    run_to_convergence,
    summarize,
    to_inference_data,
)
from bayes_update.core.posterior.pointwise import linearisation_check, pointwise_log_likelihood
from bayes_update.core.posterior.predictive import posterior_predictive, prediction_runs
from bayes_update.core.posterior.result import PosteriorResult
from bayes_update.core.posterior.settings import PosteriorSettings
from bayes_update.core.posterior.target import (
    DirectLogPosterior,
    Evaluate,
    ExecutorPool,
    WhitenedEvaluate,
    WhitenedLogPosterior,
    Whitening,
)
from bayes_update.core.problem import Problem
from bayes_update.core.runs import StoreSteps, store_in
from bayes_update.core.sensitivity import sobol_indices
from bayes_update.core.steps import StepLog
from bayes_update.data.dataset import Dataset
from surrogates.evaluation import executor_for


def sample(
    dataset: Dataset,
    model,
    settings: PosteriorSettings | None = None,
    *,
    executor: Executor | None = None,
    workers: int | None = None,
    direct: bool = False,
    start=None,
    space=None,
    likelihood: Likelihood | None = None,
    cache_dir=None,
    metrics: str | None = None,
    progress: bool = True,
    log=info,
) -> PosteriorResult:
    """Sample the posterior of a model's parameters given ``dataset`` (module docstring).

    Parameters
    ----------
    model : any model of the contract (:mod:`bayes_update.core.model`: declared
        ``parameters`` and ``simulate(theta, force, fs)``), e.g. the beam
        (:func:`bayes_update.models.beam.beam_model`).
    space : the prior (default: the model's declared parameters).
    direct : run emcee on the model itself (no surrogate); sensible with a
        model of a few ms per run.
    start : skip the start search and begin at this theta (each parameter in its unit).
    likelihood : use these scales instead of measuring them at the start
        (e.g. to compare a direct and a surrogate posterior under one likelihood).
    cache_dir : folder whose ``runs`` keep every model run (:mod:`bayes_update.core.runs`): a rerun,
        after an interruption or not, makes none of them again, and other commands given the
        same folder share them (``calibrate``'s: its best point is this search's start).
        None: no run is kept.
    metrics : the metric set, ``"paper"`` or ``"full"`` (:mod:`bayes_update.core.problem`;
        default: the model's ``default_metrics``, else ``full``).
    """
    if model is None:
        raise ModelSpecError(
            "no model given: pass a model of the contract (docs/models.md), e.g. "
            "bayes_update.models.beam.beam_model(data)"
        )
    settings = settings or PosteriorSettings()
    store = store_in(cache_dir, "sample") if cache_dir is not None else None
    steps = StoreSteps(store) if store is not None else StepLog()
    with executor_for(executor, workers) as pool:
        with steps("check_and_screen"):
            problem = problem_for(dataset, model, space, metrics, executor=pool, store=store)
            steps.add_runs(1 + problem.n_screen_runs)
        seeds = step_seeds(settings.seed)
        run = _Run(dataset, problem, problem.space, settings, pool, cache_dir, progress, log, steps, seeds)
        start, start_info = _start(run, start)
        lik = _likelihood(run, start, likelihood)
        mp, box, adj, lik = _mode(run, lik, start, remeasure=likelihood is None)
        chain = _direct_chain(run, lik, mp, adj) if direct else _surrogate_chain(run, lik, mp, adj)
        res = _result(run, chain, lik, mp, box, adj, start_info, direct)
        _extras(run, res)
    steps.finish()
    res.timing, res.n_model_runs = steps.timing, steps.runs
    for k, v in getattr(steps, "reused", {}).items():
        res.n_model_runs_reused[k] = res.n_model_runs_reused.get(k, 0) + v
    log("sample: " + steps.line())
    return res


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
    run = _Run(dataset, problem, problem.space, settings, executor, None, False, log, steps, seeds)
    problem.space.check(theta, "theta")
    lik = _likelihood(run, theta, None)
    mp, _, adj, _ = _mode(run, lik, theta)
    cov = adj.covariance(mp.covariance) if adj is not None else mp.covariance
    return {
        "mode": problem.space.to_parameters(mp.x),
        "sd": parameter_sd(problem.space, mp.x, cov),
        "covariance": cov,
        "n_model_runs": sum(steps.runs.values()),
        "runs": dict(steps.runs),
    }


class StepSeeds(NamedTuple):
    """One seed per step of :func:`sample`, spawned from ``settings.seed`` in this order
    (a step's draws do not move when another step draws more or fewer numbers)."""

    likelihood: int  # the noise replicates and the model-form draws
    walkers: int  # the walkers' initial positions
    chain: int  # emcee's moves
    design: int  # the surrogates' design (plus the attempt, on a re-centred box)
    predictive: int  # the posterior-predictive draws
    linear_only: int  # the beam's linear-only posterior
    sobol: int  # the global sensitivity indices
    start: int  # the start search's designs


def step_seeds(seed) -> StepSeeds:
    return StepSeeds(*(int(s.generate_state(1)[0]) for s in np.random.SeedSequence(seed).spawn(len(StepSeeds._fields))))


# ------------------------------------------------------------------ the steps
@dataclass
class _Run:
    """What every step of one :func:`sample` reads: the problem, its prior, the
    settings, the executor, where to cache and log, the step log and the seeds
    (one per step, spawned from ``settings.seed``)."""

    dataset: Dataset
    problem: Problem
    space: ParameterSet
    settings: PosteriorSettings
    pool: object
    cache_dir: object
    progress: bool
    log: object
    steps: StepLog
    seeds: "StepSeeds"
    reused: dict = field(default_factory=dict)  # model runs found in the cache, per design
    warnings: list = field(default_factory=list)  # fit warnings at the start (bayes_update.core.checks)


@dataclass
class _Chain:
    """What a sampling step leaves: the sampler (read in internal coordinates) and,
    on the surrogate path, the surrogates, their design and the local box's record."""

    sampler: object
    burn: int
    thin: int
    gps: dict = field(default_factory=dict)
    design: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    log_likelihood: dict = field(default_factory=dict)  # stage -> (steps, walkers) of the kept draws
    target: object = None  # the surrogate log posterior (u coordinates)


def _start(run: _Run, start) -> tuple[dict, dict]:
    """1. start: the model's own start or the two-stage calibration (unless given)."""
    space = run.space
    with run.steps("start"):
        kept = kept_start(run.problem) if start is None else None
        if kept is not None:
            # another command (calibrate) ran the model on these tests: its best point is the start
            start, n_kept = kept
            run.log(f"start: the best of {n_kept} points another command ran on these tests (the run cache)")
        elif start is None:
            start, n = find_start(
                run.dataset,
                run.problem,
                space,
                n_points=run.settings.n_start,
                seed=run.seeds.start,
                executor=run.pool,
                progress=run.progress,
                log=run.log,
                coarse=run.settings.coarse_start,
            )
            run.steps.add_runs(n)
        else:
            space.check(start, "start")
        info = {n: float(start[n]) for n in space.names}
        if not space.contains(start):
            start = space.to_parameters(np.clip(space.to_internal(start), space.box()[:, 0], space.box()[:, 1]))
        if not run.settings.coarse_start:
            _fit_check(run, start, "start point")
    return start, info


def _fit_check(run: _Run, theta, where: str) -> None:
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


def _likelihood(run: _Run, start, likelihood) -> Likelihood:
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
            run.steps.add_runs(
                likelihood_runs(
                    run.problem, s.n_replicates, run.space, s.model_error, model_replicates=s.model_replicates
                )
            )
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


def _mode(run: _Run, lik: Likelihood, start, remeasure: bool = True):
    """3. MAP, Laplace covariance, local box and the curvature adjustment; the
    model errors of a measured likelihood (discretisation and model form) measured
    at the MAP (:func:`_rescaled`) and the mode and its Laplace covariance
    following them."""
    space, s = run.space, run.settings
    with run.steps("map_laplace"):
        ev = Evaluate(run.problem, space, run.problem.stages)
        mp = find_map(
            ev, lik, space.to_internal(start), run.pool, s.map_max_evaluations, progress=False, frugal=s.frugal_map
        )
        run.steps.add_runs(len(run.problem.stages) * mp.n_evaluations)
        if s.coarse_start:
            _fit_check(run, space.to_parameters(mp.x), "MAP (from a coarse start)")
        if remeasure and mp.mode is not None and s.model_error:
            lik, mp = _rescaled(run, lik, mp)
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


def _rescaled(run: _Run, lik: Likelihood, mp):
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


def _walker_covariance(mp, adj) -> np.ndarray:
    """Where the walkers start: the Laplace covariance at the MAP, widened as the curvature
    adjustment widens the likelihood (the tests' disagreement may make it many times wider)."""
    return mp.covariance if adj is None else adj.covariance(mp.covariance)


def _direct_chain(run: _Run, lik, mp, adj) -> _Chain:
    """4-5, direct path: emcee on the model itself.  Its runs are not kept in the run store:
    a chain on the model makes 10^4-10^6 runs of a model cheap enough for it (a few ms), which
    would fill the cache with responses that cost more to write and read than to make."""
    store, run.problem.run_store = run.problem.run_store, None
    try:
        return _direct_emcee(run, lik, mp, adj)
    finally:
        run.problem.run_store = store


def _direct_emcee(run: _Run, lik, mp, adj) -> _Chain:
    s = run.settings
    with run.steps("mcmc"):
        logp = DirectLogPosterior(Evaluate(run.problem, run.space, run.problem.stages), lik, adj)
        x_init = initial_walkers(
            lambda X: np.array([logp(x)[0] for x in X]),
            mp.x,
            _walker_covariance(mp, adj),
            s.direct_walkers,
            run.seeds.walkers,
            scale=1.0,
        )
        sampler = run_emcee(
            logp,
            x_init,
            s.direct_walkers,
            s.direct_steps,
            run.seeds.chain,
            vectorize=False,
            pool=ExecutorPool(run.pool) if run.pool is not None else None,
            progress=run.progress,
            desc="MCMC on the model",
        )

        def extend(n):
            sampler.run_mcmc(None, n, progress=run.progress, progress_kwargs={"desc": "MCMC on the model (more)"})

        burn, thin, conv = run_to_convergence(
            sampler,
            extend,
            run.space.report,
            s.direct_walkers,
            s.direct_burn,
            1,
            s.direct_steps,
            s.direct_max_steps,
            run.log,
        )
        run.steps.add_runs(len(run.problem.stages) * s.direct_walkers * sampler.iteration)
    blobs = sampler.get_blobs(discard=burn, thin=thin)  # (steps, walkers, stages)
    return _Chain(
        sampler,
        burn,
        thin,
        diagnostics={"convergence": conv},
        log_likelihood={st: blobs[..., i] for i, st in enumerate(run.problem.stages)},
    )


def _surrogate_chain(run: _Run, lik, mp, adj) -> _Chain:
    """4-5, surrogate path: GPs on a design in the whitened local box, emcee on
    them; the box re-centred and widened while it cuts the posterior."""
    s, space, stages = run.settings, run.space, run.problem.stages
    d = len(space.coordinate_names)
    ev = Evaluate(run.problem, space, stages)
    whitening = Whitening.from_covariance(mp.x, capped_covariance(mp.covariance, space, s.box_sd))
    ubox = np.array([[-s.box_sd, s.box_sd]] * d, float)
    run.steps.timing["gp_fit"] = 0.0
    design = None
    for attempt in range(s.box_attempts):
        with run.steps("design_and_gp"):
            means = (
                gauss_newton_means(mp.mode, run.problem, stages, whitening)
                if s.gp_mean == "gauss_newton" and mp.mode is not None
                else None
            )
            earlier = None if design is None else (design["X"], design["z"])
            gps, U, Y, fit_time, n_earlier = build_surrogates(
                WhitenedEvaluate(ev, whitening),
                lik,
                space=space,
                box=ubox,
                whitening=whitening,
                settings=s,
                pool=run.pool,
                cache_dir=None,
                stages=stages,
                seed=run.seeds.design + attempt,
                progress=run.progress,
                log=run.log,
                reused=run.reused,
                means=means,
                earlier=earlier,
            )
            # the earlier box's points were run (and counted) there
            run.steps.add_runs(len(stages) * (int(np.sum(np.all(np.isfinite(Y), axis=1))) - n_earlier))
        run.steps.timing["gp_fit"] += fit_time
        design = {"X": whitening.to_x(U), "z": Y, "whitening": whitening}
        with run.steps("mcmc"):
            logp_u = WhitenedLogPosterior(gps, space, ubox, whitening, adj)
            # the walkers over the (adjusted) Laplace posterior's whole width: from a ball of 0.3 sd
            # the ensemble took longer than a 3000-step chain to spread (R-hat 1.012-1.020)
            L_inv = np.linalg.inv(whitening.L)
            u_init = initial_walkers(
                logp_u,
                whitening.to_u(mp.x)[0],
                L_inv @ _walker_covariance(mp, adj) @ L_inv.T,
                s.n_walkers,
                run.seeds.walkers,
                scale=1.0,
            )
            sampler = run_emcee(
                logp_u,
                u_init,
                s.n_walkers,
                s.n_steps,
                run.seeds.chain,
                vectorize=True,
                progress=run.progress,
                desc="MCMC on the surrogate",
            )
        u_draws = sampler.get_chain(discard=s.burn, flat=True)
        cut = fraction_outside_box(logp_u.gp_points(u_draws), s.box_sd, whitening, space)
        if cut <= 0.01 or attempt == s.box_attempts - 1:
            break
        # the Laplace box cut the posterior (a non-Gaussian posterior, or a MAP short of the
        # mode): re-centre and re-whiten on the surrogate posterior's draws, 3x wider (they are
        # truncated by the old box)
        x_draws = whitening.to_x(u_draws)
        run.log(
            f"the local box cut {100 * cut:.1f} % of the draws: re-centred on them, 3x wider "
            f"(attempt {attempt + 2} of {s.box_attempts})"
        )
        whitening = Whitening.from_covariance(
            x_draws.mean(axis=0), capped_covariance(9.0 * np.cov(x_draws.T), space, s.box_sd)
        )
    with run.steps("mcmc"):
        burn, thin, conv = run_to_convergence(
            sampler,
            lambda n: sampler.extend(logp_u, n, run.progress, "MCMC on the surrogate (more)"),
            lambda U: space.report(whitening.to_x(U)),
            s.n_walkers,
            s.burn,
            s.thin,
            s.n_steps,
            s.max_steps,
            run.log,
        )
    diag = {
        "box_cut_fraction": fraction_outside_box(
            logp_u.gp_points(sampler.get_chain(discard=burn, flat=True)), s.box_sd, whitening, space
        ),
        "box_attempts": attempt + 1,
        "convergence": conv,
    }
    kept = sampler.get_chain(discard=burn, thin=thin)
    G = logp_u.gp_points(kept.reshape(-1, d))
    # z = log(1 + e^2 / s^2) >= 0; the GP's mean may dip a hair below it near the mode
    ll = {
        st: Likelihood.log_likelihood_from_z({st: np.maximum(gp.mean_transformed(G), 0.0)}).reshape(kept.shape[:2])
        for st, gp in gps.items()
    }
    return _Chain(XSampler(sampler, whitening), burn, thin, gps, design, diag, ll, logp_u)


def _result(run: _Run, chain: _Chain, lik, mp, box, adj, start_info, direct) -> PosteriorResult:
    """The chain's diagnostics, ArviZ data and summary."""
    space = run.space
    diag = chain_diagnostics(chain.sampler, chain.burn, space.coordinate_names)
    diag.update(chain.diagnostics)
    diag["thin"] = chain.thin
    diag["curvature_adjustment"] = adj.to_dict() if adj is not None else None
    diag["fit_warnings"] = list(run.warnings)
    draws = chain.sampler.get_chain(discard=chain.burn, thin=chain.thin)
    lp = chain.sampler.get_log_prob(discard=chain.burn, thin=chain.thin)
    problem = run.problem
    names = {st: problem.tests[st].name for st in problem.stages}
    records = list(problem.tests.values()) + list(problem.validation.values())
    observed = {t.name: (t.response, problem.response_unit) for t in records}
    pointwise = None
    if mp.mode is not None:
        flat = draws.reshape(-1, draws.shape[-1])
        pointwise = pointwise_log_likelihood(problem, lik, mp.mode, flat, adj)
        diag["pointwise_linearisation_error"] = linearisation_check(pointwise, chain.log_likelihood, lik, problem)
        pointwise = {names[st]: v.reshape(draws.shape[:2] + (-1,)) for st, v in pointwise.items()}
    idata = to_inference_data(
        draws,
        lp,
        space,
        {
            "source": str(problem.source),
            "direct": int(direct),
            "model": type(problem.model).__name__,
            "metric_set": problem.metrics,
        },
        log_likelihood=pointwise,
        observed=observed,
    )
    summary = summarize(idata, space)
    diag["max_r_hat"] = max(v["r_hat"] for v in summary.values())
    diag["min_ess_bulk"] = min(v["ess_bulk"] for v in summary.values())
    diag["min_ess_tail"] = min(v["ess_tail"] for v in summary.values())
    conv = diag.get("convergence", {})
    if conv and not conv["converged"]:
        msg = (
            f"the chain did not converge within its cap of {conv['n_steps']} steps: R-hat up to "
            f"{diag['max_r_hat']:.4f} (target < 1.01), ESS bulk {diag['min_ess_bulk']:.0f} and tail "
            f"{diag['min_ess_tail']:.0f} (target >= 400); raise max_steps (or direct_max_steps), or look "
            "for a posterior with several modes"
        )
        run.log("WARNING: " + msg)
        warnings.warn(msg, RuntimeWarning)
    if diag.get("box_cut_fraction", 0.0) > 1e-2:
        warnings.warn(
            f"after {diag['box_attempts']} boxes the surrogate's box still cuts "
            f"{100 * diag['box_cut_fraction']:.2f} % of the draws: the posterior is wider than the "
            "Laplace approximation says; raise box_sd or box_attempts",
            RuntimeWarning,
        )
    return PosteriorResult(
        idata=idata,
        summary=summary,
        likelihood=lik,
        space=space,
        map=mp,
        box=box,
        start=start_info,
        diagnostics=diag,
        timing={},
        n_model_runs={},
        n_model_runs_reused=run.reused,
        settings=run.settings,
        direct=direct,
        problem=run.problem,
        surrogates=chain.gps,
        design=chain.design,
        draws=draws.reshape(-1, draws.shape[-1]),
        seeds=run.seeds,
        target=chain.target,
        adjustment=adj,
    )


def _extras(run: _Run, res: PosteriorResult) -> None:
    """Diagnostics beyond the posterior: the predictive check and the global
    sensitivity (each skipped at size 0)."""
    s, stages = run.settings, run.problem.stages
    if s.n_predictive:
        with run.steps("predictive"):
            res.predictive = posterior_predictive(res, s.n_predictive, run.pool, run.seeds.predictive, run.progress)
            run.steps.add_runs(
                prediction_runs(run.problem, s.n_predictive, bool(res.predictive.get("parameters_by_test")))
            )
        draws = res.predictive.get("_draws", {})
        if draws:
            add_posterior_predictive(res.idata, draws, dict.fromkeys(draws, run.problem.response_unit))
        for test, cov in res.predictive.get("coverage", {}).items():
            run.log(
                f"predictive bands, {test}: "
                + ", ".join(f"{sensor} {100 * c['50']:.0f} % / {100 * c['90']:.0f} %" for sensor, c in cov.items())
                + " of the samples inside the 50 % / 90 % bands"
            )
    if s.n_global:
        with run.steps("sensitivity"):
            res.sensitivity = sobol_indices(
                run.problem, run.space, s.n_global, s.sobol_n, run.pool, run.seeds.sobol, run.progress
            )
            run.steps.add_runs(len(stages) * s.n_global)
