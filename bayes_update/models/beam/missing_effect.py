"""Name the effect the model misses, add it, re-update, show the gap shrink.

The workflow (:func:`find_missing_effect`, CLI ``bayes-update discrepancy``):

1. **baseline**: the likelihood scales (noise replicates and model error,
   :func:`bayes_update.core.likelihood.estimate_likelihood`) and the mode of the
   baseline model (eta, c, P_eff, k_s) by least squares
   (:mod:`bayes_update.core.mode`), from the deterministic start;
2. **diagnostics** at that mode (:func:`bayes_update.models.beam.diagnostics.diagnose`):
   by test, kernel order, sine harmonic and free-decay amplitude;
3. **candidates**: each effect of the catalogue (:data:`CANDIDATES`, the four
   of :data:`fe.EFFECTS`) is added with its own parameters under a uniform
   prior on a physical range; the extended model's mode is found from the
   baseline mode (and a few starts of the effect's parameters);
4. **evidence**: Laplace approximation of log p(data | model) with the
   Gauss-Newton precision at each mode and the uniform priors' densities
   (the Occam factor of an added parameter is its posterior width over its
   prior width); ``2 ln B`` against the baseline.  A candidate is named when
   ``2 ln B > 6`` (decisive on the Kass-Raftery scale) and its parameter's
   Laplace interval (mode +- 2 sd) excludes the "no effect" value; then
   the search is repeated with the named effect in the model (a second effect
   is named by the same rule, so a combined case reports both or says what
   gap remains);
5. **re-update**: the named effects' likelihood scales are re-measured
   with them in the model (the model error of a bowed beam is not the
   straight one's); the extended mode and its Laplace posterior; the gap
   before and after: e_lin, e_nlin and the validation tests' misfit;
6. **does it explain the gap?** Evidence only ranks the catalogue: an effect
   the catalogue lacks still makes some candidate decisively better than
   the baseline (a damper took up a tenth of a hidden clamp's misfit).  So
   the named effects must also bring e_lin and e_nlin at the extended mode
   within :data:`EXPLAINED_FACTOR` times what noise and the extended model's
   own unabsorbed error leave (:func:`misfit_allowance`); otherwise nothing
   is named, the verdict is "no candidate explains the gap", and the
   effects that passed the evidence rule are reported as ``tentative``
   with the gap they would have left.

Signature check: each candidate names the diagnostic its physics should move
(:attr:`Candidate.signature`); the report states whether that diagnostic
shrank when the named effect was added.

All parameter values in reports are in the units of :class:`EffectParameter`
(mm, g, N/mm, ...) and SI in ``effect`` dicts.
"""
from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field

import numpy as np

import fe

from bayes_update.models.beam.rig import rig_of
# the naming rules, shared with the generic engine (bayes_update.core.discrepancy)
from bayes_update.core.effects import (DECISIVE, EXPLAINED_FACTOR, NamingVerdict, evidence_table,  # noqa: F401
                                       misfit_allowance, misfit_ratios)
from bayes_update.data.dataset import Dataset
from surrogates.evaluation import default_executor
from bayes_update.models.beam.space import NAMES, UNITS, ParameterSpace
from bayes_update.core.likelihood import Likelihood, estimate_likelihood
from bayes_update.models.beam.problem import UpdatingProblem
from bayes_update.core.mode import ModeResult, ResidualFunction, find_mode, laplace_log_evidence


@dataclass(frozen=True)
class EffectParameter:
    name: str
    unit: str
    low: float
    high: float
    to_si: float          # factor from ``unit`` to SI
    null: float = 0.0     # the value at which the effect vanishes

    @property
    def width(self) -> float:
        return self.high - self.low


