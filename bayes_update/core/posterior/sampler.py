"""The pipeline of :func:`sample` (the package docstring) and its result."""
from __future__ import annotations

import time
import warnings
from concurrent.futures import Executor
from dataclasses import asdict, dataclass, field

import numpy as np

from bayes_update.core.likelihood import Likelihood, curvature_adjustment, estimate_likelihood
from bayes_update.core.model import ModelSpecError, adapter_for, check_model_on
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior.design import _build_surrogates
from bayes_update.core.posterior.laplace import MapResult, capped_covariance, find_map, local_box
from bayes_update.core.posterior.mcmc import (_box_cut_fraction, _chain_diagnostics, _XSampler, initial_walkers,
                                              run_emcee, summarize, to_inference_data)
from bayes_update.core.posterior.predictive import posterior_predictive
from bayes_update.core.posterior.settings import PosteriorSettings
from bayes_update.core.posterior.target import (DirectLogPosterior, Evaluate, Whitening, WhitenedEvaluate,
                                                WhitenedLogPosterior, _ExecutorPool)
from bayes_update.core.problem import Problem
from bayes_update.data.dataset import Dataset
from surrogates.evaluation import default_executor

# ------------------------------------------------------------------ results
@dataclass
class PosteriorResult:
    idata: object
    summary: dict
    likelihood: Likelihood
    space: ParameterSet
    map: MapResult
    box: np.ndarray
    start: dict
    diagnostics: dict
    timing: dict
    n_model_runs: dict
    settings: PosteriorSettings
    direct: bool
    problem: Problem = field(repr=False, default=None)
    surrogates: dict = field(repr=False, default_factory=dict)
    design: dict = field(repr=False, default_factory=dict)
    draws: np.ndarray = field(repr=False, default=None)     # flat internal-coordinate draws
    linear_only: dict = field(repr=False, default_factory=dict)
    predictive: dict = field(repr=False, default_factory=dict)
    sensitivity: dict = field(repr=False, default_factory=dict)
    n_model_runs_reused: dict = field(default_factory=dict)  # found in the cache instead of run

    def summary_json(self) -> dict:
        return {"parameters": self.summary, "map": dict(zip(self.space.coordinate_names, map(float, self.map.x))),
                "map_units": dict(self.space.units), "likelihood": self.likelihood.to_dict(),
                "prior": self.space.to_dict(),
                "laplace_box": dict(zip(self.space.coordinate_names, self.box.tolist())),
                "start": self.start, "diagnostics": self.diagnostics, "direct": self.direct,
                "settings": asdict(self.settings),
                "linear_only": {k: v for k, v in self.linear_only.items() if not k.startswith("_")},
                "surrogate_check": {k: v for k, v in self.predictive.items() if not k.startswith("_")},
                "sensitivity": self.sensitivity}

    def run_json(self) -> dict:
        """How the run went (not what it found): wall time per step [s] and model
        runs per step, which a resumed run or another machine changes while the
        posterior stays the same."""
        return {"timing_s": self.timing, "n_model_runs": self.n_model_runs,
                "n_model_runs_reused": self.n_model_runs_reused}


def sample(dataset: Dataset, model=None, settings: PosteriorSettings | None = None, *,
           executor: Executor | None = None, workers: int | None = None, direct: bool = False,
           start=None, space=None, likelihood: Likelihood | None = None, cache_dir=None,
           metrics: str | None = None, progress: bool = True, log=print) -> PosteriorResult:
    """Sample the posterior of a model's parameters given ``dataset`` (module docstring).

    Parameters
    ----------
    model : the updating model: any model of the contract
        (:mod:`bayes_update.core.model`: declared ``parameters`` and
        ``simulate(theta, force, fs)``), or the beam (``fe.BeamModel``, the
        default, or ``fe.ModalROM``; parameters eta, c, F, k_s).
    space : the prior (default: the model's declared parameters; the beam's
        :class:`ParameterSet` box of docs/design.md#parameters-units-and-the-prior-box).
    direct : run emcee on the model itself (no surrogate); sensible with a
        model of a few ms per run (``fe.ModalROM``: about 2 ms per evaluation).
    start : skip the start search and begin at these parameters (theta, or
        ``fe.Parameters`` for the beam).
    likelihood : use these scales instead of measuring them at the start
        (e.g. to compare a direct and a surrogate posterior under one likelihood).
    cache_dir : folder of the netCDF evaluation cache (an interrupted run resumes).
    metrics : the metric set, ``"paper"`` or ``"full"`` (:mod:`bayes_update.core.problem`;
        default ``full`` for a model of the contract, ``paper`` for the beam).
    """
    settings = settings or PosteriorSettings()
    problem, space = make_problem(dataset, model, space, metrics)
    if "nonlinear" not in problem.stages:
        raise ValueError(f"{problem.source}: the posterior needs a test with role 'nonlinear' "
                         "(the high-level chirp) as well as the 'linear' one")
    stages = problem.stages
    timing, runs, reused = {}, {}, {}
    t_all = time.perf_counter()
    own_pool = executor is None and (workers or 2) > 1
    pool = default_executor(workers) if own_pool else executor
    try:
        return _sample(dataset, problem, space, settings, pool, direct, start, likelihood, cache_dir, progress,
                       log, stages, timing, runs, reused, t_all)
    finally:
        if own_pool:
            pool.shutdown()


