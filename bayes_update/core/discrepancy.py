"""The discrepancy workflow for any model of the contract: name the effect the
model misses, add it, re-update, show the gap shrink.

The model offers its candidates through ``candidate_effects()`` alone
(:mod:`bayes_update.core.effects`); the workflow and its rules are those of the
beam's :func:`bayes_update.models.beam.missing_effect.find_missing_effect`:

1. **baseline**: start at ``start`` or at the best of a Sobol' design over the
   prior (:func:`bayes_update.core.posterior.default_start`), the likelihood scales
   there (:func:`bayes_update.core.likelihood.estimate_likelihood`, with only the
   unabsorbed model error: a model comparison counts the rest as explained),
   the mode by least squares (:mod:`bayes_update.core.mode`) and its Laplace
   evidence; every candidate parameter is passed at its ``null``;
2. **candidates**: each effect's parameters are added (uniform prior on their
   bounds, log-uniform for ``log=True``); the extended mode is searched from
   the current mode with the effect's parameters at null and at +- a tenth of
   the range from it; Laplace log evidence and ``2 ln B`` against the model
   without it.  Named when ``2 ln B >`` :data:`DECISIVE` and the Laplace interval
   (mode +- 2 sd) of one of its parameters excludes the null; then a next
   round looks for a second effect (``max_effects``);
3. **re-update**: the likelihood scales re-measured with the named effects
   in the model, the extended mode and its Laplace posterior;
4. **does it explain the gap?** the named effects must bring e_lin and e_nlin
   within :data:`EXPLAINED_FACTOR` x :func:`misfit_allowance`; otherwise
   nothing is named, the verdict is "no candidate explains the gap" and the
   effects are reported as ``tentative``;
5. **gap** before and after: e_lin, e_nlin and, for each test with role
   ``validation``, the direct output error ||y - y_model|| / ||y|| (record
   means removed, as :class:`Problem` does).

Values are reported in each parameter's unit, under its declared name.
"""
from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from surrogates.evaluation import default_executor
from bayes_update.core.mode import ModeResult, ResidualFunction, SpacePoint, find_mode, laplace_log_evidence
from bayes_update.core.effects import (DECISIVE, EXPLAINED_FACTOR, ExtendedSpace, NamingVerdict, WithNulls,
                                       candidate_effects, evidence_table, misfit_ratios)
from bayes_update.core.calibrate import problem_for
from bayes_update.core.model import check_model_on
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.problem import DatasetError, Problem

__all__ = ["DiscrepancySettings", "DiscrepancyResult", "find_discrepancy", "write_discrepancy"]


@dataclass(frozen=True)
class DiscrepancySettings:
    n_replicates: int = 24         # noise replicates for the likelihood scales
    max_iterations: int = 50       # least-squares iterations per start
    max_effects: int = 2           # effects named at most (greedy, one at a time)
    n_start: int = 64              # Sobol' points of the start search (when no start is given)
    effect_start: float = 0.1      # effect starts: null and null +- this fraction of the range
    seed: int = 0

    @classmethod
    def quick(cls, **kw) -> "DiscrepancySettings":
        base = dict(n_replicates=8, max_iterations=30)
        base.update(kw)
        return cls(**base)


@dataclass
class Fit:
    """One model (baseline + added effects) at its mode."""

    names: list                  # added effects, in order
    space: ExtendedSpace
    mode: ModeResult
    log_evidence: float
    covariance: np.ndarray
    metrics: dict                # e_lin, e_nlin at the mode

    @property
    def theta(self) -> dict:
        return self.space.to_parameters(self.mode.x)

    def to_json(self, effects: dict) -> dict:
        values = self.space.values(self.mode.x, self.covariance)
        base = {n: v for n, v in self.theta.items() if n in self.space.base.names}
        sd = np.sqrt(np.diag(self.covariance))[:self.space.n_base]
        return {"parameters": {n: {"mode": base[n], "unit": self.space.base[n].unit,
                                   "sd_internal": float(s), "coordinate": c}
                               for n, s, c in zip(self.space.base.names, sd, self.space.base.coordinate_names)},
                "effects": {e: {p.name: values[p.name] for p in effects[e]} for e in self.names},
                "e_lin": self.metrics["e_lin"], "e_nlin": self.metrics["e_nlin"], "log_evidence": self.log_evidence}