@dataclass(frozen=True)
class Candidate:
    """A named effect with its parameters' uniform priors (report units)."""

    name: str
    parameters: tuple
    signature: str        # the diagnostic its physics moves (see SIGNATURES)

    def effect(self, values) -> fe.effects.Effect:
        """The :mod:`fe` effect at ``values`` (report units, one per parameter)."""
        v = [float(x) * p.to_si for x, p in zip(values, self.parameters)]
        if self.name == "initial_imperfection":
            return fe.InitialImperfection(amplitude=v[0])
        if self.name == "amplitude_dependent_damping":
            return fe.AmplitudeDependentDamping(kind="quadratic", coefficient=max(v[0], 0.0))
        if self.name == "shaker_attachment":
            return fe.ShakerAttachment(mass=max(v[0], 0.0), stiffness=max(v[1], 0.0))
        if self.name == "clamp_compliance":
            return fe.ClampCompliance(stiffness=math.inf if v[0] <= 0 else 1.0 / v[0])
        raise ValueError(f"no effect named {self.name!r}")

    def values_of(self, effect) -> list:
        """Report-unit values of an :mod:`fe` effect of this kind (the inverse of :meth:`effect`)."""
        if self.name == "initial_imperfection":
            si = [effect.amplitude]
        elif self.name == "amplitude_dependent_damping":
            si = [effect.coefficient]
        elif self.name == "shaker_attachment":
            si = [effect.mass, effect.stiffness]
        elif self.name == "clamp_compliance":
            si = [0.0 if math.isinf(effect.stiffness) else 1.0 / effect.stiffness]
        else:
            raise ValueError(f"no effect named {self.name!r}")
        return [s / p.to_si for s, p in zip(si, self.parameters)]

    def log_prior_density(self) -> float:
        return -sum(math.log(p.width) for p in self.parameters)


#: What each signature means (the diagnostic that should shrink).
SIGNATURES = {
    "y2": "the residual's second-order share in the high-level chirp (a broken symmetry)",
    "y3": "the residual's third-order share in the high-level chirp (nonlinear dissipation)",
    "validation": "the validation tests' misfit (a linear change the two-coefficient y1 absorbs)",
}

#: The catalogue with the priors of the effects' parameters (physical ranges
#: for the rig: a strip 460 x 18 x 2 mm, EI/L = 0.58 N m/rad).
CANDIDATES = {
    "initial_imperfection": Candidate(
        "initial_imperfection", (EffectParameter("amplitude", "mm", -1.0, 1.0, 1e-3),), "y2"),
    "amplitude_dependent_damping": Candidate(
        "amplitude_dependent_damping", (EffectParameter("coefficient", "MN s^2/m^2", 0.0, 200.0, 1e6),), "y3"),
    "shaker_attachment": Candidate(
        "shaker_attachment", (EffectParameter("mass", "g", 0.0, 40.0, 1e-3),
                              EffectParameter("stiffness", "N/mm", 0.0, 4.0, 1e3)), "validation"),
    "clamp_compliance": Candidate(
        "clamp_compliance", (EffectParameter("flexibility", "rad/(N m)", 0.0, 0.2, 1.0),), "validation"),
}
assert set(CANDIDATES) == set(fe.EFFECTS)


@dataclass
class ExtendedMap:
    """Picklable ``x -> (model, parameters)``: x = (eta, c, P_eff, k_s, effect
    parameters of each candidate in ``added`` in turn)."""

    space: ParameterSpace
    model: object
    added: tuple = ()     # Candidates

    def __call__(self, x):
        x = np.asarray(x, float)
        effects, i = [], 4
        for cand in self.added:
            k = len(cand.parameters)
            effects.append(cand.effect(x[i:i + k]))
            i += k
        model = dataclasses.replace(self.model, effects=tuple(self.model.effects) + tuple(effects))
        return model, self.space.to_parameters(x[:4])


@dataclass(frozen=True)
class DiscrepancySettings:
    n_replicates: int = 24         # noise replicates for the likelihood scales
    max_iterations: int = 50       # least-squares iterations (model evaluations) per start
    max_effects: int = 2           # effects named at most (greedy, one at a time)
    validation: bool = True        # simulate the validation tests before and after
    band_starts: bool = True       # baseline also started on the c-k_s band (not only at the start)
    reestimate_likelihood: bool = True   # likelihood scales again at the baseline's mode
    seed: int = 0

    @classmethod
    def quick(cls, **kw) -> "DiscrepancySettings":
        base = dict(n_replicates=8, max_iterations=30, band_starts=False, reestimate_likelihood=False)
        base.update(kw)
        return cls(**base)


