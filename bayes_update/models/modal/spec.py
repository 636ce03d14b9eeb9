"""What a modal model is made of, checked: its modes, sensors, output coefficients,
nonlinear elements and declared parameters (:mod:`bayes_update.models.modal`).

Mode numbers are 1-based positions in the model's list of modes (mode 1 is
the first (f_hz, zeta) given; :func:`bayes_update.data.inspect.find_modes`
lists them by frequency).  Every check raises ``ValueError`` naming the
argument and what is wrong.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from bayes_update.core.parameters import Parameter

__all__ = [
    "KINDS",
    "ELEMENTS",
    "SHAPES",
    "IWAN_SLIDERS",
    "COLUMNS",
    "SHAPE_COLUMNS",
    "column",
    "shape_column",
    "Nonlinearity",
    "check_modes",
    "check_sensors",
    "check_coefficients",
    "check_residual",
    "check_updated",
    "check_nonlinear",
    "check_candidates",
    "declare",
    "element_parameter",
]

#: the sensor kinds, in the order of the derivative each takes of the modal coordinate (p = 0, 1, 2)
KINDS = ("displacement", "velocity", "acceleration")
#: the nonlinear elements: the force each adds (per unit modal mass, the 1 kg of the unit input) and
#: the SI unit of its coefficient, x the mode's coordinate or, for an element at a sensor, the
#: displacement of the sensor's point [m], x' its rate [m/s]; in this order in the integrator's rows
ELEMENTS = {
    "k2": ("quadratic stiffness k2 x^2", "1/(m s^2)"),
    "k3": ("cubic stiffness k3 x^3", "1/(m^2 s^2)"),
    "c3": ("cubic damping c3 x'^3", "s/m^2"),
    "friction": ("smooth Coulomb friction F tanh(x'/v0)", "m/s^2"),
    "clearance": ("contact spring kc (x - gap) for x > gap, kc (x + gap) for x < -gap, 0 between", "1/s^2"),
    "jenkins": ("Jenkins element: a spring kt in series with a slider, -kt z, z the slider's travel", "1/s^2"),
    "iwan": ("Iwan element: Jenkins elements in parallel, each kt / n, their slips spread to slip", "1/s^2"),
}
#: the elements with a shape constant, fixed by the user (an argument of :class:`Nonlinearity`, not a
#: parameter): its name, SI unit and meaning; in this order in the integrator's rows of constants
SHAPES = {
    "friction": ("v0", "m/s", "its smoothing velocity (the force is 76 % of F at x' = v0)"),
    "clearance": ("gap", "m", "the half-width of its gap (contact from |x| = gap on)"),
    "jenkins": ("slip", "m", "its spring's stretch at which the slider slips (slip force kt x slip)"),
    "iwan": ("slip", "m", "the largest of its sliders' slips (they slip at slip / n, 2 slip / n, ..., slip)"),
}
#: an Iwan element's Jenkins sliders n: each of stiffness kt / n, their slips slip i / n (i = 1 .. n), so
#: that its joint slips over a range of levels (one Jenkins element slips at one)
IWAN_SLIDERS = 4
#: the integrator's columns of coefficients and of shape constants (an Iwan element is Jenkins rows)
COLUMNS = ("k2", "k3", "c3", "friction", "clearance", "jenkins")
SHAPE_COLUMNS = ("friction", "clearance", "jenkins")


def column(kind: str) -> int:
    """The integrator's column of an element's coefficient (an Iwan element's: the Jenkins')."""
    return COLUMNS.index("jenkins" if kind == "iwan" else kind)


def shape_column(kind: str) -> int:
    """The integrator's column of an element's shape constant (an Iwan element's: the Jenkins')."""
    return SHAPE_COLUMNS.index("jenkins" if kind == "iwan" else kind)


#: default prior of an updated mode: frequency within +-5 %, damping ratio x0.5..x2 (log-uniform;
#: below 1 always: its top is at most halfway from the damping ratio to critical damping)
FREQ_SPAN = 0.05
DAMPING_SPAN = 2.0


@dataclass(frozen=True)
class Nonlinearity:
    """A nonlinear element, ``kind`` one of :data:`ELEMENTS` (``"k2"``, ``"k3"``, ``"c3"``,
    ``"friction"``, ``"clearance"``, ``"jenkins"``, ``"iwan"``), either in the equation of mode ``mode``
    (1-based; its modal coordinate's force) or ``at`` a sensor (its name: a joint at the point that sensor measures,
    acting on every mode through that point's displacement, :mod:`bayes_update.models.modal.joints`),
    or between the points of sensors ``at`` and ``to`` (x the displacement of the first relative to
    the second: a joint that holds one body on another).
    Its coefficient is the parameter :attr:`name` (``"k3_1"``, ``"k3_at_acc1"``), in the unit
    :attr:`unit`, null (switched off) at 0.  A friction takes its smoothing velocity ``v0`` [m/s]
    (``Nonlinearity("friction", at="acc1", v0=1e-3)``), a clearance the half-width of its gap
    ``gap`` [m] (``Nonlinearity("clearance", 1, gap=2e-4)``), a Jenkins element the stretch ``slip`` [m]
    at which it slips (``Nonlinearity("jenkins", 2, slip=5e-4)``), an Iwan element the largest slip of its
    :data:`IWAN_SLIDERS` sliders (``Nonlinearity("iwan", 2, slip=1e-3)``): constants of the model (:data:`SHAPES`)."""

    kind: str
    mode: int | None = None
    at: str | None = None
    v0: float | None = None
    gap: float | None = None
    slip: float | None = None
    to: str | None = None

    @property
    def name(self) -> str:
        if self.to is not None and self.at is not None:
            return f"{self.kind}_between_{_identifier(self.at)}_{_identifier(self.to)}"
        if self.at is not None:
            return f"{self.kind}_at_{_identifier(self.at)}"
        return f"{self.kind}_{self.mode}"

    @property
    def point(self) -> str | None:
        """The joint's place: the sensor's name (``"acc1"``), or ``"acc1-acc2"`` for an element
        between two sensors' points; None for an element in a mode."""
        if self.at is None:
            return None
        return self.at if self.to is None else f"{self.at}-{self.to}"

    @property
    def unit(self) -> str:
        return ELEMENTS[self.kind][1]

    @property
    def index(self) -> int:
        return self.mode - 1

    @property
    def where(self) -> str:
        """``mode 1``, ``sensor 'acc1'`` or ``sensors 'acc1' and 'acc2'``: what the messages name."""
        if self.to is not None and self.at is not None:
            return f"sensors {self.at!r} and {self.to!r}"
        return f"sensor {self.at!r}" if self.at is not None else f"mode {self.mode}"

    @property
    def shape(self) -> float:
        """The shape constant, v0 [m/s], gap [m] or slip [m] (0 for an element without one)."""
        own = {"v0": self.v0, "gap": self.gap, "slip": self.slip}
        return own[SHAPES[self.kind][0]] if self.kind in SHAPES else 0.0


def _identifier(text: str) -> str:
    """A sensor's name as part of a parameter's name: every character not of an identifier as ``_``."""
    return re.sub(r"\W", "_", text)


def check_modes(modes, what: str = "modes") -> np.ndarray:
    """``[(f_hz, zeta), ...]`` as an (M, 2) array: at least one mode, each frequency
    positive [Hz], each damping ratio in (0, 1)."""
    try:
        arr = np.array(modes, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what} must be a list of (frequency [Hz], damping ratio) pairs ({exc})") from None
    if arr.ndim != 2 or arr.shape[1] != 2 or arr.shape[0] == 0:
        raise ValueError(
            f"{what} must be a non-empty list of (frequency [Hz], damping ratio) pairs, got shape {arr.shape}"
        )
    for k, (f, z) in enumerate(arr, start=1):
        if not (math.isfinite(f) and f > 0):
            raise ValueError(f"{what}: mode {k} has frequency {f!r} Hz; a frequency must be positive")
        if not (0 < z < 1):
            raise ValueError(f"{what}: mode {k} has damping ratio {z!r}; it must lie in (0, 1) (an underdamped mode)")
    return arr


def check_sensors(sensors, what: str = "sensors") -> tuple:
    """Sensors as ``((name, kind), ...)``: given as kinds (``"acceleration"``; named
    ``sensor1``, ``sensor2``, ...) or as (name, kind) pairs (a data set's ``sensors``)."""
    if isinstance(sensors, str):
        sensors = [sensors]
    out = []
    for k, s in enumerate(sensors, start=1):
        name, kind = (f"sensor{k}", s) if isinstance(s, str) else tuple(s)
        if kind not in KINDS:
            raise ValueError(f"{what}: sensor {name!r} has kind {kind!r}; a sensor measures one of {KINDS}")
        out.append((str(name), kind))
    if not out:
        raise ValueError(f"{what}: no sensor given; give each sensor's kind, one of {KINDS}")
    names = [n for n, _ in out]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ValueError(f"{what}: duplicate sensor names {dup}")
    return tuple(out)


def check_coefficients(values, n_modes: int, n_sensors: int, what: str) -> np.ndarray:
    """Real coefficients of shape (n_modes, n_sensors); (n_modes,) for one sensor."""
    arr = np.asarray(values)
    if arr.dtype.kind == "c":
        raise ValueError(
            f"{what} must be real: the model is of a proportionally damped structure, whose modes are real"
        )
    arr = arr.astype(float)
    if arr.ndim == 1 and n_sensors == 1:
        arr = arr[:, None]
    if arr.shape != (n_modes, n_sensors):
        raise ValueError(f"{what} has shape {arr.shape}; it must be ({n_modes} modes, {n_sensors} sensors)")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what} holds non-finite values")
    return arr


