"""The preloaded beam as a model of the contract: :class:`Beam`.

It wraps an ``fe`` model (``fe.BeamModel``, the full FE, or ``fe.ModalROM``,
~1 ms per run) and gives the framework what every model gives it:

* ``parameters``: eta [MPa s], c [N s/mm], F [N], k_s [N/mm] (the paper's
  units) with the uniform prior box of the beam study (docs/design.md);
* ``simulate(theta, force, fs)``: the transverse velocity at the sensor
  [m/s]; a point where the beam buckles or Newton diverges raises
  :class:`bayes_update.ModelError`;
* internal coordinates (eta, c, P_eff, k_s): e_lin depends on F and k_s
  almost only through the preload the beam carries,
  P_eff = F K_b / (K_b + k_s), so sampling in P_eff straightens a ridge; the
  uniform prior then has density (K_b + k_s) / K_b (the Jacobian of
  F -> P_eff), :meth:`log_jacobian`;
* ``refined()`` (the model-error term), ``candidate_effects()`` (the four
  effects of :data:`fe.EFFECTS`, each switched off at its null value), and
  the beam's optional hooks: ``start`` (the paper's grids),
  ``extra_starts`` (the c-k_s band), ``diagnose`` / ``effect_signatures``
  (harmonics, free decays, kernel orders; the discrepancy workflow's
  signature check).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

import fe
from bayes_update.core.model import ModelError, ModelSpecError
from bayes_update.core.parameters import Parameter
from bayes_update.models.beam.effects import (
    EFFECT_PARAMETERS,
    HIDDEN_EFFECT_RANGES,
    SIGNATURE_MEANING,
    SIGNATURES,
    effect_from_si,
    effect_values,
    hidden_effects,
)

__all__ = [
    "Beam",
    "EFFECT_PARAMETERS",
    "HIDDEN_EFFECT_RANGES",
    "hidden_effects",
    "effect_values",
    "MPA_S",
    "N_PER_MM",
    "N_S_PER_MM",
    "PRIOR",
    "beam_model",
]

MPA_S, N_S_PER_MM, N_PER_MM = 1e6, 1e3, 1e3

#: The beam study's prior box, paper units (docs/design.md, "Parameter space").
PRIOR = {"eta": (1.0, 6.0), "c": (0.0, 30.0), "F": (60.0, 95.0), "k_s": (0.0, 600.0)}
UNITS = {"eta": "MPa s", "c": "N s/mm", "F": "N", "k_s": "N/mm"}
_TO_SI = {"eta": MPA_S, "c": N_S_PER_MM, "F": 1.0, "k_s": N_PER_MM}


@dataclass(frozen=True)
class Beam:
    """The beam rig's FE model (or its ROM) as a model of the contract.

    Parameters
    ----------
    fe_model : ``fe.BeamModel`` or ``fe.ModalROM`` built for the data set's rig.
    prior : {name: (low, high)} in paper units for any of eta, c, F, k_s
        (the others keep :data:`PRIOR`).
    """

    fe_model: object
    prior: dict = field(default_factory=dict)

    #: the paper's metric set reproduces Tables 1-3 (docs/design.md, "Metrics")
    default_metrics = "paper"
    #: names and units of the internal coordinates (:meth:`to_internal`)
    internal_names = ("eta", "c", "P_eff", "k_s")
    internal_units = {"eta": "MPa s", "c": "N s/mm", "P_eff": "N", "k_s": "N/mm"}
    #: what the sensor measures
    response_kind, response_unit = "velocity", "m/s"
    #: the virtual rig's records carry no sensor offsets: they are kept as they are,
    #: so that the beam's numbers stay those of the paper reproduction
    remove_offsets = False

    def __post_init__(self):
        unknown = set(self.prior) - set(PRIOR)
        if unknown:
            raise ValueError(f"prior: unknown parameter(s) {sorted(unknown)}; the beam's are {list(PRIOR)}")
        box = {**PRIOR, **{k: tuple(float(v) for v in r) for k, r in self.prior.items()}}
        for name, (lo, hi) in box.items():
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"prior range of {name} must be finite with low < high, got {(lo, hi)}")
            if lo < 0 or (name in ("eta", "F") and lo <= 0):
                raise ValueError(
                    f"prior range of {name} must be {'positive' if name in ('eta', 'F') else 'non-negative'}"
                    f", got {(lo, hi)} {UNITS[name]}"
                )
        object.__setattr__(self, "prior", box)

    # -- the contract -----------------------------------------------------
    @property
    def rig(self) -> fe.Rig:
        return self.fe_model.rig

    @property
    def parameters(self) -> list:
        return [Parameter(n, *self.prior[n], unit=UNITS[n]) for n in PRIOR]

    def fe_parameters(self, theta) -> fe.Parameters:
        """``fe.Parameters`` (SI) of theta in paper units."""
        return fe.Parameters(**{n: float(theta[n]) * _TO_SI[n] for n in PRIOR})

    def theta_of(self, params: fe.Parameters) -> dict:
        """theta in paper units of ``fe.Parameters`` (SI)."""
        return {n: getattr(params, n) / _TO_SI[n] for n in PRIOR}

    def effects_of(self, theta) -> tuple:
        """The :mod:`fe` effects theta switches on (every parameter of an effect at its null: off)."""
        out = []
        for name, pars in EFFECT_PARAMETERS.items():
            values = [float(theta.get(p[0], 0.0)) for p in pars]
            if any(v != 0.0 for v in values):
                out.append(effect_from_si(name, [v * p[4] for v, p in zip(values, pars)]))
        return tuple(out)

    def with_effects(self, theta):
        """The ``fe`` model with the effects of theta added to its own."""
        added = self.effects_of(theta)
        if not added:
            return self.fe_model
        if isinstance(self.fe_model, fe.ModalROM):
            raise ModelError(
                "the modal ROM cannot carry the beam's effects (only a bow fits its reduced "
                "form): use the full FE model (--model fe)"
            )
        return dataclasses.replace(self.fe_model, effects=tuple(self.fe_model.effects) + added)

    def simulate(self, theta, force, fs):
        """Transverse velocity at the sensor [m/s] under ``force`` [N] sampled at ``fs`` [Hz]."""
        model = self.with_effects(theta)
        try:
            return fe.simulate(
                model, self.fe_parameters(theta), force, fs=fs, positions=[self.rig.sensor_position_m]
            ).sensor_velocity
        except (fe.BucklingError, fe.ConvergenceError) as exc:
            raise ModelError(f"{type(exc).__name__}: {exc}") from exc

    def check_dataset(self, dataset) -> None:
        """Refuse a data set of another rig than the model's (ValueError)."""
        from bayes_update.models.beam.rig import rig_of

        if self.rig != rig_of(dataset):
            raise ValueError(
                "the model was built for another rig than the data set's "
                f"(model: {self.rig}, data: {rig_of(dataset)}); build it with beam_model(dataset)"
            )

    # -- internal coordinates: (eta, c, P_eff, k_s) in paper units ------------
    @property
    def kb(self) -> float:
        """Axial stiffness of the beam E A / L [N/mm]."""
        return self.rig.axial_stiffness / N_PER_MM

    def to_internal(self, theta) -> np.ndarray:
        return np.array(
            [theta["eta"], theta["c"], theta["F"] * self.kb / (self.kb + theta["k_s"]), theta["k_s"]], float
        )

    def from_internal(self, x) -> dict:
        kb, (eta, c, p_eff, k_s) = self.kb, (float(v) for v in x)
        return {"eta": eta, "c": c, "F": p_eff * (kb + k_s) / kb, "k_s": k_s}

    def log_jacobian(self, x) -> float:
        """``log |d(eta, c, F, k_s) / d(eta, c, P_eff, k_s)| = log((K_b + k_s) / K_b)``."""
        kb = self.kb
        return math.log((kb + float(x[3])) / kb)

    def from_internal_many(self, X) -> dict:
        """:meth:`from_internal` of the rows of ``X`` (n, 4): {name: (n,) array}."""
        X, kb = np.atleast_2d(np.asarray(X, float)), self.kb
        return {"eta": X[:, 0], "c": X[:, 1], "F": X[:, 2] * (kb + X[:, 3]) / kb, "k_s": X[:, 3]}

    def log_jacobian_many(self, X) -> np.ndarray:
        """:meth:`log_jacobian` of the rows of ``X`` (n, 4)."""
        X, kb = np.atleast_2d(np.asarray(X, float)), self.kb
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.log((kb + X[:, 3]) / kb)

    # -- optional members ---------------------------------------------------
    def refined(self) -> "Beam":
        """A finer model of the same physics for the model-error term: 3x the
        elements and 4x the substeps (the ROM: the full FE at those settings)."""
        m = self.fe_model
        if isinstance(m, fe.ModalROM):
            finer = fe.BeamModel(
                rig=m.rig,
                n_elements=3 * fe.model.DEFAULT_ELEMENTS,
                substeps=4 * fe.model.DEFAULT_SUBSTEPS,
                effects=m.effects,
            )
        else:
            finer = dataclasses.replace(m, n_elements=3 * m.n_elements, substeps=4 * m.substeps)
        return dataclasses.replace(self, fe_model=finer)

    def candidate_effects(self) -> dict:
        """{effect: [Parameter(..., null=0)]}: the four effects of :data:`fe.EFFECTS`."""
        if isinstance(self.fe_model, fe.ModalROM):
            raise ModelSpecError(
                "the discrepancy workflow adds effects the modal ROM cannot carry (only a "
                "bow fits its reduced form): use the full FE model (--model fe)"
            )
        return {
            e: [Parameter(n, lo, hi, unit=u, null=0.0) for n, u, lo, hi, _ in pars]
            for e, pars in EFFECT_PARAMETERS.items()
        }

    def extra_starts(self, x, n: int = 3) -> list:
        """Points on the (c, k_s) band at the (eta, P_eff) of internal point ``x``: an
        n x n grid over the prior's c and k_s ranges, kept where F stays inside its
        range (the low level pins eta and P_eff; along the band the nonlinear misfit
        can have more than one valley)."""
        (c_lo, c_hi), (k_lo, k_hi), (f_lo, f_hi) = self.prior["c"], self.prior["k_s"], self.prior["F"]
        out = []
        for c in c_lo + (c_hi - c_lo) * (np.arange(n) + 0.5) / n:
            for ks in k_lo + (k_hi - k_lo) * (np.arange(n) + 0.5) / n:
                p = np.array([x[0], c, x[2], ks])
                if f_lo <= self.from_internal(p)["F"] <= f_hi:
                    out.append(p)
        return out

    def start(
        self, dataset, executor=None, progress: bool = False, coarse: bool = False, store=None
    ) -> tuple[dict, int]:
        """(theta, model runs): the paper's two-stage updating on coarse grids,
        the start of ``find_discrepancy`` for the beam; with ``coarse`` (the start
        of ``sample``, whose MAP search goes on from it) only eta and P_eff from
        the low level (:func:`~bayes_update.models.beam.calibrate.coarse_start`,
        6 runs against about 280).  ``store``: the run cache
        (:class:`~bayes_update.core.runs.RunStore`) its runs are kept in and found in."""
        from bayes_update.models.beam.calibrate import CalibrationSettings, calibrate, coarse_start

        if coarse:
            return coarse_start(dataset, self, executor, progress, store=store)
        cal = calibrate(
            dataset,
            self,
            CalibrationSettings.quick(),
            executor=executor,
            progress=progress,
            log=lambda *a: None,
            store=store,
        )
        return cal.final_theta, cal.setup["n_model_runs"]

    def diagnose(self, dataset, theta, basis=None) -> dict:
        """Where the beam at ``theta`` and the data disagree: by test, kernel order,
        sine harmonic and free-decay amplitude
        (:func:`bayes_update.models.beam.diagnostics.diagnose`), and the
        validation tests' numbers (sine PSDs; :mod:`bayes_update.models.beam.validation`)."""
        from bayes_update.models.beam.diagnostics import diagnose
        from bayes_update.models.beam.validation import compare_test

        out = diagnose(dataset, self, theta, basis=basis)
        high = dataset.by_role("nonlinear")
        out["nonlinear_test"] = high[0].name if high else None
        out["validation"] = {
            t.name: compare_test(t, out["_velocity"][t.name], dataset.sampling_rate_hz)
            for t in dataset.by_role("validation")
        }
        return out

    def signature(self, effect: str, diagnostics: dict, gap: dict):
        """(key, meaning, value) of the number ``effect``'s physics should shrink
        (:data:`SIGNATURES`) in ``diagnostics`` (:meth:`diagnose`) and ``gap``."""
        key = SIGNATURES.get(effect)
        if key is None:
            return None
        if key == "validation":
            value = gap.get("held_out_error_beyond_noise")
        else:
            value = diagnostics["by_order"].get(diagnostics.get("nonlinear_test"), {}).get(key)
        return key, SIGNATURE_MEANING[key], value

    def diagnostics_figure(self, diagnostics: dict):
        """The four panels of :meth:`diagnose` (a matplotlib Figure)."""
        from bayes_update.models.beam.diagnostics import diagnostics_figure

        return diagnostics_figure(diagnostics)

    def describe(self) -> dict:
        """What identifies the model in a cache key and a report."""
        keys = ("n_elements", "substeps", "rho_inf", "formulation", "n_modes", "input_interpolation")
        d = {"kind": type(self.fe_model).__name__, "rig": self.rig.to_dict()}
        d.update({k: getattr(self.fe_model, k) for k in keys if hasattr(self.fe_model, k)})
        effects = getattr(self.fe_model, "effects", ())
        if effects:
            d["effects"] = [{"name": e.name, **e.parameters()} for e in effects]
        return d


def beam_model(dataset=None, kind: str = "fe", prior: dict | None = None, **options) -> Beam:
    """The beam of ``dataset``'s rig as a model of the contract.

    Parameters
    ----------
    kind : ``"fe"`` (``fe.BeamModel``; options ``n_elements``, ``substeps``,
        ``rho_inf``, ``effects``) or ``"rom"`` (``fe.ModalROM``, ~1 ms per run;
        option ``n_modes``).
    prior : {name: (low, high)} in paper units, for any of eta, c, F, k_s.
    """
    from bayes_update.models.beam.rig import rig_of

    rig = rig_of(dataset) if dataset is not None else fe.Rig()
    if kind == "fe":
        model = fe.BeamModel(rig=rig, **options)
    elif kind == "rom":
        model = fe.ModalROM(rig=rig, **options)
    else:
        raise ValueError(f"kind must be 'fe' or 'rom', got {kind!r}")
    return Beam(model, prior or {})