@dataclass
class Fit:
    """One model (baseline + added effects) at its mode."""

    added: tuple                 # Candidates
    mode: ModeResult
    log_evidence: float
    covariance: np.ndarray
    metrics: dict                # e_lin, e_nlin at the mode

    @property
    def names(self) -> list:
        return [c.name for c in self.added]

    def effect_values(self) -> list:
        """[(candidate, [(parameter, mode, sd)])] for the added effects."""
        out, i = [], 4
        sd = np.sqrt(np.diag(self.covariance))
        for cand in self.added:
            rows = []
            for p in cand.parameters:
                rows.append((p, float(self.mode.x[i]), float(sd[i])))
                i += 1
            out.append((cand, rows))
        return out


def _bounds(space: ParameterSpace, added) -> tuple[np.ndarray, np.ndarray]:
    box = space.box()
    lo, hi = list(box[:, 0]), list(box[:, 1])
    for cand in added:
        lo += [p.low for p in cand.parameters]
        hi += [p.high for p in cand.parameters]
    return np.array(lo), np.array(hi)


def _effect_starts(cand: Candidate) -> list:
    """The start of a candidate's parameters: a tenth of the range above the
    null value (least squares crosses zero where the range has both signs:
    a bow's sign flips y2, smoothly)."""
    return [[p.null + 0.1 * (p.high - p.null) for p in cand.parameters]]


def fit_model(problem: UpdatingProblem, space: ParameterSpace, lik: Likelihood, added, starts,
              settings: DiscrepancySettings, executor=None) -> Fit:
    """Mode, Laplace covariance and log evidence of the baseline + ``added``."""
    stages = problem.stages
    fun = ResidualFunction(problem, stages, tuple(lik.scales[s].sd for s in stages),
                           ExtendedMap(space, problem.model, tuple(added)))
    lo, hi = _bounds(space, added)
    steps = 1e-4 * (hi - lo)
    mode = find_mode(fun, starts, lo, hi, steps, executor, max_iterations=settings.max_iterations)
    cov = mode.covariance(scale=hi - lo)
    # the uniform prior's density in (eta, c, P_eff, k_s) is (K_b + k_s) / K_b
    # over its volume; the least squares keep to the bounding box (the mode
    # may sit where F is slightly outside its range), so no support check here
    log_prior = math.log((space.kb + mode.x[3]) / space.kb) - _log_prior_volume(space)
    log_prior += sum(c.log_prior_density() for c in added)
    logz = laplace_log_evidence(mode, log_prior, _widths(space, added))
    r = mode.residual
    n = len(r) // len(stages)
    metrics = {Likelihood.key(st): float(np.linalg.norm(r[i * n:(i + 1) * n]) * lik.scales[st].sd)
               for i, st in enumerate(stages)}
    return Fit(tuple(added), mode, logz, cov, metrics)


def _widths(space: ParameterSpace, added) -> np.ndarray:
    """Prior widths in the fitted coordinates: the box's in (eta, c, P_eff,
    k_s) (P_eff's range at the mode's k_s is the F range scaled) and each
    effect parameter's."""
    box = space.box()
    w = list(box[:, 1] - box[:, 0])
    for cand in added:
        w += [p.width for p in cand.parameters]
    return np.array(w)


def _log_prior_volume(space: ParameterSpace) -> float:
    """log of the prior box's volume in (eta, c, F, k_s)."""
    return sum(math.log(hi - lo) for lo, hi in (space.eta, space.c, space.F, space.k_s))


def _excludes_null(fit: Fit, cand: Candidate) -> bool:
    for c, rows in fit.effect_values():
        if c.name == cand.name:
            return any(abs(m - p.null) > 2.0 * sd for p, m, sd in rows)
    return False


@dataclass
class DiscrepancyResult(NamingVerdict):
    named: list                  # candidate names, in the order they were named
    rounds: list                 # per round: {"base": [...], "candidates": [...]} (JSON-ready)
    baseline: Fit
    final: Fit
    likelihood: Likelihood       # of the baseline
    final_likelihood: Likelihood
    diagnostics_before: dict
    diagnostics_after: dict
    gap_before: dict
    gap_after: dict
    signature: dict
    timing: dict
    space: ParameterSpace = field(repr=False, default=None)
    explains_gap: bool = True    # the final model's misfit is within what noise and model error leave
    misfit_ratio: dict = field(default_factory=dict)   # e_lin, e_nlin over misfit_allowance (of the model checked)
    tentative: list = field(default_factory=list)      # decisive by evidence, but did not explain the gap
    gap_with_tentative: dict | None = None             # the gap the tentative effects would have left

    def to_json(self) -> dict:
        return {**self.decision_json(),
                "candidates": self.rounds[0]["candidates"] if self.rounds else [],
                "rounds": self.rounds,
                "gap_before": self.gap_before, "gap_after": self.gap_after,
                "signature_check": self.signature,
                "baseline_mode": _x_dict(self.baseline.mode.x),
                "final_mode": _fit_dict(self.final),
                "likelihood": self.likelihood.to_dict(),
                "final_likelihood": self.final_likelihood.to_dict(),
                "timing_s": self.timing}


