"""Posterior predictive check: model runs at posterior draws, bands of the compared outputs,
and the surrogate's metrics against the model's there."""
from __future__ import annotations

from dataclasses import dataclass
import numpy as np
from surrogates.evaluation import evaluate_many
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.likelihood import Likelihood
from bayes_update.core.problem import Problem


# ---------------------------------------------------------------- extras
@dataclass
class _Predict:
    problem: Problem
    space: ParameterSet

    def __call__(self, x):
        p = self.space.to_parameters(np.asarray(x, float))
        out = {}
        for st in self.problem.stages:
            try:
                v = self.problem.simulate(p, st)
            except self.problem.failures:
                return None
            out[st] = self.problem.output(st, self.problem.components(st, v))
            out[Likelihood.key(st)] = self.problem.metric(st, v)
        return out


def posterior_predictive(res, n: int, pool, seed, progress) -> dict:
    """FE runs at ``n`` posterior draws: bands of y1 (linear test) and y2 + y3
    (nonlinear test), and the surrogate's metrics against the model's there."""
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(res.draws), size=min(n, len(res.draws)), replace=False)
    X = res.draws[idx]
    out = evaluate_many(_Predict(res.problem, res.space), list(X), pool, progress=progress,
                        desc="posterior predictive")
    ok = [i for i, o in enumerate(out) if o is not None]
    pred = {"n_draws": len(X), "n_failed": len(X) - len(ok)}
    bands = {}
    for st in res.problem.stages:
        Y = np.array([out[i][st] for i in ok])
        ref = res.problem.reference_components(st)
        bands[st] = {"low": np.percentile(Y, 5, axis=0), "high": np.percentile(Y, 95, axis=0),
                     "median": np.median(Y, axis=0), "reference": res.problem.output(st, ref)}
        e_model = np.array([out[i][Likelihood.key(st)] for i in ok])
        pred[f"{Likelihood.key(st)}_model_median"] = float(np.median(e_model))
        if res.surrogates:
            z = res.surrogates[st].predict_transformed(res.design["whitening"].to_u(X[ok]))[0]
            e_gp = res.likelihood.from_z(st, z)
            rel = np.abs(e_gp - e_model) / e_model
            pred[f"{Likelihood.key(st)}_gp_median_rel_error"] = float(np.median(rel))
            pred[f"{Likelihood.key(st)}_gp_max_rel_error"] = float(np.max(rel))
            pred[f"_{st}_pairs"] = (e_model, e_gp)
    pred["_bands"] = bands
    pred["_draws"] = {st: np.array([out[i][st] for i in ok]) for st in res.problem.stages}
    return pred
