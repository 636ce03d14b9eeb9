"""The fits of the discrepancy workflow (:mod:`bayes_update.core.discrepancy`): a
model (the baseline plus added effects) at its least-squares mode with its
Laplace evidence, where its effect's parameters sit (at the null, on a bound),
the naming rule for one candidate, and the gap a fit leaves on the tests."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bayes_update.core.comparison import score_model
from bayes_update.core.effects import DECISIVE, ExtendedSpace
from bayes_update.core.metrics import metric_key
from bayes_update.core.mode import ModeResult, ResidualFunction, SpacePoint, find_mode
from bayes_update.core.problem import Problem
from surrogates.evaluation import evaluate_many

__all__ = [
    "AT_VALUE",
    "GAP_LABELS",
    "Fit",
    "failed_fit",
    "fit_model",
    "gap",
    "names_effect",
    "names_pair",
    "noise_floor",
]


@dataclass
class Fit:
    """One model (baseline + added effects) at its mode."""

    names: list  # added effects, in order
    space: ExtendedSpace
    mode: ModeResult
    log_evidence: float
    covariance: np.ndarray
    metrics: dict  # e_lin, e_nlin at the mode

    @property
    def theta(self) -> dict:
        return self.space.to_parameters(self.mode.x)

    def to_json(self, effects: dict) -> dict:
        values = self.space.values(self.mode.x, self.covariance)
        base = {n: v for n, v in self.theta.items() if n in self.space.base.names}
        sd = np.sqrt(np.diag(self.covariance))[: self.space.n_base]
        return {
            "parameters": {
                n: {"mode": base[n], "unit": self.space.base[n].unit, "sd_internal": float(s), "coordinate": c}
                for n, s, c in zip(self.space.base.names, sd, self.space.base.coordinate_names)
            },
            "effects": {e: {p.name: values[p.name] for p in effects[e]} for e in self.names},
            **self.metrics,
            "log_evidence": self.log_evidence,
        }


def fit_model(
    problem: Problem, space: ExtendedSpace, names, lik, starts, settings, executor=None, iterations: int | None = None
) -> Fit:
    """Mode, Laplace covariance and log evidence of the baseline + the parameters of ``space``
    (``iterations``: per start, default ``settings.max_iterations``); the model run once more
    per test at its mode for its own error covariance (:func:`~bayes_update.core.comparison.score_model`)."""
    stages = problem.stages
    fun = ResidualFunction(problem, stages, tuple(lik.scales[s].sd for s in stages), SpacePoint(space, problem.model))
    box = space.box()
    lo, hi = box[:, 0], box[:, 1]
    tol = settings.cost_tolerance
    mode = find_mode(
        fun,
        starts,
        lo,
        hi,
        1e-4 * (hi - lo),
        executor,
        max_iterations=iterations or settings.max_iterations,
        cost_tolerance=tol,
        central=tol is None,
    )
    # each model scored under its own error covariance: the noise and what its own mode leaves
    # beyond it (bayes_update.core.comparison; one run per test)
    scored = score_model(
        problem, lik, mode, space.to_parameters(mode.x), space.log_prior_density(mode.x), hi - lo, executor
    )
    cov, logz = scored.covariance, scored.log_evidence
    metrics = {
        metric_key(st): float(np.linalg.norm(mode.residual[rows]) * lik.scales[st].sd)
        for st, rows in problem.stage_rows(stages).items()
    }
    return Fit(list(names), space, mode, logz, cov, metrics)


def effect_starts(space: ExtendedSpace, k: int, fraction: float) -> list:
    """Starts of the last ``k`` coordinates: null +- ``fraction`` of the range
    towards each bound (where the range extends that way); the null itself
    when the range is a point."""
    box, null = space.box()[-k:], space.null_internal()[-k:]
    up = null + fraction * (box[:, 1] - null)
    down = null - fraction * (null - box[:, 0])
    out = [v for v in (up, down) if not np.allclose(v, null)]
    return out or [null]


def _member(fit: Fit, k: int, end: int | None) -> tuple:
    """One added effect's ``k`` parameters ending at coordinate ``end`` (default:
    the last effect added): (their mode, their null values, their prior box,
    their Laplace sd), all internal coordinates."""
    stop = len(fit.mode.x) if end is None else end
    s, n = slice(stop - k, stop), fit.space.n_base
    return (
        fit.mode.x[s],
        fit.space.null_internal()[s.start - n : s.stop - n],
        fit.space.box()[s],
        np.sqrt(np.diag(fit.covariance))[s],
    )


def effect_excludes_null(fit: Fit, k: int, end: int | None = None) -> bool:
    x, null, _, sd = _member(fit, k, end)
    return bool(np.any(np.abs(x - null) > 2.0 * sd))


#: an effect's parameter within this share of its prior range of a value sits at it
AT_VALUE = 1e-3


def effect_at_null(fit: Fit, k: int, end: int | None = None) -> bool:
    """Every parameter of an added effect (default: the last) fitted at its null
    value: the data asked nothing of it."""
    x, null, box, _ = _member(fit, k, end)
    return bool(np.all(np.abs(x - null) <= AT_VALUE * (box[:, 1] - box[:, 0])))


def effect_at_bound(fit: Fit, k: int, end: int | None = None) -> bool:
    """A parameter of an added effect (default: the last) on a bound of its prior
    (other than its null): the fit wanted more than the prior allows, a sign of a
    wrong model, or of an effect taking another's share as well."""
    x, null, box, _ = _member(fit, k, end)
    tol = AT_VALUE * (box[:, 1] - box[:, 0])
    on = (np.abs(x - box[:, 0]) <= tol) | (np.abs(x - box[:, 1]) <= tol)
    return bool(np.any(on & (np.abs(x - null) > tol)))