def fit_model(problem: Problem, space: ExtendedSpace, names, lik, starts, settings, executor=None) -> Fit:
    """Mode, Laplace covariance and log evidence of the baseline + the parameters of ``space``."""
    stages = problem.stages
    fun = ResidualFunction(problem, stages, tuple(lik.scales[s].sd for s in stages), SpacePoint(space, problem.model))
    box = space.box()
    lo, hi = box[:, 0], box[:, 1]
    mode = find_mode(fun, starts, lo, hi, 1e-4 * (hi - lo), executor, max_iterations=settings.max_iterations)
    cov = mode.covariance(scale=hi - lo)
    logz = laplace_log_evidence(mode, space.log_prior_density(mode.x), hi - lo)
    r, n = mode.residual, len(mode.residual) // len(stages)
    metrics = {("e_lin" if st == "linear" else "e_nlin"):
               float(np.linalg.norm(r[i * n:(i + 1) * n]) * lik.scales[st].sd) for i, st in enumerate(stages)}
    return Fit(list(names), space, mode, logz, cov, metrics)


def _effect_starts(space: ExtendedSpace, k: int, fraction: float) -> list:
    """Starts of the last ``k`` coordinates: the null, and null +- ``fraction`` of
    the range towards each bound (where the range extends that way)."""
    box, null = space.box()[-k:], space.null_internal()[-k:]
    up = null + fraction * (box[:, 1] - null)
    down = null - fraction * (null - box[:, 0])
    out = [null]
    out += [v for v in (up, down) if not np.allclose(v, null)]
    return out


def _excludes_null(fit: Fit, k: int) -> bool:
    x, sd = fit.mode.x[-k:], np.sqrt(np.diag(fit.covariance))[-k:]
    return bool(np.any(np.abs(x - fit.space.null_internal()[-k:]) > 2.0 * sd))


def _gap(fit: Fit, problem: Problem) -> dict:
    """e_lin, e_nlin and the direct output error on each validation test at ``fit``'s mode."""
    out = {"e_lin": fit.metrics["e_lin"], "e_nlin": fit.metrics["e_nlin"],
           "e_sum": fit.metrics["e_lin"] + fit.metrics["e_nlin"]}
    val = problem.prediction_errors(fit.theta)
    if val:
        out["validation"] = float(np.mean(list(val.values())))
        out["validation_tests"] = {k: {"rel_l2": v} for k, v in val.items()}
    return out


@dataclass
class DiscrepancyResult(NamingVerdict):
    named: list                  # effect names, in the order they were named
    rounds: list                 # per round: {"base": [...], "candidates": [...]} (JSON-ready)
    baseline: Fit
    final: Fit
    likelihood: object           # of the baseline (unabsorbed model error)
    final_likelihood: object
    gap_before: dict
    gap_after: dict
    effects: dict                # the model's candidate_effects(), checked
    start: dict
    timing: dict
    explains_gap: bool = True
    misfit_ratio: dict = field(default_factory=dict)
    tentative: list = field(default_factory=list)
    gap_with_tentative: dict | None = None
    problem: Problem | None = field(default=None, repr=False)    # for the figures

    def to_json(self) -> dict:
        return {**self.decision_json(),
                "candidate_effects": {e: {p.name: {"low": p.low, "high": p.high, "unit": p.unit, "log": p.log,
                                                   "null": p.null} for p in ps} for e, ps in self.effects.items()},
                "candidates": self.rounds[0]["candidates"] if self.rounds else [],
                "rounds": self.rounds, "gap_before": self.gap_before, "gap_after": self.gap_after,
                "start": self.start,
                "baseline_mode": self.baseline.to_json(self.effects), "final_mode": self.final.to_json(self.effects),
                "likelihood": self.likelihood.to_dict(), "final_likelihood": self.final_likelihood.to_dict(),
                "timing_s": self.timing}


