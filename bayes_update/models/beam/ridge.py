"""The beam's linear-only posterior: what the low-level test alone says, a ridge of
constant P_eff in (F, k_s) with c unidentified (the ridge figure of docs/posterior.md)."""
from __future__ import annotations

from functools import partial

import numpy as np

import surrogates
from bayes_update.core.posterior.design import _cache, _gp_factory
from bayes_update.core.posterior.laplace import local_box
from bayes_update.core.posterior.mcmc import initial_walkers, run_emcee
from bayes_update.core.posterior.target import Evaluate, SurrogateLogPosterior
from bayes_update.models.beam.space import UNITS
from surrogates.evaluation import evaluate_many


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
        box[i] = [max(res.map.x[i] - 3 * s.box_sd * sd[i], res.space.box()[i, 0]),
                  min(res.map.x[i] + 3 * s.box_sd * sd[i], res.space.box()[i, 1])]
    ss = np.random.SeedSequence(seed).spawn(3)
    X = surrogates.design(box, s.n_linear, "sobol", seed=int(ss[0].generate_state(1)[0]))
    cache = _cache(cache_dir, ev, "linear_only", reused=reused)
    evaluate = partial(surrogates.cached_evaluate, cache=cache) if cache is not None else evaluate_many
    r = evaluate(ev, list(X), executor=pool, progress=progress)
    y = np.array([float(lik.to_z("linear", q["e_lin"])) for q in r])

    def weight(sur):
        return SurrogateLogPosterior({"linear": sur}, res.space, box)

    ref = surrogates.refine(ev, lambda: _gp_factory(box, 0, res.space.coordinate_names), X, y, weight, 1, max(8, s.n_linear // 4), pool,
                            seed=int(ss[1].generate_state(1)[0]), candidates=2048,
                            target=lambda q: float(lik.to_z("linear", q["e_lin"])), log_weight=True,
                            evaluate=evaluate, progress=progress)
    logp = SurrogateLogPosterior({"linear": ref.surrogate}, res.space, box)
    init = initial_walkers(logp, res.map.x, np.diag(((box[:, 1] - box[:, 0]) / 20) ** 2), s.n_walkers,
                           int(ss[2].generate_state(1)[0]))
    smp = run_emcee(logp, init, s.n_walkers, s.n_steps, int(ss[2].generate_state(2)[1]), vectorize=True,
                    progress=progress)
    draws = smp.get_chain(discard=s.burn, thin=s.thin, flat=True)
    F = res.space.F_of(draws)
    corr = float(np.corrcoef(F, draws[:, 3])[0, 1])
    full = res.draws
    out = {"n_model_runs": len(ref.X), "corr_F_k_s": corr,
           "sd": {"eta": float(draws[:, 0].std()), "c": float(draws[:, 1].std()),
                  "P_eff": float(draws[:, 2].std()), "k_s": float(draws[:, 3].std()), "F": float(F.std())},
           "sd_full": {"eta": float(full[:, 0].std()), "c": float(full[:, 1].std()),
                       "P_eff": float(full[:, 2].std()), "k_s": float(full[:, 3].std()),
                       "F": float(res.space.F_of(full).std())},
           "units": dict(UNITS), "_draws": draws}
    out["narrowing"] = {k: out["sd"][k] / out["sd_full"][k] for k in ("c", "k_s")}
    # the high level leaves a band in (c, k_s), not a point: the joint spread
    # (sqrt of the determinant of the covariance) says how much it removes
    det = [np.sqrt(np.linalg.det(np.cov(D[:, [1, 3]].T))) for D in (draws, full)]
    out["narrowing"]["c_k_s_area"] = float(det[0] / det[1])
    log(f"linear-only posterior: corr(F, k_s) = {corr:.3f}; adding the high level narrows c "
        f"{out['narrowing']['c']:.1f}x, k_s {out['narrowing']['k_s']:.1f}x (sd ratio), the (c, k_s) "
        f"area {out['narrowing']['c_k_s_area']:.1f}x")
    return out