#: a nested fit whose log L ends more than this below the model without its effect has failed
FAILED_FIT_LOG_L = 0.5


def failed_fit(fit: Fit, without: Fit) -> bool:
    """A model with an effect contains the model without it (the effect at its null), so
    its optimum cannot be worse: a fit that ends more than :data:`FAILED_FIT_LOG_L` below
    ``without`` in log L has not found its optimum (its 2 ln B is no evidence)."""
    return bool(fit.mode.cost > without.mode.cost + FAILED_FIT_LOG_L)


def _improves_held_out(row: dict) -> bool:
    """The held-out tests predicted better beyond their noise (no validation test: the
    evidence alone decides, and the result says so)."""
    return row.get("held_out") is None or bool(row["held_out"]["improves"])


def names_effect(row: dict) -> bool:
    """The naming rule for one candidate's evidence row: decisive evidence
    (2 ln B > :data:`DECISIVE`, each model under its own model-form error,
    :mod:`bayes_update.core.comparison`), a parameter more than 2 sd from its null, the fit neither at its null
    nor on a bound of its prior nor failed, and the held-out tests predicted better
    beyond their noise (:mod:`bayes_update.core.held_out`)."""
    return bool(
        row["two_ln_B"] is not None
        and row["two_ln_B"] > DECISIVE
        and row["excludes_null"]
        and not row["at_null"]
        and not row["at_bound"]
        and _improves_held_out(row)
    )


def names_pair(row: dict, partner_alone: float, first_alone: float) -> bool:
    """The naming rule for two effects fitted together, tried when the strongest
    single candidate sat on a bound of its prior (``row["members"]``: each
    member's flags): decisive against the model without both, decisive against
    each member alone (``partner_alone`` and ``first_alone``, their 2 ln B: each
    must add what the other cannot), each member more than 2 sd from its
    null, neither at its null nor on a bound, and the held-out tests predicted
    better beyond their noise."""
    return bool(
        row["two_ln_B"] > DECISIVE
        and row["two_ln_B"] - partner_alone > DECISIVE
        and row["two_ln_B"] - first_alone > DECISIVE
        and all(m["excludes_null"] and not m["at_null"] and not m["at_bound"] for m in row["members"].values())
        and _improves_held_out(row)
    )


