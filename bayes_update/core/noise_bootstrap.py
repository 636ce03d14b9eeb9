"""The likelihood's scales measured at the estimate: the parametric bootstrap.

:func:`estimate_likelihood` draws K replicates of the measurement at the
estimate, runs the model on them (and on the sensitivity span's points and the
refined model), and gives each stage its :class:`~bayes_update.core.likelihood_scales.StageScale`;
:func:`likelihood_runs` counts those runs beforehand.  Apart from the scales'
re-measurement at the mode (:mod:`bayes_update.core.mode_errors`): this is the
first, noise-led measurement.  The derivation: :mod:`bayes_update.core.likelihood`.
"""

from __future__ import annotations

import numpy as np

from bayes_update.core.likelihood_scales import Likelihood, StageScale
from bayes_update.core.model_form import periodogram
from bayes_update.core.problem import Problem
from bayes_update.core.replicates import ScalesRun, control_variate_rows, draw_replicates, lti_fit
from bayes_update.core.span import derivative_from, derivative_points, span_of
from surrogates.evaluation import evaluate_many

#: noise replicates whose time-domain residuals give the noise's spectrum (Likelihood.noise_spectra)
SPECTRUM_REPLICATES = 32


# --------------------------------------------------------------------- noise
def noise_scale_from_replicates(e2, max_dof: int) -> tuple[float, float]:
    """(mean of e^2, nu) from replicate values of e^2, assuming e^2 = s^2 chi^2_nu:
    mean = nu s^2 and var = 2 nu s^4 give nu = 2 mean^2 / var, clipped to
    [1, max_dof] (the metric cannot have more directions than regressors)."""
    e2 = np.asarray(e2, float)
    if e2.ndim != 1 or e2.size < 4 or not np.all(np.isfinite(e2)) or np.any(e2 < 0):
        raise ValueError("need at least 4 finite non-negative replicate values of e^2")
    mean = float(e2.mean())
    var = float(e2.var(ddof=1))
    nu = float(np.clip(2 * mean**2 / var, 1.0, max_dof)) if var > 0 else float(max_dof)
    return mean, nu