def check_residual(values, n_sensors: int) -> np.ndarray:
    """One real residual coefficient per sensor, (S,); None: none (0)."""
    if values is None:
        return np.zeros(n_sensors)
    arr = np.asarray(values)
    if arr.dtype.kind == "c":
        raise ValueError("residual must be real: one residual coefficient per sensor")
    arr = np.atleast_1d(arr.astype(float))
    if arr.shape != (n_sensors,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"residual has shape {arr.shape}; it must hold one finite value per sensor, ({n_sensors},)")
    return arr


def check_updated(updated, n_modes: int) -> tuple:
    """The 1-based numbers of the updated modes (``"all"``: every mode)."""
    if isinstance(updated, str):
        if updated != "all":
            raise ValueError(f"updated must be 'all' or a list of mode numbers (1-based), got {updated!r}")
        return tuple(range(1, n_modes + 1))
    nums = tuple(int(k) for k in updated)
    bad = [k for k in nums if not 1 <= k <= n_modes]
    if bad:
        raise ValueError(f"updated names mode(s) {bad}; the modes are numbered 1 to {n_modes}")
    if len(set(nums)) != len(nums):
        raise ValueError(f"updated names a mode twice: {list(nums)}")
    return tuple(sorted(nums))


def check_nonlinear(nonlinear, n_modes: int, sensor_names=(), what: str = "nonlinear") -> tuple:
    """Nonlinear elements as :class:`Nonlinearity` objects, from those or pairs: ``(kind, mode)``
    (1-based) or ``(kind, sensor name)`` (an element at that sensor's point); a friction, a
    clearance or a Jenkins element as a :class:`Nonlinearity`, with its shape constant (``v0=``, ``gap=``,
    ``slip=``)."""
    out = []
    for item in nonlinear or ():
        if isinstance(item, Nonlinearity):
            el = item
        elif len(item) == 2 and isinstance(item[1], str):
            el = Nonlinearity(item[0], at=item[1])
        elif len(item) == 3 and all(isinstance(x, str) for x in item):
            el = Nonlinearity(item[0], at=item[1], to=item[2])
        else:
            el = Nonlinearity(*item)
        if el.kind not in ELEMENTS:
            raise ValueError(f"{what}: unknown element {el.kind!r}; the elements are {sorted(ELEMENTS)}")
        if (el.mode is None) == (el.at is None):
            raise ValueError(
                f"{what}: {el.kind} needs one place, a mode (mode=1) or a sensor's point (at='acc1'); "
                f"got mode={el.mode!r}, at={el.at!r}"
            )
        shapes = _check_shape(el, what)
        if el.at is not None:
            for end in (el.at, el.to):
                if end is not None and end not in sensor_names:
                    known = list(sensor_names)
                    raise ValueError(
                        f"{what}: {el.kind} at sensor {end!r}, which does not exist; the sensors are {known}"
                    )
            if el.to is not None and el.to == el.at:
                raise ValueError(f"{what}: {el.kind} between sensor {el.at!r} and itself: give two sensors")
            to = {} if el.to is None else {"to": str(el.to)}
            out.append(Nonlinearity(el.kind, at=str(el.at), **to, **shapes))
            continue
        if el.to is not None:
            raise ValueError(f"{what}: {el.kind} to={el.to!r} needs at= (an element between two sensors' points)")
        if not (isinstance(el.mode, (int, np.integer)) and 1 <= el.mode <= n_modes):
            raise ValueError(f"{what}: {el.kind} on mode {el.mode!r}; the modes are numbered 1 to {n_modes}")
        out.append(Nonlinearity(el.kind, int(el.mode), **shapes))
    names = [e.name for e in out]
    if len(set(names)) != len(names):
        raise ValueError(f"{what}: an element is given twice: {names}")
    return tuple(out)


