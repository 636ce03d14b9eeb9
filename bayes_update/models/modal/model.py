"""The modal superposition model of the contract: :class:`ModalModel`
(physics, units and conventions: :mod:`bayes_update.models.modal`)."""

from __future__ import annotations

import copy
import math
import warnings
from collections.abc import Mapping

import numpy as np

from .dynamics import Coupling, mode_responses, outputs, residual_columns, rk4_substeps, step_rate_hz
from .fit import coordinate_rms, element_bounds, fit_outputs
from .joints import check_driving_point, joint_matrices, place_values
from .residual_modes import excited_top, fit_residual_modes
from .signature import diagnose, signature
from .spec import (
    KINDS,
    SHAPES,
    check_candidates,
    check_coefficients,
    check_modes,
    check_nonlinear,
    check_residual,
    check_sensors,
    check_updated,
    declare,
    element_parameter,
)

__all__ = ["MISFIT_HINT", "ModalModel"]

#: a record's fit that leaves more than this share of a sensor's rms unexplained is told
#: (:meth:`ModalModel.from_modes`)
MISFIT_HINT = 0.1


class ModalModel:
    """Modes in superposition, some with nonlinear elements; a model of the contract.

    Parameters
    ----------
    modes : ``[(f_hz, zeta), ...]``, the modes' nominal frequencies [Hz] and damping
        ratios [-] (what :func:`bayes_update.data.inspect.find_modes` returns); mode
        k (1-based) is the k-th.  Frequencies positive, damping ratios in (0, 1).
    coefficients : (M, S) real output coefficients c_ms [-] ((M,) for one sensor).
    sensors : each sensor's kind (``"displacement"``, ``"velocity"``,
        ``"acceleration"``) or ``(name, kind)`` pairs (a data set's ``sensors``),
        in the order of the response's columns.
    residual : (S,) residual coefficients d_s, in m/N (displacement, velocity) or
        1/kg (acceleration); default none (0).
    updated : the 1-based numbers of the modes whose frequency ``f<k>`` [Hz] and
        damping ratio ``zeta<k>`` [-] are parameters (``"all"``, the default, or
        e.g. ``[1, 3]``); the others stay at their nominal values.
    nonlinear : elements, as :class:`~bayes_update.models.modal.Nonlinearity` or
        ``(kind, mode)`` and ``(kind, sensor name)`` pairs, kind ``"k2"``, ``"k3"`` or
        ``"c3"``, or ``Nonlinearity("friction", ..., v0=)``, ``Nonlinearity("clearance",
        ..., gap=)`` and ``Nonlinearity("jenkins", ..., slip=)`` with their shape constants
        [m/s, m, m]: each adds its coefficient
        ``<kind>_<mode>`` or ``<kind>_at_<sensor>`` (null 0) to the parameters.  An element
        in a mode acts on that mode's coordinate; one at a sensor is a joint at the point the
        sensor measures, acting on every mode through that point's displacement
        (:mod:`bayes_update.models.modal.joints`).
    bounds : ``{name: (low, high)}`` priors overriding the defaults (frequency
        +-5 %, damping ratio x0.5..x2, log-uniform); an element's prior has no
        default here (:meth:`from_modes` sets one from the record).
    substeps : RK4 steps per sample of a nonlinear mode, times what its frequency
        asks (:func:`~bayes_update.models.modal.dynamics.rk4_substeps`); the modes coupled
        by joints take the steps their highest frequency asks; a clearance's contact spring
        and a friction's slope at the top of their priors may ask more
        (:func:`~bayes_update.models.modal.dynamics.step_rate_hz`).
    driving_point : the name of the sensor at the point where the force acts (the
        driving-point sensor): required by an element at a sensor, whose force enters mode
        m's equation scaled by c_m(sensor) / c_m(driving point).  Its coefficients must be
        positive for every mode (they are phi_dm^2 x 1 kg).
    candidates : elements, given as ``nonlinear`` is, offered to the discrepancy workflow
        (:meth:`candidate_effects`, one effect per element, its coefficient's name): each is
        integrated as an element of ``nonlinear`` is, but its coefficient (null 0, prior from
        ``bounds``) is not in ``parameters``: :meth:`simulate` takes it from theta when there,
        else 0.  A candidate's name must not be a parameter's.

    Attributes ``modes`` (M, 2), ``sensors``, ``coefficients`` (M, S), ``residual``
    (S,), ``updated``, ``nonlinear``, ``candidates``, ``substeps``, ``driving_point``, ``parameters``;
    ``record_misfit`` {sensor: relative rms misfit of the fit} when built by :meth:`from_modes`.
    """

    def __init__(
        self,
        modes,
        coefficients,
        sensors="velocity",
        residual=None,
        updated="all",
        nonlinear=(),
        bounds: Mapping | None = None,
        substeps: int = 4,
        driving_point: str | None = None,
        candidates=(),
    ):
        self.modes = check_modes(modes)
        self.sensors = check_sensors(sensors)
        M, S = self.modes.shape[0], len(self.sensors)
        self.coefficients = check_coefficients(coefficients, M, S, "coefficients")
        self.residual = check_residual(residual, S)
        self.updated = check_updated(updated, M)
        self.nonlinear = check_nonlinear(nonlinear, M, [n for n, _ in self.sensors])
        self.candidates = check_candidates(candidates, M, self.sensors, driving_point)
        every = self.nonlinear + self.candidates
        driving = check_driving_point(driving_point, self.sensors, self.coefficients, every)
        self.driving_point = None if driving is None else self.sensors[driving][0]
        self._points, self._weights, self._shares, self._shapes = joint_matrices(
            every, self.sensors, self.coefficients, driving
        )
        if not (isinstance(substeps, (int, np.integer)) and substeps >= 1):
            raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
        self.substeps = int(substeps)
        bounds, own = dict(bounds or {}), {e.name for e in self.candidates}
        clash = sorted(own & {e.name for e in self.nonlinear})
        if clash:
            raise ValueError(
                f"candidates: {clash} already a declared parameter (an element of nonlinear=); a candidate "
                "is an element the model does not have: drop it from one of the two lists"
            )
        self.parameters = declare(self.modes, self.updated, self.nonlinear, {k: bounds[k] for k in set(bounds) - own})
        self._candidate_parameters = [element_parameter(e, bounds) for e in self.candidates]
        self.record_misfit = None
        self.n_residual_modes = 0  # the last of ``modes`` fitted above the band (from_modes)

    # -- the contract -------------------------------------------------------
    def simulate(self, theta: Mapping[str, float], force, fs: float) -> np.ndarray:
        """The sensors' response to ``force`` [N] sampled at ``fs`` [Hz], from rest:
        (n,) for one sensor, (n, S) for several, each in its kind's SI unit (m, m/s,
        m/s^2).  ``theta`` in the parameters' units.  Raises ``ValueError`` for bad
        input, :class:`~bayes_update.ModelError` when a nonlinear mode diverges."""
        if not (isinstance(fs, (int, float, np.floating, np.integer)) and math.isfinite(fs) and fs > 0):
            raise ValueError(f"fs must be a positive sampling rate [Hz], got {fs!r}")
        u = np.asarray(force, dtype=float)
        if u.ndim != 1 or u.size == 0:
            raise ValueError(f"force must be one channel of samples, shape (n,), got shape {u.shape}")
        if not np.all(np.isfinite(u)):
            raise ValueError("force holds non-finite values (NaN or inf)")
        f_hz, zeta, elements, values = self._values(theta)
        steps = {m: rk4_substeps(self._rate_hz([m]), fs, self.substeps) for m in elements}
        coupling = None
        if self._points:  # the joints' RK4 steps: as the highest of the modes they couple asks
            rate = self._rate_hz(np.flatnonzero(np.any(self._weights != 0, axis=0)), joints=True)
            steps_joint = rk4_substeps(rate, fs, self.substeps)
            coupling = Coupling(self._weights, self._shares, values, self._shapes, steps_joint, self._points)
        R = mode_responses(u, fs, f_hz, zeta, elements, steps, coupling=coupling)
        kinds = tuple(k for _, k in self.sensors)
        columns = residual_columns(u, fs, kinds) if np.any(self.residual) else None
        y = outputs(R, self.coefficients, np.array([KINDS.index(k) for k in kinds]), self.residual, columns)
        return y[:, 0] if y.shape[1] == 1 else y

    def _values(self, theta) -> tuple:
        """Frequencies [Hz], damping ratios [-], ``{mode index: (coefficients (6,), shapes (3,))}``
        and the joints' (P, 6) coefficients at their points at theta (:func:`~.joints.place_values`)."""
        if not isinstance(theta, Mapping):
            raise ValueError(f"theta must map each parameter name to a value, got {type(theta).__name__}")
        missing = [p.name for p in self.parameters if p.name not in theta]
        if missing:
            raise ValueError(f"theta lacks {missing}; the parameters are {[p.name for p in self.parameters]}")
        f_hz, zeta = self.modes[:, 0].copy(), self.modes[:, 1].copy()
        for k in self.updated:
            f, z = float(theta[f"f{k}"]), float(theta[f"zeta{k}"])
            if not (math.isfinite(f) and f > 0):
                raise ValueError(f"theta['f{k}'] = {f!r} Hz: a frequency must be positive")
            if not (0 < z < 1):
                raise ValueError(f"theta['zeta{k}'] = {z!r}: a damping ratio must lie in (0, 1)")
            f_hz[k - 1], zeta[k - 1] = f, z
        elements, values = place_values(self.nonlinear + self.candidates, theta, self.candidates, self._points)
        return f_hz, zeta, elements, values

    def _f_top(self, m: int) -> float:
        """The top of mode m's (0-based) frequency prior [Hz]: what its RK4 steps are sized for."""
        name = f"f{m + 1}"
        return next((p.high for p in self.parameters if p.name == name), float(self.modes[m, 0]))

    def _rate_hz(self, modes, joints: bool = False) -> float:
        """The rate [Hz] the RK4 steps of ``modes`` (0-based; with ``joints``, the modes the joints
        couple, integrated together) are sized for: their highest frequency, raised by the contact
        springs and frictions among their elements at the top of their priors (:func:`step_rate_hz`)."""
        top = {p.name: max(abs(p.low), abs(p.high)) for p in self.parameters + self._candidate_parameters}
        contact = slope = 0.0
        for e in self.nonlinear + self.candidates:
            # a Jenkins element only softens (its stuck stiffness is in the mode's): no faster motion
            if e.kind not in ("clearance", "friction"):
                continue
            if (e.at is None and e.index not in modes) or (e.at is not None and not joints):
                continue
            j = self._points.index(e.point) if e.at is not None else None
            ws = 1.0 if j is None else float(self._weights[j] @ self._shares[j])
            if e.kind == "clearance":
                contact += top[e.name] * ws
            else:
                slope += top[e.name] / e.shape * ws
        return step_rate_hz(max(self._f_top(m) for m in modes), contact, slope)

    # -- optional members ----------------------------------------------------
    def candidate_effects(self) -> dict:
        """``{coefficient name: [its Parameter, null 0]}``: one effect per candidate element,
        ``{}`` when the model has none (the discrepancy workflow then refuses it)."""
        return {p.name: [p] for p in self._candidate_parameters}

    def diagnose(self, dataset, theta, basis=None) -> dict:
        """Every mode's frequency and damping in every test, and the periodic tests' distortion,
        measured and of the model at ``theta`` (:mod:`bayes_update.models.modal.signature`; ``basis`` unused)."""
        return diagnose(self, dataset, theta)

    def diagnostics_figure(self, diagnostics: dict):
        """:meth:`diagnose`'s result drawn (:func:`bayes_update.models.modal.figures.diagnostics_figure`)."""
        from .figures import diagnostics_figure  # matplotlib, imported where a figure is drawn

        return diagnostics_figure(diagnostics)

    def signature(self, effect: str, diagnostics: dict, gap: dict):
        """(key, meaning, value): what an element should shrink (:mod:`~bayes_update.models.modal.signature`)."""
        return signature(self, effect, diagnostics)

    def refined(self) -> "ModalModel":
        """The same model with twice the RK4 substeps (the framework's model-error term). RK4's error
        falls 16-fold when its steps halve, so the difference from this model is some 15/16 of the
        model's own time-step error; its linear modes are exact at any step and do not change.  With a
        clearance the error falls some 4-fold on average but erratically (:mod:`.dynamics`)."""
        finer = copy.copy(self)
        finer.substeps = 2 * self.substeps
        return finer

    def describe(self) -> dict:
        """The model's constants (its identity in a cache key and a report), JSON-ready."""
        return {
            "model": "ModalModel",
            "modes": [{"freq_hz": float(f), "damping_ratio": float(z)} for f, z in self.modes],
            "sensors": [list(s) for s in self.sensors],
            "coefficients": self.coefficients.tolist(),
            "residual": self.residual.tolist(),
            "updated": list(self.updated),
            "nonlinear": [e.name for e in self.nonlinear],
            **self._shape_constants(),
            "driving_point": self.driving_point,
            "substeps": self.substeps,
            "priors": {p.name: [p.low, p.high, p.unit] for p in self.parameters},
            **self._candidates_description(),
        }

    def _candidates_description(self) -> dict:
        """``{"candidates": {name: [low, high, unit]}}`` for :meth:`describe`; none: ``{}``."""
        priors = {p.name: [p.low, p.high, p.unit] for p in self._candidate_parameters}
        return {"candidates": priors} if priors else {}

    def _shape_constants(self) -> dict:
        """``{"shapes": {element: {"v0" or "gap": value}}}`` for :meth:`describe`: the shape
        constants are part of the model's identity; none: ``{}`` (the description as before)."""
        every = self.nonlinear + self.candidates
        shapes = {e.name: {SHAPES[e.kind][0]: e.shape} for e in every if e.kind in SHAPES}
        return {"shapes": shapes} if shapes else {}

    def coordinate_rms(self, dataset, between=()) -> dict:
        """``{test name: {place: rms [m]}}`` in the linear response of the nominal modes to each test's
        force: each mode (its number), sensor's point (its name) and pair of points in ``between``
        (``[("store", "mid")]``: ``"store-mid"``; :func:`~bayes_update.models.modal.fit.coordinate_rms`):
        the scale of a slip or a gap, between their rms at the two levels a joint's mode moves between."""
        fs = float(dataset.sampling_rate_hz)
        return {
            t.name: coordinate_rms(self.modes, self.coefficients, self.sensors, t.force, fs, between)
            for t in dataset.tests
        }

    def check_dataset(self, dataset) -> None:
        """Refuse a data set whose sensors are not the model's (their number and kinds, in order)."""
        theirs = [tuple(s) for s in dataset.sensors]
        if [k for _, k in theirs] != [k for _, k in self.sensors]:
            raise ValueError(
                f"the data set's sensors {theirs} are not the model's {list(self.sensors)}: one output "
                "coefficient per mode and sensor, sensors of the same kinds in the same order; build the "
                "model from this data set (ModalModel.from_dataset) or pass its sensors"
            )

    # -- construction from a record ------------------------------------------
    @classmethod
    def from_modes(
        cls,
        modes,
        force,
        response,
        fs: float,
        sensors="velocity",
        updated="all",
        nonlinear=(),
        bounds: Mapping | None = None,
        substeps: int = 4,
        residual: bool = True,
        transient: bool = True,
        strongest=(),
        driving_point: str | None = None,
        candidates=(),
        residual_modes: int = 0,
    ) -> "ModalModel":
        """The model of ``modes`` ``[(f_hz, zeta), ...]`` whose output coefficients and
        residual terms fit the record ``force`` (n,) [N], ``response`` (n,) or (n, S)
        at ``fs`` [Hz] (:func:`~bayes_update.models.modal.fit.fit_outputs`: linear least
        squares in the time domain, the modes held).  ``residual=False``: no residual
        term; ``transient=False``: the record starts from rest.  ``residual_modes``: that
        many modes above the record's excited band, their frequency and damping fitted to
        it (:mod:`~bayes_update.models.modal.residual_modes`; never updated, numbered after
        ``modes``: ``updated="all"`` means ``modes``); where a sensor's fit leaves more than
        :data:`MISFIT_HINT` of its rms without them, a warning says so.  The nonlinear
        elements' default priors scale with the modal amplitude of the strongest of
        ``force`` and the forces in ``strongest`` (a data set's other tests:
        :func:`~bayes_update.models.modal.fit.element_bounds`); ``bounds`` overrides
        any prior; the candidates' default priors as the elements'.  Other arguments as for
        :class:`ModalModel`."""
        modes = check_modes(modes)
        sensors = check_sensors(sensors)
        n_band = modes.shape[0]
        if residual_modes:
            top = excited_top(force, fs)
            extra = fit_residual_modes(modes, force, response, fs, sensors, residual_modes, top, residual, transient)
            modes = np.vstack([modes, extra])
        if isinstance(updated, str) and updated == "all":
            updated = range(1, n_band + 1)
        elements = check_nonlinear(nonlinear, modes.shape[0], [n for n, _ in sensors])
        cands = check_candidates(candidates, modes.shape[0], sensors, driving_point)
        fit = fit_outputs(modes, force, response, fs, sensors, residual, transient)
        driving = check_driving_point(driving_point, sensors, fit.coefficients, elements + cands)
        prior = element_bounds(elements + cands, modes, [force, *strongest], fs, fit.coefficients, sensors, driving)
        prior.update(dict(bounds or {}))
        model = cls(
            modes, fit.coefficients, sensors, fit.residual, updated, elements, prior, substeps, driving_point, cands
        )
        model.record_misfit = fit.misfit
        model.n_residual_modes = int(residual_modes)
        worst = max(fit.misfit, key=fit.misfit.get)
        if not residual_modes and fit.misfit[worst] > MISFIT_HINT:
            warnings.warn(
                f"the modes leave {100 * fit.misfit[worst]:.1f} % of sensor {worst}'s rms unexplained: modes "
                "above the band may respond to it (most at a driving point); try residual_modes=1 or 2",
                stacklevel=2,
            )
        return model

    @classmethod
    def from_dataset(
        cls,
        dataset,
        updated="all",
        nonlinear=(),
        bounds: Mapping | None = None,
        substeps: int = 4,
        driving_point: str | None = None,
        candidates=(),
        residual_modes: int = 0,
        **options,
    ) -> "ModalModel":
        """:meth:`from_modes` on the data set's test with role ``linear``: its modes as the
        first look at the data finds them (:func:`bayes_update.data.inspect.find_modes`),
        its sensors, its sampling rate; the elements' priors scale with the strongest of
        all its tests.  ``options``: ``residual``, ``transient``."""
        from bayes_update.data.inspect import find_modes

        linear = dataset.by_role("linear")
        if not linear:
            raise ValueError(
                f"dataset {dataset.name!r} has no test with role 'linear': the modes and the output "
                "coefficients come from the low-level test"
            )
        rec, fs = linear[0], float(dataset.sampling_rate_hz)
        modes = find_modes(rec.force, rec.response, fs, rec.period_samples)
        others = [t.force for t in dataset.tests if t is not rec]
        return cls.from_modes(
            modes,
            rec.force,
            rec.response,
            fs,
            sensors=dataset.sensors,
            updated=updated,
            nonlinear=nonlinear,
            bounds=bounds,
            substeps=substeps,
            strongest=others,
            driving_point=driving_point,
            candidates=candidates,
            residual_modes=residual_modes,
            **options,
        )