def best_extra_starts(problem: Problem, space: ExtendedSpace, lik, x0, executor, n_best: int = 2) -> tuple[list, int]:
    """(the ``n_best`` lowest-cost of the model's ``extra_starts(x0)``, model runs);
    none if it offers none."""
    extra = getattr(problem.model, "extra_starts", None)
    grid = [np.asarray(g, float) for g in extra(x0)] if callable(extra) else []
    if not grid:
        return [], 0
    fun = ResidualFunction(
        problem, problem.stages, tuple(lik.scales[s].sd for s in problem.stages), SpacePoint(space, problem.model)
    )
    cost = [0.5 * float(r @ r) for r in evaluate_many(fun, grid, executor, progress=False)]
    return [grid[i] for i in np.argsort(cost)[:n_best]], len(grid) * len(problem.stages)


def noise_floor(problem: Problem, test) -> float:
    """The relative output error a perfect model would have on ``test``: each
    sensor's measurement noise (:meth:`Problem.test_noise`) over its rms, the
    rms over the sensors [-]."""
    y = test.response if test.response.ndim == 2 else test.response[:, None]
    ratios = problem.test_noise(test.name) / np.sqrt(np.mean(y**2, axis=0))
    return float(np.sqrt(np.mean(np.square(ratios))))


#: what each entry of a gap is (the rows of the gap table and the keys of discrepancy.json alike)
GAP_LABELS = {
    "e_lin": "e_lin: relative error of the linear test's compared components",
    "e_nlin": "e_nlin: relative error of the nonlinear test's compared components",
    "held_out_relative_error": "held-out tests: relative output error (mean over the tests)",
    "held_out_error_beyond_noise": "held-out tests: output error beyond their noise (mean over the tests)",
    "held_out_noise_floor": "held-out tests: the relative error their noise alone gives (mean)",
}


def gap(fit: Fit, problem: Problem, floors: dict) -> dict:
    """e_lin, e_nlin and the held-out (validation) tests' output error at ``fit``'s mode
    (:data:`GAP_LABELS`): ``held_out_error_beyond_noise`` is sqrt(rel^2 - floor^2)
    averaged over the tests (the noise alone gives rel = floor, which no model
    removes), ``held_out_relative_error`` the raw mean, ``held_out_tests`` per test; the means
    over the tests the model runs, those it cannot (it diverged) in ``held_out_cannot_run``."""
    out = {**fit.metrics, "e_sum": float(sum(fit.metrics.values()))}
    every = problem.prediction_errors(fit.theta)
    val = {k: v for k, v in every.items() if math.isfinite(v)}
    if len(val) < len(every):
        out["held_out_cannot_run"] = [k for k in every if k not in val]
    if val:
        excess = [math.sqrt(max(v**2 - (floors.get(k) or 0.0) ** 2, 0.0)) for k, v in val.items()]
        out["held_out_error_beyond_noise"] = float(np.mean(excess))
        out["held_out_relative_error"] = float(np.mean(list(val.values())))
        out["held_out_noise_floor"] = float(np.mean([floors.get(k) or 0.0 for k in val]))
        out["held_out_tests"] = {k: {"relative_error": v, "noise_floor": floors.get(k)} for k, v in val.items()}
    return out


def signature_changes(model, named, d0, d1, gap0, gap1) -> dict:
    """For each named effect, the number its physics should move (the model's
    ``signature(effect, diagnostics, gap)``), before and after."""
    sig = getattr(model, "signature", None)
    out = {}
    for name in named if callable(sig) and d0 is not None else ():
        got = sig(name, d0, gap0)
        if got is None:
            continue
        key, meaning, before = got
        after = sig(name, d1, gap1)[2]
        out[name] = {
            "signature": key,
            "meaning": meaning,
            "before": before,
            "after": after,
            "shrank": bool(before is not None and after is not None and after < before),
        }
    return out