def _check_shape(el: Nonlinearity, what: str = "nonlinear") -> dict:
    """``{"v0": value}``, ``{"gap": value}`` or ``{}``: the element's shape constant, a finite positive
    float where its kind takes one (:data:`SHAPES`), none where it does not."""
    own = SHAPES[el.kind][0] if el.kind in SHAPES else None
    for arg, value in (("v0", el.v0), ("gap", el.gap), ("slip", el.slip)):
        if arg != own and value is not None:
            kinds = [k for k, (a, _, _) in SHAPES.items() if a == arg]
            raise ValueError(f"{what}: {el.kind} at {el.where} takes no {arg}= (only {kinds[0]} does)")
    if own is None:
        return {}
    _, unit, meaning = SHAPES[el.kind]
    value = getattr(el, own)
    place = f"at={el.at!r}" if el.at is not None else repr(el.mode)
    if value is None:
        raise ValueError(
            f"{what}: {el.kind} at {el.where} needs {own} [{unit}] > 0, {meaning}: "
            f"Nonlinearity({el.kind!r}, {place}, {own}=...)"
        )
    try:
        value = float(value)
    except (TypeError, ValueError):
        value = None
    if not (value is not None and math.isfinite(value) and value > 0):
        raise ValueError(
            f"{what}: {el.kind} at {el.where} has {own} = {getattr(el, own)!r}; {own} [{unit}], {meaning}, "
            "must be a positive number"
        )
    return {own: value}