def _x_dict(x) -> dict:
    return {f"{n}_{UNITS[n].replace(' ', '_').replace('/', '_per_')}": float(v) for n, v in zip(NAMES, x[:4])}


def _fit_dict(fit: Fit) -> dict:
    sd = np.sqrt(np.diag(fit.covariance))
    out = {"parameters": {n: {"mode": float(fit.mode.x[i]), "sd": float(sd[i]), "unit": UNITS[n]}
                          for i, n in enumerate(NAMES)},
           "effects": {}, "e_lin": fit.metrics["e_lin"], "e_nlin": fit.metrics["e_nlin"],
           "log_evidence": fit.log_evidence}
    for cand, rows in fit.effect_values():
        out["effects"][cand.name] = {p.name: {"mode": m, "sd": s, "unit": p.unit, "prior": [p.low, p.high]}
                                     for p, m, s in rows}
    return out


def noise_floors(dataset: Dataset, role: str = "validation") -> dict:
    """{test: the relative L2 misfit a perfect model would have} = the
    velocity's white-noise sd (read above the excited band) over its RMS."""
    from bayes_update.core.likelihood import noise_band, white_noise_sd

    fs = dataset.sampling_rate_hz
    out = {}
    for t in dataset.by_role(role):
        sd = white_noise_sd(t.velocity, fs, noise_band(t.force, fs))
        out[t.name] = float(sd / np.sqrt(np.mean(t.velocity ** 2)))
    return out


def _gap(fit: Fit, validation: dict | None, floors: dict) -> dict:
    """e_lin, e_nlin and the validation misfit.  ``validation`` is the misfit
    beyond the noise, sqrt(rel_l2^2 - floor^2) averaged over the validation
    tests (the noise alone gives rel_l2 = floor, about 1 % at 40 dB, which no
    model removes); ``validation_rel_l2`` the raw mean."""
    out = {"e_lin": fit.metrics["e_lin"], "e_nlin": fit.metrics["e_nlin"],
           "e_sum": fit.metrics["e_lin"] + fit.metrics["e_nlin"]}
    if validation is not None:
        tests = {k: v for k, v in validation.items() if not k.startswith("_")}
        if tests:
            excess = [math.sqrt(max(v["rel_l2"] ** 2 - floors.get(k, 0.0) ** 2, 0.0)) for k, v in tests.items()]
            out["validation"] = float(np.mean(excess))
            out["validation_rel_l2"] = float(np.mean([v["rel_l2"] for v in tests.values()]))
        out["validation_tests"] = {k: dict({kk: vv for kk, vv in v.items() if kk in ("rel_l2", "psd_db_rms")},
                                           noise_floor=floors.get(k)) for k, v in tests.items()}
    return out


def _model_with(model, fit: Fit, space: ParameterSpace):
    return ExtendedMap(space, model, fit.added)(fit.mode.x)


