"""The beam's linear-only posterior: what the low-level test alone says, a ridge of
constant P_eff in (F, k_s) with c unidentified (the ridge figure of docs/posterior.md)."""

from __future__ import annotations

from functools import partial

import numpy as np

import surrogates
from bayes_update.core.logs import info
from bayes_update.core.posterior.design import design_cache, design_gp
from bayes_update.core.posterior.laplace import local_box
from bayes_update.core.posterior.mcmc import initial_walkers, run_emcee
from bayes_update.core.posterior.target import Evaluate, SurrogateLogPosterior
from surrogates.evaluation import evaluate_many, executor_for


def add_linear_only(post, workers=None, cache_dir=None, progress: bool = True, log=info) -> dict:
    """The beam's linear-only posterior (the ridge) of a beam posterior ``post``
    (:func:`bayes_update.sample`), added to ``post.extras["linear_only"]`` with its
    model runs and time (the ridge figure of
    :func:`bayes_update.reports.posterior_plots.posterior_figures` draws it)."""
    import time

    t0 = time.perf_counter()
    with executor_for(None, workers) as pool:
        lo = linear_only_posterior(
            post, pool, post.seeds.linear_only, cache_dir, progress, log, post.n_model_runs_reused
        )
    post.extras["linear_only"] = lo
    post.n_model_runs["linear_only"] = lo["n_model_runs"]
    post.n_model_runs["total"] += lo["n_model_runs"]
    post.timing["linear_only"] = time.perf_counter() - t0
    post.timing["total"] += post.timing["linear_only"]
    return lo


def linear_only_posterior(res, pool, seed, cache_dir, progress, log, reused=None) -> dict:
    """The posterior from the low-level test alone: (F, k_s) on a ridge of
    constant P_eff, c unidentified.  Its own design (c and k_s over the
    prior), GP of z_lin and emcee."""
    s = res.settings
    lik = res.likelihood.restricted(("linear",))
    ev = Evaluate(res.problem, res.space, ("linear",))
    sd = np.sqrt(np.diag(res.map.covariance))
    box = local_box(res.space, res.map.x, res.map.covariance, s.box_sd, free=("c", "k_s"))
    # the high level pins eta and P_eff: widen them for the low level alone
    for i in (0, 2):
        box[i] = [
            max(res.map.x[i] - 3 * s.box_sd * sd[i], res.space.box()[i, 0]),
            min(res.map.x[i] + 3 * s.box_sd * sd[i], res.space.box()[i, 1]),
        ]
    ss = np.random.SeedSequence(seed).spawn(3)
    X = surrogates.design(box, s.n_linear, "sobol", seed=int(ss[0].generate_state(1)[0]))
    cache = design_cache(cache_dir, ev, "linear_only", reused=reused)
    evaluate = partial(surrogates.cached_evaluate, cache=cache) if cache is not None else evaluate_many
    r = evaluate(ev, list(X), executor=pool, progress=progress)
    y = np.array([float(lik.to_z("linear", q["e_lin"])) for q in r])

    def weight(sur):
        return SurrogateLogPosterior({"linear": sur}, res.space, box)

    ref = surrogates.refine(
        ev,
        lambda: design_gp(box, 0, res.space.coordinate_names),
        X,
        y,
        weight,
        1,
        max(8, s.n_linear // 4),
        pool,
        seed=int(ss[1].generate_state(1)[0]),
        candidates=2048,
        target=lambda q: float(lik.to_z("linear", q["e_lin"])),
        log_weight=True,
        evaluate=evaluate,
        progress=progress,
    )
    logp = SurrogateLogPosterior({"linear": ref.surrogate}, res.space, box)
    init = initial_walkers(
        logp, res.map.x, np.diag(((box[:, 1] - box[:, 0]) / 20) ** 2), s.n_walkers, int(ss[2].generate_state(1)[0])
    )
    smp = run_emcee(
        logp,
        init,
        s.n_walkers,
        s.n_steps,
        int(ss[2].generate_state(2)[1]),
        vectorize=True,
        progress=progress,
        desc="MCMC, low level only",
    )
    draws = smp.get_chain(discard=s.burn, thin=s.thin, flat=True)
    low, full = res.space.report(draws), res.space.report(res.draws)
    corr = float(np.corrcoef(low["F"], low["k_s"])[0, 1])
    names = ("eta", "c", "P_eff", "k_s", "F")
    out = {
        "n_model_runs": len(ref.X),
        "corr_F_k_s": corr,
        "sd": {n: float(low[n].std()) for n in names},
        "sd_full": {n: float(full[n].std()) for n in names},
        "units": dict(res.space.report_units),
        "_draws": draws,
    }
    out["narrowing"] = {k: out["sd"][k] / out["sd_full"][k] for k in ("c", "k_s")}
    # the high level leaves a band in (c, k_s), not a point: the joint spread
    # (sqrt of the determinant of the covariance) says how much it removes
    det = [np.sqrt(np.linalg.det(np.cov(np.vstack([D["c"], D["k_s"]])))) for D in (low, full)]
    out["narrowing"]["c_k_s_area"] = float(det[0] / det[1])
    log(
        f"linear-only posterior: corr(F, k_s) = {corr:.3f}; adding the high level narrows c "
        f"{out['narrowing']['c']:.1f}x, k_s {out['narrowing']['k_s']:.1f}x (sd ratio), the (c, k_s) "
        f"area {out['narrowing']['c_k_s_area']:.1f}x"
    )
    return out