def estimate_likelihood(
    problem: Problem,
    params,
    *,
    refined=None,
    model_error: bool = True,
    n_replicates: int = 32,
    seed=0,
    stages=None,
    space=None,
    model_replicates: int | None = None,
    executor=None,
) -> Likelihood:
    """Measure the likelihood scales at the estimate ``params`` (:mod:`bayes_update.core.likelihood`).

    n_replicates : noise replicates per stage (K model runs each, unless
        ``model_replicates``); the relative sd of the estimated s_n is about
        1/sqrt(2 K nu).
    model_replicates : None (every replicate a model run), or k: the response to
        the force noise of the ``n_replicates`` replicates from a linear
        time-invariant estimate of the model's response (one model run), its
        error corrected by k replicates run on the model as well
        (:func:`bayes_update.core.replicates.control_variate_rows`): 2 + k model runs per stage instead of K.
    refined : the model the model error is measured against (default
        :meth:`Problem.refined_model`); ignored with ``model_error=False`` (e.g. when
        the data come from the updating model itself).
    executor : runs every model run of every stage in parallel, all at once (the same
        numbers as without: every random draw is made here, in the same order).
    """
    if int(n_replicates) != n_replicates or n_replicates < 4:
        raise ValueError(f"n_replicates must be an integer >= 4, got {n_replicates!r}")
    if model_replicates is not None and (int(model_replicates) != model_replicates or model_replicates < 4):
        raise ValueError(f"model_replicates must be None or an integer >= 4, got {model_replicates!r}")
    stages = problem.stages if stages is None else tuple(stages)
    ref_model, error_source = None, "off (model_error=False)"
    if model_error:
        ref_model = refined if refined is not None else problem.refined_model()
        error_source = f"{type(ref_model).__name__} (refined)" if refined is not None else problem.refinement_source()
    space = space if space is not None else problem.default_space()
    # every random draw first, stage by stage in a fixed order, then every model run of every
    # stage in one call to the executor (the workers never wait for a stage), then the sums
    plans, tasks = [], []
    for i, stage in enumerate(stages):
        plan = draw_replicates(
            problem,
            stage,
            int(n_replicates),
            model_replicates,
            np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,))),
        )
        plan["x"], plan["h"], plan["steps"], points = derivative_points(space, params)
        kinds = (
            [("force", plan["force"])]
            + [("force", f) for f in plan["forces"]]
            + [("output", x) for x in points]
            + ([("refined", plan["force"])] if ref_model is not None else [])
        )
        plan["slice"] = slice(len(tasks), len(tasks) + len(kinds))
        tasks += [(kind, stage, arg) for kind, arg in kinds]
        plans.append(plan)
    # the refined model's runs (the longest) first, so that none is left alone at the end
    order = sorted(range(len(tasks)), key=lambda j: tasks[j][0] != "refined")
    done = evaluate_many(
        ScalesRun(problem, params, space, ref_model), [tasks[j] for j in order], executor, batch_size=1, progress=False
    )
    results = [None] * len(tasks)
    for j, value in zip(order, done):
        results[j] = value
    scales, residuals, sensitivities, spectra = {}, {}, {}, {}
    for stage, plan in zip(stages, plans):
        res = results[plan["slice"]]
        v0, runs = res[0], res[1 : 1 + len(plan["forces"])]
        outs = res[1 + len(plan["forces"]) : 1 + len(plan["forces"]) + len(plan["x"])]
        ref_norm = np.linalg.norm(problem.output(stage, problem.reference_components(stage)))
        # the replicate's difference is projected on the recorded force's regressors, not on
        # its noisy force's: y_meas and v share v0, so the regressors' own change with the
        # force noise acts on their difference only, a second-order term (on the default data
        # set the metric's noise is the same to 3 digits either way: 0.0828 % against 0.0830 %
        # linear, 0.611 % against 0.611 % nonlinear), and no projector is built per replicate
        proj = problem.projector(stage)

        def row(noise, dv):
            return problem.output(stage, problem.components(stage, noise - dv, proj)) / ref_norm

        if plan["probe"] is not None:
            lti = lti_fit(plan["probe"], runs[0] - v0)
            D, w = control_variate_rows(row, lti, plan["cheap"], plan["pairs"], runs[1:], v0)
            changes = [lti(du) for du, _ in plan["cheap"][:SPECTRUM_REPLICATES]]
        else:  # every replicate a model run (none needed without force noise)
            runs = runs if plan["forces"] else [v0] * len(plan["cheap"])
            D = np.array([row(noise, v - v0) for (_, noise), v in zip(plan["cheap"], runs)])
            w = np.full(len(D), 1.0 / len(D))
            changes = [v - v0 for v in runs[:SPECTRUM_REPLICATES]]
        # the noise's spectrum in a replicate's time-domain residual (sensor noise and the response
        # to the force noise): what the model-form error at the mode is measured beyond
        spectra[stage] = np.mean([periodogram(noise - dv) for (_, noise), dv in zip(plan["cheap"], changes)], axis=0)
        e2 = np.sum(D**2, axis=1)
        n_reg = problem.n_regressors(stage)
        _, nu = noise_scale_from_replicates(e2[w > 0][: int(n_replicates)], n_reg)  # nu: reported only
        mean = float(w @ e2)
        y0 = problem.output(stage, problem.components(stage, v0))
        sens = derivative_from(plan["x"], plan["h"], plan["steps"], y0, outs)
        sensitivities[stage] = sens
        Q = span_of(sens.derivative, stage)
        span_var = float(w @ np.sum((D @ Q) ** 2, axis=1) / Q.shape[1])
        e_model = e_perp = 0.0
        if ref_model is not None:
            d = y0 - problem.output(stage, problem.components(stage, res[-1]))
            e_model = float(np.linalg.norm(d) / ref_norm)
            e_perp = float(np.linalg.norm(d - Q @ (Q.T @ d)) / ref_norm)
        residuals[stage] = (D, w)
        scales[stage] = StageScale(
            stage=stage,
            noise_mean_square=mean,
            noise_dof=nu,
            model_error=e_model,
            n_regressors=n_reg,
            n_replicates=int(n_replicates),
            noise_levels=_noise_levels(plan["estimates"], problem.sensors),
            span_variance=span_var,
            span_rank=int(Q.shape[1]),
            model_error_unabsorbed=e_perp,
            model_error_source=error_source,
        )
    return Likelihood(scales, residuals, sensitivities, spectra, n_model_runs=len(tasks))


def _noise_levels(estimates: dict, sensors) -> dict:
    """{channel: {"sd", "unit", "method", "detail"}} of the noise the bootstrap adds
    (the force's counted as 0 where it is unknown)."""
    from bayes_update.data.dataset import RESPONSE_UNITS

    units = {"force": "N", **{name: RESPONSE_UNITS[kind] for name, kind in sensors}}
    return {ch: {**estimates[ch].to_dict(), "unit": units[ch]} for ch in ["force"] + [n for n, _ in sensors]}


def likelihood_runs(
    problem: Problem,
    n_replicates: int,
    space=None,
    model_error: bool = True,
    stages=None,
    model_replicates: int | None = None,
) -> int:
    """Model runs :func:`estimate_likelihood` will take, to plan a budget before running it
    (what it made is its result's ``n_model_runs``): per stage one at the estimate,
    ``n_replicates`` (or the LTI probe and ``model_replicates``; none without force
    noise), d for the sensitivity span and one of the refined model (when there is one)."""
    stages = problem.stages if stages is None else tuple(stages)
    d = len(space if space is not None else problem.default_space())
    refined = model_error and problem.refined_model() is not None
    total = 0
    for st in stages:
        est = problem.noise[problem.tests[st].name]["force"]
        if not est.sd:
            replicates = 0
        else:
            replicates = int(n_replicates) if model_replicates is None else 1 + int(model_replicates)
        total += 1 + replicates + d + int(refined)
    return total