def make_problem(dataset: Dataset, model, space=None, metrics=None):
    """(problem, space) for ``model`` on ``dataset``.

    A model of the contract (declared ``parameters``; checked with one run
    here, before any heavy work) gets a :class:`bayes_update.core.Problem`
    (:func:`bayes_update.core.calibrate.problem_for`: under the ``full``
    metric set J1 follows the parameters the linear test moves) and its
    :class:`ParameterSet`.  A model of another package with an adapter
    (:func:`bayes_update.core.model.adapter_for`: the beam's ``fe`` models)
    gets what its adapter builds."""
    if model is None:
        raise ModelSpecError("no model given: pass a model of the contract (docs/models.md), or a beam "
                             "model (fe.BeamModel / fe.ModalROM)")
    if not hasattr(model, "parameters"):
        adapter = adapter_for(model)
        if adapter is None:
            raise ModelSpecError(f"{type(model).__name__} is not a model: it declares no `parameters` "
                                 "(docs/models.md)")
        return adapter(dataset, model, space, metrics)
    from bayes_update.core.calibrate import problem_for

    checked = check_model_on(model, dataset)
    space = space if space is not None else checked
    return problem_for(dataset, model, space, metrics)[0], space


def default_start(dataset, problem, space, pool, n_points: int, seed, progress, log):
    """(start point, model runs): the problem's own ``default_start`` when it has
    one (the beam's: the paper's grids), else the generic two-stage calibration
    (:mod:`bayes_update.core.calibrate`) on the problem as built."""
    if hasattr(problem, "default_start"):
        return problem.default_start(dataset, pool, progress, log)
    from bayes_update.core.calibrate import screen_linear, two_stage

    log(f"start: the two-stage calibration (Sobol' designs of {n_points} points, then least squares)")
    names, runs = getattr(problem, "linear_parameters", None), 0
    if names is None:
        names, _, runs = screen_linear(problem, space, pool)
    found = two_stage(problem, space, names, n_start=n_points, seed=seed, executor=pool, progress=progress)
    return space.to_parameters(found.x), runs + found.n_model_runs