def find_discrepancy(dataset, model, *, start=None, candidates=None, settings: DiscrepancySettings | None = None,
                     metrics: str | None = None, executor=None, workers=None, progress: bool = False,
                     log=print) -> DiscrepancyResult:
    """The workflow of the module docstring for ``model`` (any model of the contract
    with ``candidate_effects()``) on ``dataset`` (tests with roles ``linear``,
    ``nonlinear`` and optionally ``validation``).

    Parameters
    ----------
    start : {name: value} of the model's parameters (default: the best of
        ``settings.n_start`` Sobol' points over the prior).
    candidates : effect names to consider (default: all the model offers).
    metrics : the metric set (default ``full``; :mod:`bayes_update.core.problem`).
    """
    from bayes_update.core.likelihood import estimate_likelihood  # the likelihood's scales (its module also serves the beam)
    from bayes_update.core.posterior import default_start

    settings = settings or DiscrepancySettings()
    base = ParameterSet(model.parameters, model)
    effects = candidate_effects(model, base.names)
    names = list(effects) if candidates is None else list(candidates)
    unknown = [n for n in names if n not in effects]
    if unknown:
        raise ValueError(f"unknown candidate effect(s) {unknown}; {type(model).__name__} offers {sorted(effects)}")
    nulls = {p.name: p.null for ps in effects.values() for p in ps}
    check_model_on(model, dataset, theta={**base.center(), **nulls})
    problem = problem_for(dataset, WithNulls(model, nulls), base, metrics)[0]
    if "nonlinear" not in problem.stages:
        raise DatasetError(f"{problem.source}: the discrepancy workflow needs the high-level test "
                           "(role 'nonlinear') as well as the linear one")
    own_pool = executor is None and (workers or 2) > 1
    pool = default_executor(workers) if own_pool else executor
    timing, t_all = {}, time.perf_counter()
    seeds = [int(s.generate_state(1)[0]) for s in np.random.SeedSequence(settings.seed).spawn(3)]

    def likelihood(space, theta, seed, unabsorbed=True):
        lik = estimate_likelihood(problem, theta, n_replicates=settings.n_replicates, seed=seed, space=space)
        return lik.unabsorbed() if unabsorbed else lik

    def fit(added, lik, starts):
        space = ExtendedSpace(base, [p for e in added for p in effects[e]])
        return fit_model(problem, space, added, lik, starts, settings, pool)

    try:
        # baseline ---------------------------------------------------------------------
        t0 = time.perf_counter()
        if start is None:
            start, _ = default_start(dataset, problem, base, pool, settings.n_start, seeds[0], progress, log)
        else:
            base.check(start, "start")
        start = {n: float(start[n]) for n in base.names}
        space0 = ExtendedSpace(base)
        lik = likelihood(space0, start, seeds[1])
        b = base.box()
        x0 = np.clip(base.to_internal(start), b[:, 0], b[:, 1])
        current = baseline = fit([], lik, [x0])
        timing["baseline"] = time.perf_counter() - t0
        log(f"baseline: e_lin {100 * baseline.metrics['e_lin']:.3f} %, e_nlin {100 * baseline.metrics['e_nlin']:.3f} %")
        # rounds of naming -------------------------------------------------------------
        t0 = time.perf_counter()
        rounds, named, remaining = [], [], list(names)
        for _ in range(settings.max_effects):
            rows, fits = [], {}
            for e in remaining:
                k = len(effects[e])
                trial = ExtendedSpace(base, list(current.space.added) + list(effects[e]))
                starts = [np.concatenate([current.mode.x, s]) for s in _effect_starts(trial, k, settings.effect_start)]
                f = fits[e] = fit(current.names + [e], lik, starts)
                two_ln_b = 2.0 * (f.log_evidence - current.log_evidence)
                values = {p.name: f.space.values(f.mode.x, f.covariance)[p.name] for p in effects[e]}
                rows.append({"name": e, "two_ln_B": two_ln_b,
                             "delta_log_likelihood": float(current.mode.cost - f.mode.cost),
                             "n_parameters": k, "parameters": values, "excludes_null": _excludes_null(f, k),
                             "e_lin": f.metrics["e_lin"], "e_nlin": f.metrics["e_nlin"]})
                log(f"  {e}: 2 ln B = {two_ln_b:.1f}, " + ", ".join(
                    f"{n} = {v['mode']:.4g} +- {v['sd']:.2g} {v['unit']}" for n, v in values.items()))
            rows.sort(key=lambda r: -r["two_ln_B"])
            rounds.append({"base": list(current.names), "candidates": rows})
            best = rows[0] if rows else None
            if best is None or best["two_ln_B"] <= DECISIVE or not best["excludes_null"]:
                break
            named.append(best["name"])
            remaining.remove(best["name"])
            current = fits[best["name"]]
            if len(named) < settings.max_effects and remaining:    # polish before the next round
                current = fit(current.names, lik, [current.mode.x])
            log(f"named: {best['name']}")
        timing["naming"] = time.perf_counter() - t0
        # re-update with the named effects' own likelihood scales ------------------------
        t0 = time.perf_counter()
        final, final_lik = baseline, lik
        if named:
            final_lik = likelihood(current.space, current.theta, seeds[2], unabsorbed=False)
            final = fit(current.names, final_lik, [current.mode.x])
        timing["re_update"] = time.perf_counter() - t0
        # do the named effects explain the gap? ------------------------------------------
        misfit = misfit_ratios(current if named else baseline, final_lik if named else lik)
        explains = all(r <= EXPLAINED_FACTOR for r in misfit.values())
        tentative, tentative_fit = [], None
        if named and not explains:
            log(f"{', '.join(named)} leave(s) the misfit at " + ", ".join(f"{k} {v:.1f}x" for k, v in misfit.items())
                + " what noise and model error allow: no candidate explains the gap")
            tentative, tentative_fit, named = named, final, []
            final, final_lik = baseline, lik
        # gap before and after -----------------------------------------------------------
        t0 = time.perf_counter()
        gap_before = _gap(baseline, problem)
        gap_after = _gap(final, problem) if named else gap_before
        gap_tentative = _gap(tentative_fit, problem) if tentative_fit is not None else None
        timing["gap"] = time.perf_counter() - t0
    finally:
        if own_pool:
            pool.shutdown()
    timing["total"] = time.perf_counter() - t_all
    return DiscrepancyResult(named=named, rounds=rounds, baseline=baseline, final=final, likelihood=lik,
                             final_likelihood=final_lik, gap_before=gap_before, gap_after=gap_after,
                             effects={e: effects[e] for e in names}, start=start, timing=timing,
                             explains_gap=explains, misfit_ratio=misfit, tentative=tentative,
                             gap_with_tentative=gap_tentative, problem=problem)


