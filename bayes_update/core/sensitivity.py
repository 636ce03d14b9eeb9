"""Global sensitivity of e_lin and e_nlin over the prior box (Sobol' indices).

A Sobol' design over the prior box of the declared parameters, one model run per
test at each point, a Gaussian process of log e per metric, and SALib's
Saltelli estimator of first-order (S1) and total (ST) indices of log e on the
GP mean.  The indices are for log e: the metrics span decades over the box,
and what a user asks ("which parameter does the low-level test see?") is
about their order of magnitude.  The GP's held-out error is reported with the
indices so that they can be trusted or not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import surrogates
from bayes_update.core.metrics import metric_key
from bayes_update.core.problem import Problem
from surrogates.evaluation import evaluate_many


@dataclass
class _EvaluatePublic:
    problem: Problem
    space: object

    def __call__(self, u):
        return self.problem.evaluate(self.space.theta(np.asarray(u, float)))


def sobol_indices(problem: Problem, space, n_design: int, n_sobol: int, pool, seed, progress: bool = True) -> dict:
    """{metric: {"S1": {...}, "ST": {...}, "S1_conf", "ST_conf", "gp_holdout"}} (SALib),
    over the prior box of the declared parameters (their units)."""
    from SALib.analyze import sobol as sobol_analyze
    from SALib.sample import sobol as sobol_sample

    PUBLIC = tuple(space.names)
    bounds = np.column_stack([space.low, space.high])
    X = surrogates.design(bounds, n_design, "sobol", seed=seed)
    metrics = tuple(metric_key(st) for st in problem.stages)
    res = evaluate_many(_EvaluatePublic(problem, space), list(X), pool, progress=progress, desc="global design")
    salib_problem = {"num_vars": len(PUBLIC), "names": list(PUBLIC), "bounds": bounds.tolist()}
    S = sobol_sample.sample(salib_problem, int(n_sobol), calc_second_order=False, seed=int(seed) % 2**31)
    out = {
        "n_design": int(n_design),
        # a run per design point and stage whose metric it computed
        "n_model_runs": len(X) * len({key for r in res for key in r if key in metrics}),
        "n_sobol": int(n_sobol),
        "units": {p.name: p.unit for p in space.parameters},
        "output": "log e",
    }
    for key in metrics:
        y = np.array([r.get(key, np.nan) for r in res], float)
        ok = np.isfinite(y) & (y > 0)
        if ok.sum() < 8:
            continue

        def factory():
            return surrogates.GPSurrogate(bounds, transform="log", names=list(PUBLIC), n_restarts_optimizer=2, seed=0)

        gp = factory().fit(X[ok], y[ok])
        hold = surrogates.holdout_validation(factory, X[ok], y[ok], fraction=0.25, seed=0)
        z = gp.predict_transformed(S)[0]
        Si = sobol_analyze.analyze(salib_problem, z, calc_second_order=False, seed=int(seed) % 2**31)
        out[key] = {
            "S1": dict(zip(PUBLIC, map(float, Si["S1"]))),
            "ST": dict(zip(PUBLIC, map(float, Si["ST"]))),
            "S1_conf": dict(zip(PUBLIC, map(float, Si["S1_conf"]))),
            "ST_conf": dict(zip(PUBLIC, map(float, Si["ST_conf"]))),
            "gp_holdout": {k: v for k, v in hold.items() if isinstance(v, (int, float))},
        }
    return out