def _sample(dataset, problem, space, settings, pool, direct, start, likelihood, cache_dir, progress, log,
            stages, timing, runs, reused, t_all):
    seeds = np.random.SeedSequence(settings.seed).spawn(8)
    seed_of = [int(s.generate_state(1)[0]) for s in seeds]
    # 1. start ---------------------------------------------------------------
    t0 = time.perf_counter()
    if start is None:
        start, runs["start"] = default_start(dataset, problem, space, pool, settings.n_start, seed_of[7],
                                             progress, log)
    else:
        space.check(start, "start")
        runs["start"] = 0
    start_info = space.describe(start)
    if not space.contains(start):
        start = space.to_parameters(np.clip(space.to_internal(start), space.box()[:, 0], space.box()[:, 1]))
    timing["start"] = time.perf_counter() - t0
    # 2. likelihood scales ------------------------------------------------------
    t0 = time.perf_counter()
    if likelihood is None:
        lik = estimate_likelihood(problem, start, model_error=settings.model_error,
                                  n_replicates=settings.n_replicates, seed=seed_of[0], space=space)
        # replicates, the estimate, the refined model, 8 runs for the sensitivity span
        runs["likelihood_scales"] = len(stages) * (settings.n_replicates + 9 + int(settings.model_error))
    else:
        if set(likelihood.stages) != set(stages):
            raise ValueError(f"the likelihood covers stages {likelihood.stages}, the data {stages}")
        lik = likelihood
        runs["likelihood_scales"] = 0
    timing["likelihood_scales"] = time.perf_counter() - t0
    for st, sc in lik.scales.items():
        log(f"likelihood {st}: noise sd {100 * sc.noise_sd:.3f} % per direction of the parameters' span "
            f"({sc.span_rank}), model error "
            f"{100 * sc.model_error:.3f} %, s = {100 * sc.sd:.3f} %")
    # 3. MAP and local box --------------------------------------------------------
    t0 = time.perf_counter()
    ev = Evaluate(problem, space, stages)
    mp = find_map(ev, lik, space.to_internal(start), pool, settings.map_max_evaluations, progress=False)
    box = local_box(space, mp.x, mp.covariance, settings.box_sd)
    runs["map_laplace"] = len(stages) * mp.n_evaluations
    timing["map_laplace"] = time.perf_counter() - t0
    log("MAP: " + ", ".join(f"{n} = {v:.4g} {space.units[n]}" for n, v in zip(space.coordinate_names, mp.x))
        + "; Laplace sd: " + ", ".join(f"{v:.3g}" for v in np.sqrt(np.diag(mp.covariance))))
    adj = None
    if settings.curvature_adjustment and mp.mode is not None:
        adj = curvature_adjustment(lik, mp.mode.jacobian, mp.x, np.diff(space.box(), axis=1)[:, 0], stages,
                                   names=space.coordinate_names)
        if adj is not None:
            log("curvature adjustment: noise variance / likelihood's along the parameters' directions "
                + ", ".join(f"{v:.2f}" for v in adj.variance_ratios) + "; sd x "
                + ", ".join(f"{n} {v:.2f}" for n, v in zip(space.coordinate_names, adj.sd_ratios)))
    result = dict(design={}, surrogates={})
    # 4-5. sampling -----------------------------------------------------------------
    if direct:
        t0 = time.perf_counter()
        logp = DirectLogPosterior(ev, lik, adj)
        x_init = initial_walkers(lambda X: np.array([logp(x) for x in X]), mp.x, mp.covariance,
                                 settings.n_walkers, seed_of[1])
        sampler = run_emcee(logp, x_init, settings.n_walkers, settings.direct_steps, seed_of[2],
                            vectorize=False, pool=_ExecutorPool(pool) if pool is not None else None,
                            progress=progress)
        runs["mcmc"] = len(stages) * settings.n_walkers * settings.direct_steps
        timing["mcmc"] = time.perf_counter() - t0
        gps = {}
    else:
        t0 = time.perf_counter()
        whitening = Whitening.from_covariance(mp.x, capped_covariance(mp.covariance, space, settings.box_sd))
        ubox = np.array([[-settings.box_sd, settings.box_sd]] * len(space.coordinate_names), float)
        timing["gp_fit"], timing["mcmc"], runs["design"] = 0.0, 0.0, 0
        for attempt in range(settings.box_attempts):
            t0 = time.perf_counter()
            gps, U, Y, fit_time = _build_surrogates(WhitenedEvaluate(ev, whitening), lik, space, ubox, whitening,
                                                    settings, pool, cache_dir, stages, seed_of[3] + attempt,
                                                    progress, log, reused)
            runs["design"] += len(stages) * int(np.sum(np.all(np.isfinite(Y), axis=1)))
            timing["design_and_gp"] = timing.get("design_and_gp", 0.0) + time.perf_counter() - t0
            timing["gp_fit"] += fit_time
            result["design"] = {"X": whitening.to_x(U), "z": Y, "whitening": whitening}
            t0 = time.perf_counter()
            logp_u = WhitenedLogPosterior(gps, space, ubox, whitening, adj)
            u_init = initial_walkers(logp_u, np.zeros(len(space.coordinate_names)), np.eye(len(space.coordinate_names)), settings.n_walkers,
                                     seed_of[1])
            sampler = run_emcee(logp_u, u_init, settings.n_walkers, settings.n_steps, seed_of[2],
                                vectorize=True, progress=progress)
            timing["mcmc"] += time.perf_counter() - t0
            u_draws = sampler.get_chain(discard=settings.burn, flat=True)
            cut = _box_cut_fraction(logp_u.gp_points(u_draws), settings.box_sd, whitening, space)
            if cut <= 0.01 or attempt == settings.box_attempts - 1:
                break
            # the Laplace box cut the posterior (a non-Gaussian posterior, or a
            # MAP short of the mode): re-centre and re-whiten on the surrogate
            # posterior's draws, 3x wider (they are truncated by the old box)
            x_draws = whitening.to_x(u_draws)
            log(f"the local box cut {100 * cut:.1f} % of the draws: re-centred on them, 3x wider "
                f"(attempt {attempt + 2} of {settings.box_attempts})")
            whitening = Whitening.from_covariance(x_draws.mean(axis=0),
                                                  capped_covariance(9.0 * np.cov(x_draws.T), space,
                                                                    settings.box_sd))
        diag_attempts = attempt + 1
        sampler = _XSampler(sampler, whitening)
    burn = settings.direct_burn if direct else settings.burn
    thin = 1 if direct else settings.thin
    diag = _chain_diagnostics(sampler, burn, space.coordinate_names)
    if isinstance(sampler, _XSampler):
        diag["box_cut_fraction"] = _box_cut_fraction(
            logp_u.gp_points(sampler.sampler.get_chain(discard=burn, flat=True)), settings.box_sd,
            sampler.whitening, space)
    diag["thin"] = thin
    diag["curvature_adjustment"] = adj.to_dict() if adj is not None else None
    if not direct:
        diag["box_attempts"] = diag_attempts
    chain = sampler.get_chain(discard=burn, thin=thin)
    lp = sampler.get_log_prob(discard=burn, thin=thin)
    idata = to_inference_data(chain, lp, space, {"source": str(problem.source), "direct": int(direct),
                                                  "model": type(problem.model).__name__})
    summary = summarize(idata, space)
    diag["max_r_hat"] = max(v["r_hat"] for v in summary.values())
    diag["min_ess_bulk"] = min(v["ess_bulk"] for v in summary.values())
    if diag.get("box_cut_fraction", 0.0) > 1e-2:
        warnings.warn(f"after {diag['box_attempts']} boxes the surrogate's box still cuts "
                      f"{100 * diag['box_cut_fraction']:.2f} % of the draws: the posterior is wider than the "
                      "Laplace approximation says; raise box_sd or box_attempts", RuntimeWarning)
    flat = chain.reshape(-1, chain.shape[-1])
    res = PosteriorResult(idata=idata, summary=summary, likelihood=lik, space=space, map=mp, box=box,
                          start=start_info, diagnostics=diag, timing=timing, n_model_runs=runs,
                          n_model_runs_reused=reused,
                          settings=settings, direct=direct, problem=problem, surrogates=gps,
                          design=result["design"], draws=flat)
    # extras: linear-only posterior, predictive check, sensitivity ----------------------------
    if settings.n_predictive:
        t0 = time.perf_counter()
        res.predictive = posterior_predictive(res, settings.n_predictive, pool, seed_of[4], progress)
        runs["predictive"] = len(stages) * settings.n_predictive
        timing["predictive"] = time.perf_counter() - t0
    if settings.n_linear and not direct and hasattr(space, "ridge_posterior"):
        t0 = time.perf_counter()
        res.linear_only = space.ridge_posterior(res, pool, seed_of[5], cache_dir, progress, log, reused)
        runs["linear_only"] = res.linear_only["n_model_runs"]
        timing["linear_only"] = time.perf_counter() - t0
    if settings.n_global:
        t0 = time.perf_counter()
        from bayes_update.core.sensitivity import sobol_indices
        res.sensitivity = sobol_indices(problem, space, settings.n_global, settings.sobol_n, pool, seed_of[6],
                                        progress)
        runs["sensitivity"] = len(stages) * settings.n_global
        timing["sensitivity"] = time.perf_counter() - t0
    timing["total"] = time.perf_counter() - t_all
    runs["total"] = int(sum(v for k, v in runs.items() if k != "total"))
    return res