def find_missing_effect(dataset: Dataset, model=None, *, space: ParameterSpace | None = None,
                        start: fe.Parameters | None = None, candidates=None,
                        settings: DiscrepancySettings | None = None, executor=None, workers=None,
                        progress: bool = True, log=print) -> DiscrepancyResult:
    """The workflow of the module docstring on ``dataset`` (never told what is hidden).

    Parameters
    ----------
    model : the baseline updating model (default ``fe.BeamModel``; it must
        accept effects, so not the modal ROM).
    start : baseline start (default: the deterministic two-stage updating on coarse grids).
    candidates : names from :data:`CANDIDATES` (default all four).
    """
    from bayes_update.models.beam.calibrate import CalibrationSettings, calibrate
    from bayes_update.models.beam.diagnostics import diagnose
    from bayes_update.models.beam.validation import validate

    settings = settings or DiscrepancySettings()
    model = model if model is not None else fe.BeamModel(rig=rig_of(dataset))
    if isinstance(model, fe.ModalROM):
        raise ValueError("the discrepancy workflow adds effects the modal ROM cannot carry "
                         "(only a bow fits its reduced form): use fe.BeamModel")
    names = list(CANDIDATES) if candidates is None else list(candidates)
    unknown = [n for n in names if n not in CANDIDATES]
    if unknown:
        raise ValueError(f"unknown candidate effect(s) {unknown}; choose from {sorted(CANDIDATES)}")
    space = space or ParameterSpace(rig_of(dataset))
    problem = UpdatingProblem(dataset, model)
    if "nonlinear" not in problem.stages:
        raise ValueError(f"{problem.source}: the discrepancy workflow needs the high-level test "
                         "(role 'nonlinear') as well as the linear one")
    own_pool = executor is None and (workers or 2) > 1
    pool = default_executor(workers) if own_pool else executor
    timing = {}
    t_all = time.perf_counter()
    try:
        t0 = time.perf_counter()
        if start is None:
            log("baseline start: the deterministic two-stage updating on coarse grids")
            start = calibrate(dataset, model, CalibrationSettings.quick(), executor=pool, progress=progress,
                              log=lambda *a: None).final_params
        x0 = np.clip(space.to_internal(start), space.box()[:, 0], space.box()[:, 1])
        lik = estimate_likelihood(problem, space.to_parameters(x0), n_replicates=settings.n_replicates,
                                  seed=settings.seed, space=space).unabsorbed()
        base_starts = [x0] + (space.extra_starts(x0, n=2) if settings.band_starts else [])
        base = fit_model(problem, space, lik, (), base_starts, settings, pool)
        if settings.reestimate_likelihood:
            # the likelihood at the baseline's mode, not at the coarse start
            lik = estimate_likelihood(problem, space.to_parameters(base.mode.x),
                                      n_replicates=settings.n_replicates, seed=settings.seed,
                                      space=space).unabsorbed()
            base = fit_model(problem, space, lik, (), [base.mode.x], settings, pool)
        timing["baseline"] = time.perf_counter() - t0
        log(f"baseline: e_lin {100 * base.metrics['e_lin']:.3f} %, e_nlin {100 * base.metrics['e_nlin']:.3f} % "
            f"(likelihood scales {100 * lik.scales['linear'].sd:.3f} %, {100 * lik.scales['nonlinear'].sd:.3f} %)")
        # rounds of naming -------------------------------------------------------------
        t0 = time.perf_counter()
        current, rounds, named = base, [], []
        remaining = [CANDIDATES[n] for n in names]
        for _ in range(settings.max_effects):
            rows, fits = [], {}
            for cand in remaining:
                starts = [list(current.mode.x) + list(v) for v in _effect_starts(cand)]
                fit = fit_model(problem, space, lik, current.added + (cand,), starts, settings, pool)
                fits[cand.name] = fit
                two_ln_b = 2.0 * (fit.log_evidence - current.log_evidence)
                values = {p.name: {"mode": m, "sd": s, "unit": p.unit} for p, m, s in fit.effect_values()[-1][1]}
                rows.append({"name": cand.name, "two_ln_B": two_ln_b,
                             "delta_log_likelihood": float(current.mode.cost - fit.mode.cost),
                             "n_parameters": len(cand.parameters), "parameters": values,
                             "excludes_null": _excludes_null(fit, cand),
                             "e_lin": fit.metrics["e_lin"], "e_nlin": fit.metrics["e_nlin"]})
                log(f"  {cand.name}: 2 ln B = {two_ln_b:.1f}, " + ", ".join(
                    f"{k} = {v['mode']:.4g} +- {v['sd']:.2g} {v['unit']}" for k, v in values.items()))
            rows.sort(key=lambda r: -r["two_ln_B"])
            rounds.append({"base": current.names, "candidates": rows})
            best = rows[0] if rows else None
            if best is None or best["two_ln_B"] <= DECISIVE or not best["excludes_null"]:
                break
            named.append(best["name"])
            # polish the named fit (its start was the baseline's): the next
            # round must not name a second effect for what this one's
            # unfinished fit left over
            current = fits[best["name"]]
            if len(named) < settings.max_effects:
                current = fit_model(problem, space, lik, current.added, [current.mode.x], settings, pool)
            remaining = [c for c in remaining if c.name != best["name"]]
            log(f"named: {best['name']}")
        timing["naming"] = time.perf_counter() - t0
        # re-update with the named effects: their own likelihood scales -----------------
        t0 = time.perf_counter()
        final, final_lik = base, lik
        if named:
            ext_model, ext_params = _model_with(model, current, space)
            ext_problem = UpdatingProblem(dataset, ext_model, basis=problem.basis)
            final_lik = estimate_likelihood(ext_problem, ext_params, n_replicates=settings.n_replicates,
                                            seed=settings.seed + 1, space=space)
            final = fit_model(problem, space, final_lik, current.added, [current.mode.x], settings, pool)
        timing["re_update"] = time.perf_counter() - t0
        # does the model (with the named effects) explain the data? -------------------
        # the naming fit (comparison scales) against what noise and the extended
        # model's own unabsorbed error leave; otherwise nothing is named
        misfit = misfit_ratios(current if named else base, final_lik if named else lik)
        explains = all(r <= EXPLAINED_FACTOR for r in misfit.values())
        tentative, tentative_fit = [], None
        if named and not explains:
            log(f"{', '.join(named)} leave(s) the misfit at " + ", ".join(
                f"{k} {v:.1f}x" for k, v in misfit.items()) + " what noise and model error allow: "
                "no candidate explains the gap")
            tentative, tentative_fit, named = named, final, []
            final, final_lik = base, lik
        # gap before and after --------------------------------------------------------
        t0 = time.perf_counter()
        m0, p0 = _model_with(model, base, space)
        m1, p1 = _model_with(model, final, space)
        val0 = val1 = None
        if settings.validation and dataset.by_role("validation"):
            val0 = validate(dataset, m0, p0, progress=False)
            val1 = validate(dataset, m1, p1, progress=False) if named else val0
        d0 = diagnose(dataset, m0, p0, basis=problem.basis)
        d1 = diagnose(dataset, m1, p1, basis=problem.basis) if named else d0
        floors = noise_floors(dataset) if val0 is not None else {}
        gap_before, gap_after = _gap(base, val0, floors), _gap(final, val1, floors)
        signature = _signature_check(named, d0, d1, gap_before, gap_after, problem)
        gap_tentative = None
        if tentative_fit is not None:
            mt, pt = _model_with(model, tentative_fit, space)
            val_t = validate(dataset, mt, pt, progress=False) if val0 is not None else None
            gap_tentative = _gap(tentative_fit, val_t, floors)
        timing["gap"] = time.perf_counter() - t0
    finally:
        if own_pool:
            pool.shutdown()
    timing["total"] = time.perf_counter() - t_all
    return DiscrepancyResult(named=named, rounds=rounds, baseline=base, final=final, likelihood=lik,
                             final_likelihood=final_lik, diagnostics_before=d0, diagnostics_after=d1,
                             gap_before=gap_before, gap_after=gap_after, signature=signature, timing=timing,
                             space=space, explains_gap=explains, misfit_ratio=misfit, tentative=tentative,
                             gap_with_tentative=gap_tentative)


