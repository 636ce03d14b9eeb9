"""The pipeline of :func:`sample` (the package docstring)."""

from __future__ import annotations

import warnings
from concurrent.futures import Executor

from bayes_update.core.calibrate import problem_for
from bayes_update.core.likelihood import Likelihood
from bayes_update.core.logs import info
from bayes_update.core.model import ModelSpecError
from bayes_update.core.posterior.chains import Chain, direct_chain, surrogate_chain
from bayes_update.core.posterior.laplace_steps import likelihood_step, mode_step
from bayes_update.core.posterior.mcmc import (
    add_posterior_predictive,
    chain_diagnostics,
    summarize,
    to_inference_data,
)
from bayes_update.core.posterior.pointwise import linearisation_check, pointwise_log_likelihood
from bayes_update.core.posterior.predictive import posterior_predictive
from bayes_update.core.posterior.result import PosteriorResult
from bayes_update.core.posterior.run import Run, step_seeds
from bayes_update.core.posterior.settings import PosteriorSettings
from bayes_update.core.posterior.start import start_step
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
        run = Run(dataset, problem, problem.space, settings, pool, cache_dir, progress, log, steps, seeds)
        start, start_info = start_step(run, start)
        lik = likelihood_step(run, start, likelihood)
        mp, box, adj, lik = mode_step(run, lik, start, remeasure=likelihood is None)
        chain = direct_chain(run, lik, mp, adj) if direct else surrogate_chain(run, lik, mp, adj)
        res = _result(run, chain, lik, mp, box, adj, start_info, direct)
        _extras(run, res)
    steps.finish()
    res.timing, res.n_model_runs = steps.timing, steps.runs
    for k, v in getattr(steps, "reused", {}).items():
        res.n_model_runs_reused[k] = res.n_model_runs_reused.get(k, 0) + v
    log("sample: " + steps.line())
    return res


def _result(run: Run, chain: Chain, lik, mp, box, adj, start_info, direct) -> PosteriorResult:
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


def _extras(run: Run, res: PosteriorResult) -> None:
    """Diagnostics beyond the posterior: the predictive check and the global
    sensitivity (each skipped at size 0)."""
    s = run.settings
    if s.n_predictive:
        with run.steps("predictive"):
            res.predictive = posterior_predictive(res, s.n_predictive, run.pool, run.seeds.predictive, run.progress)
            run.steps.add_runs(res.predictive["n_model_runs"])
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
            run.steps.add_runs(res.sensitivity["n_model_runs"])