def format_result(res: DiscrepancyResult) -> str:
    b, a, t = res.gap_before, res.gap_after, res.gap_with_tentative
    lines = [evidence_table(res), "",
             "gap          before      after" + ("   with " + " + ".join(res.tentative) if t else "")]
    for k in ("e_lin", "e_nlin", "validation"):
        if b.get(k) is not None:
            lines.append(f"{k:<12} {100 * b[k]:8.3f} %  {100 * a[k]:8.3f} %"
                         + (f"  {100 * t[k]:8.3f} %" if t and t.get(k) is not None else ""))
    for e in res.named:
        for n, v in res.final.to_json(res.effects)["effects"][e].items():
            lines.append(f"{e}: {n} = {v['mode']:.5g} {v['unit']} (Laplace interval "
                         f"{v['interval'][0]:.5g} to {v['interval'][1]:.5g}; null {v['null']:g})")
    return "\n".join(lines)


def write_discrepancy(res: DiscrepancyResult, out, truth: dict | None = None) -> dict:
    """Write discrepancy.json and evidence.md to folder ``out``; returns the JSON document."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    doc = res.to_json()
    if truth is not None:
        doc["truth"] = truth
    (out / "discrepancy.json").write_text(json.dumps(doc, indent=1, default=_json_default))
    (out / "evidence.md").write_text(evidence_table(res) + "\n")
    return doc


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return str(o)