def _signature_value(sig: str, diag: dict, gap: dict, problem: UpdatingProblem):
    high = problem.tests["nonlinear"].name
    if sig in ("y2", "y3"):
        return diag["by_order"].get(high, {}).get(sig)
    if sig == "validation":
        return gap.get("validation")
    raise ValueError(sig)


def _signature_check(named, d0, d1, gap0, gap1, problem) -> dict:
    out = {}
    for name in named:
        sig = CANDIDATES[name].signature
        before = _signature_value(sig, d0, gap0, problem)
        after = _signature_value(sig, d1, gap1, problem)
        out[name] = {"signature": sig, "meaning": SIGNATURES[sig], "before": before, "after": after,
                     "shrank": bool(before is not None and after is not None and after < before)}
    return out


# ------------------------------------------------------------------- output
def gap_figure(res: DiscrepancyResult, dataset: Dataset):
    """Before/after: the metrics and validation misfit, the evidence, and the
    residual PSD of a validation test (or the high-level chirp)."""
    from matplotlib.figure import Figure

    from bayes_update.data.spectral import psd

    fig = Figure(figsize=(15, 4.2), constrained_layout=True)
    a1, a2, a3 = fig.subplots(1, 3)
    keys = [k for k in ("e_lin", "e_nlin", "validation") if res.gap_before.get(k) is not None]
    x = np.arange(len(keys))
    after_label = ("after (+ " + ", ".join(res.named) + ")" if res.named else
                   "after (nothing named: no candidate explains the gap)" if not res.explains_gap else
                   "after (nothing named)")
    a1.bar(x - 0.2, [100 * res.gap_before[k] for k in keys], 0.4, label="baseline", color="C3")
    a1.bar(x + 0.2, [100 * res.gap_after[k] for k in keys], 0.4, label=after_label, color="C2")
    a1.set_yscale("log")
    a1.set_xticks(x, ["e_lin", "e_nlin", "validation misfit\nbeyond noise"][:len(keys)])
    a1.set_ylabel("misfit [%]")
    a1.set_title("the gap before and after")
    a1.legend(fontsize=8)
    rows = res.rounds[0]["candidates"] if res.rounds else []
    names = [r["name"].replace("_", "\n") for r in rows]
    vals = [r["two_ln_B"] for r in rows]
    a2.barh(range(len(rows)), vals, color=["C2" if r["name"] in res.named else "C7" for r in rows])
    a2.axvline(DECISIVE, color="k", ls="--", lw=0.8, label=f"decisive: 2 ln B = {DECISIVE:g}")
    a2.set_xscale("symlog", linthresh=10)
    a2.set_yticks(range(len(rows)), names, fontsize=8)
    a2.invert_yaxis()
    a2.set_xlabel("2 ln B against the baseline")
    a2.set_title("evidence (round 1)")
    a2.legend(fontsize=8)
    val = dataset.by_role("validation")
    chirps = [t for t in val if t.signal == "chirp"] or [t for t in dataset.tests if t.role == "nonlinear"]
    t = chirps[0]
    fs = dataset.sampling_rate_hz
    f, p = psd(t.velocity, fs)
    a3.semilogy(f, p, color="k", lw=1, label=f"data ({t.name})")
    for d, lab, col in ((res.diagnostics_before, "residual, baseline", "C3"),
                        (res.diagnostics_after, "residual, after", "C2")):
        v = d["_velocity"].get(t.name)
        if v is not None:
            f, p = psd(t.velocity - v, fs)
            a3.semilogy(f, p, color=col, lw=1, label=lab)
    a3.set_xlim(0, 150)
    a3.set_xlabel("frequency [Hz]")
    a3.set_ylabel("velocity PSD [(m/s)^2/Hz]")
    a3.set_title("where the gap was")
    a3.legend(fontsize=8)
    return fig