def default_mode_bounds(modes: np.ndarray, updated: tuple) -> dict:
    """``{name: (low, high)}`` of the updated modes' frequencies [Hz] and damping ratios [-]."""
    out = {}
    for k in updated:
        f, z = modes[k - 1]
        out[f"f{k}"] = ((1 - FREQ_SPAN) * f, (1 + FREQ_SPAN) * f)
        out[f"zeta{k}"] = (z / DAMPING_SPAN, min(DAMPING_SPAN * z, 0.5 * (1 + z)))
    return out


def declare(modes: np.ndarray, updated: tuple, elements: tuple, bounds: Mapping) -> list:
    """The declared parameters: ``f<k>`` [Hz] and ``zeta<k>`` [-] of each updated mode,
    then each element's coefficient (null 0).  ``bounds`` overrides the default
    priors by name; an element's bounds have no default here (its scale depends
    on the record: :func:`bayes_update.models.modal.fit.element_bounds`)."""
    bounds = dict(bounds or {})
    default = default_mode_bounds(modes, updated)
    names = [*default, *(e.name for e in elements)]
    unknown = sorted(set(bounds) - set(names))
    if unknown:
        raise ValueError(f"bounds names {unknown}, which are not parameters of the model; its parameters are {names}")
    params = []
    for k in updated:
        lo, hi = _pair(bounds.get(f"f{k}", default[f"f{k}"]), f"f{k}")
        if lo <= 0:
            raise ValueError(f"bounds['f{k}'] = ({lo!r}, {hi!r}): a frequency's prior must be positive")
        params.append(Parameter(f"f{k}", lo, hi, unit="Hz"))
        lo, hi = _pair(bounds.get(f"zeta{k}", default[f"zeta{k}"]), f"zeta{k}")
        if not (0 < lo and hi < 1):
            raise ValueError(f"bounds['zeta{k}'] = ({lo!r}, {hi!r}): a damping ratio's prior must lie in (0, 1)")
        params.append(Parameter(f"zeta{k}", lo, hi, unit="-", log=True))
    params += [element_parameter(e, bounds) for e in elements]
    if not params:
        raise ValueError("nothing to update: name modes in updated= or elements in nonlinear=")
    return params


def element_parameter(e: Nonlinearity, bounds: Mapping) -> Parameter:
    """The coefficient of element ``e`` (null 0) with its prior ``bounds[e.name]``, required."""
    if e.name not in bounds:
        raise ValueError(
            f"bounds['{e.name}'] is missing: give the prior of the {ELEMENTS[e.kind][0]} at "
            f"{e.where} [{e.unit}] (ModalModel.from_modes sets one from the record)"
        )
    lo, hi = _pair(bounds[e.name], e.name)
    return Parameter(e.name, lo, hi, unit=e.unit, null=0.0)


def _pair(value, name: str) -> tuple:
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"bounds['{name}'] must be a (low, high) pair, got {value!r}") from None
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise ValueError(f"bounds['{name}'] = ({lo!r}, {hi!r}): need finite low < high")
    return lo, hi


def check_candidates(candidates, n_modes: int, sensors: tuple, driving_point) -> tuple:
    """The candidate elements, checked as ``nonlinear`` is; one at a sensor needs a driving point."""
    out = check_nonlinear(candidates, n_modes, [n for n, _ in sensors], what="candidates")
    joints = [e.name for e in out if e.at is not None]
    if joints and driving_point is None:
        raise ValueError(
            f"candidates: {joints[0]} sits at a sensor's point, but no driving point is named: give "
            "driving_point=<the sensor at the point where the force acts> (bayes_update.models.modal.joints)"
        )
    return out
