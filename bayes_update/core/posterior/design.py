"""The surrogates of the posterior: a Sobol' design in the whitened local box, Gaussian
processes of z = log(1 + e^2 / s^2) per stage, refinement rounds where the posterior is; the
evaluation cache an interrupted run resumes from."""
from __future__ import annotations

import time
from functools import partial
import numpy as np
import surrogates
from surrogates.evaluation import evaluate_many
from bayes_update.core.likelihood import Likelihood
from bayes_update.core.posterior.mcmc import initial_walkers, run_emcee
from bayes_update.core.posterior.target import Evaluate, WhitenedEvaluate, Whitening, WhitenedLogPosterior


def _gp_factory(box, seed, names):
    return surrogates.GPSurrogate(box, transform="none", names=list(names), n_restarts_optimizer=2, seed=seed)


def _build_surrogates(ev: WhitenedEvaluate, lik, space, box, whitening, settings, pool, cache_dir, stages, seed,
                      progress, log, reused=None):
    """Design in the whitened box (inside the prior), GPs of z per stage,
    refinement rounds; all in u coordinates."""
    from threadpoolctl import threadpool_limits

    ss = np.random.SeedSequence(seed).spawn(3)
    # a Sobol' design of the u box, keeping the points inside the prior
    # (near a corner of the prior most of the box is outside: draw more)
    for factor in (8, 64, 512):
        cand = surrogates.design(box, factor * settings.n_initial, "sobol", seed=int(ss[0].generate_state(1)[0]))
        inside = np.isfinite(space.log_prior(whitening.to_x(cand)))
        if inside.sum() >= settings.n_initial:
            break
    else:
        raise RuntimeError(f"only {inside.sum()} of {len(cand)} design candidates fall inside the prior box")
    U0 = cand[inside][:settings.n_initial]
    cache = _cache(cache_dir, ev.evaluate, "design", whitening, reused)
    evaluate = partial(surrogates.cached_evaluate, cache=cache) if cache is not None else evaluate_many
    res = evaluate(ev, list(U0), executor=pool, progress=progress)

    def target(r):
        return [float(lik.to_z(st, r[Likelihood.key(st)])) for st in stages]

    Y0 = np.array([target(r) for r in res])

    def weight(surs):
        return WhitenedLogPosterior(dict(zip(stages, surs)), space, box, whitening)

    def candidates(surs, rng):
        # draws of a short MCMC on the current surrogate posterior, plus Sobol' points
        logp = weight(surs)
        init = initial_walkers(logp, np.zeros(len(box)), np.eye(len(box)), 16, int(rng.integers(2 ** 31)))
        smp = run_emcee(logp, init, 16, 400, int(rng.integers(2 ** 31)), vectorize=True, progress=False)
        draws = smp.get_chain(discard=200, thin=2, flat=True)
        sob = surrogates.design(box, 512, "sobol", seed=int(rng.integers(2 ** 31)))
        return np.vstack([draws, sob])

    def factory():
        return _gp_factory(box, seed=0, names=space.coordinate_names)

    with threadpool_limits(2):
        t = time.perf_counter()
        ref = surrogates.refine(ev, factory, U0, Y0, weight, settings.n_rounds, settings.batch, pool,
                                seed=int(ss[1].generate_state(1)[0]), candidates=candidates, target=target,
                                log_weight=True, evaluate=evaluate, progress=progress)
        t_fit = time.perf_counter() - t
    gps = dict(zip(stages, ref.surrogate))
    for st, gp in gps.items():
        log(f"GP of z_{st}: {int(np.isfinite(ref.y[:, 0]).sum())} runs; " + gp.summary().splitlines()[0])
    return gps, ref.X, ref.y, t_fit


def _cache(cache_dir, ev: Evaluate, name: str, whitening: Whitening | None = None, reused: dict | None = None):
    """The evaluation cache of ``name`` under ``cache_dir`` (None: no cache); ``reused``
    counts the model runs its entries on disk save, per name."""
    if cache_dir is None:
        return None
    from pathlib import Path

    from bayes_update.core.basis import describe_basis
    config = {"what": name, "stages": list(ev.stages), "model": ev.problem.describe()["model"],
              "basis": describe_basis(ev.problem.basis), "metric_set": ev.problem.metrics,
              "data": ev.problem.data_fingerprint,
              "coordinates": list(ev.space.coordinate_names)}
    if whitening is not None:     # points are stored in the whitened coordinates
        config["whitening"] = {"center": whitening.center.tolist(), "L": whitening.L.tolist()}
    path = Path(cache_dir)
    path.mkdir(parents=True, exist_ok=True)
    cache = surrogates.EvaluationCache(path / name, config)
    if reused is not None:
        reused[name] = reused.get(name, 0) + cache.n_loaded * len(ev.stages)
    return cache