def write_discrepancy(res: DiscrepancyResult, dataset: Dataset, out, truth: dict | None = None) -> dict:
    """Write discrepancy.json, evidence.md and the figures to ``out``."""
    import json
    from pathlib import Path

    from bayes_update.models.beam.diagnostics import diagnostics_figure

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    doc = res.to_json()
    if truth is not None:
        doc["truth"] = truth
    (out / "discrepancy.json").write_text(json.dumps(doc, indent=1, default=_json_default))
    (out / "evidence.md").write_text(evidence_table(res) + "\n")
    gap_figure(res, dataset).savefig(out / "gap_before_after.png", dpi=110)
    diagnostics_figure(res.diagnostics_before).savefig(out / "diagnostics_before.png", dpi=100)
    if res.named:
        diagnostics_figure(res.diagnostics_after).savefig(out / "diagnostics_after.png", dpi=100)
    return doc


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, (np.bool_,)):
        return bool(o)
    return str(o)


def format_result(res: DiscrepancyResult) -> str:
    b, a = res.gap_before, res.gap_after
    t = res.gap_with_tentative
    lines = [evidence_table(res), "",
             "gap          before      after" + ("   with " + " + ".join(res.tentative) if t else "")]
    for k in ("e_lin", "e_nlin", "validation"):
        if b.get(k) is not None:
            lines.append(f"{k:<12} {100 * b[k]:8.3f} %  {100 * a[k]:8.3f} %"
                         + (f"  {100 * t[k]:8.3f} %" if t and t.get(k) is not None else ""))
    for name, s in res.signature.items():
        lines.append(f"signature of {name} ({s['signature']}): {s['before']:.4g} -> {s['after']:.4g} "
                     f"({'shrank' if s['shrank'] else 'did NOT shrink'})")
    return "\n".join(lines)
