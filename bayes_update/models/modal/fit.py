"""A modal model's constants from a record: its output coefficients and residual
terms by linear least squares in the time domain, and its nonlinear elements'
default priors (:meth:`bayes_update.models.modal.ModalModel.from_modes`).

Each mode's unit response (b_m = 1 [1/kg], the modes at their given frequency
and damping, every element at its null) is simulated on the record's force
with the model's own integrator; each sensor's measured response is then
regressed on those of its kind, its residual column
(:func:`~bayes_update.models.modal.dynamics.residual_columns`), a constant (the
sensor's offset) and, for a record that does not start at rest, each mode's
free decays from a unit displacement and a unit rate.  The offset and the
free decays are nuisance terms, dropped: the model starts from rest, as the
framework runs it.  The fit is exact for the model's own form: a record the
model made (from rest, no noise) gives its coefficients back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import mode_responses, residual_columns
from .joints import point_weights
from .spec import KINDS

__all__ = [
    "RecordFit",
    "fit_outputs",
    "element_bounds",
    "ELEMENT_SHARE",
    "DAMPING_FACTOR",
    "CONTACT_FACTOR",
    "SLIP_SHARE",
]

#: default prior of k2 and k3: symmetric, the element's force at the rms amplitude of the mode's
#: linear response to the strongest force at most this share of the mode's linear stiffness force;
#: of a friction F: [0, top], F at most this share of that stiffness force (it dissipates: F >= 0)
ELEMENT_SHARE = 0.25
#: default prior of c3: [0, top], the cubic damping force at the rms modal rate at most this many
#: times the mode's linear damping force there (cubic damping dissipates: no negative values)
DAMPING_FACTOR = 4.0
#: default prior of a clearance's contact stiffness kc: [0, this many times the static stiffness of
#: its place] (a contact stiffer than the structure it stops: an actuator behind its free play)
CONTACT_FACTOR = 10.0
#: default prior of a Jenkins element's stiffness kt: [0, this share of the static stiffness of its
#: place] (fully slipped, the place keeps at least the rest: a joint that takes all of a structure's
#: stiffness with it when it slips is not a joint but a mechanism)
SLIP_SHARE = 0.5


@dataclass(frozen=True)
class RecordFit:
    """The result of :func:`fit_outputs`: ``coefficients`` (M, S) [-], ``residual`` (S,)
    (in each sensor's residual unit), ``misfit`` {sensor: rms of the fit's residual /
    rms of the measured response (offset removed)}, ``errors`` (n, S) the fit's residual
    over each sensor's rms."""

    coefficients: np.ndarray
    residual: np.ndarray
    misfit: dict
    errors: np.ndarray | None = None


def check_record(force, response, fs, n_sensors: int) -> tuple:
    """force (n,), response (n, S) as float arrays, finite, fs positive; else ValueError."""
    if not (isinstance(fs, (int, float, np.floating, np.integer)) and np.isfinite(fs) and fs > 0):
        raise ValueError(f"fs must be a positive sampling rate [Hz], got {fs!r}")
    u = np.asarray(force, float)
    y = np.asarray(response, float)
    if u.ndim != 1:
        raise ValueError(f"force must be one channel, shape (n,), got shape {u.shape}")
    y = y[:, None] if y.ndim == 1 else y
    if y.ndim != 2 or y.shape[0] != u.size:
        raise ValueError(
            f"response has shape {np.shape(response)}; the force has {u.size} samples: "
            f"need ({u.size},) or ({u.size}, n_sensors)"
        )
    if y.shape[1] != n_sensors:
        raise ValueError(f"response has {y.shape[1]} column(s) but sensors names {n_sensors}: one column per sensor")
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
        raise ValueError("force and response must be finite (no NaN or inf)")
    return u, y


def fit_outputs(
    modes: np.ndarray,
    force: np.ndarray,
    response: np.ndarray,
    fs: float,
    sensors: tuple,
    residual: bool = True,
    transient: bool = True,
) -> RecordFit:
    """Least-squares output coefficients of ``modes`` (M, 2) [Hz, -] on one record (module
    docstring).  The force's mean is removed first, as the framework removes it before
    the model sees a force.  ``residual=False`` fits no residual term (its coefficient 0);
    ``transient=False`` takes the record as starting from rest."""
    M, S = modes.shape[0], len(sensors)
    u, y = check_record(force, response, fs, S)
    top = modes[:, 0].max()
    if top >= fs / 2:
        raise ValueError(
            f"modes: a mode at {top:g} Hz is at or above the Nyquist frequency {fs / 2:g} Hz of the record"
        )
    n_cols = M * (3 if transient else 1) + 2
    if u.size < 4 * n_cols:
        raise ValueError(f"the record has {u.size} samples: too few for {n_cols} regressors per sensor")
    u = u - u.mean()
    R = mode_responses(u, fs, modes[:, 0], modes[:, 1])
    free = []
    if transient:
        zero = np.zeros_like(u)
        for state in ((1.0, 0.0), (0.0, 1.0)):
            free.append(mode_responses(zero, fs, modes[:, 0], modes[:, 1], state0=np.tile(state, (M, 1))))
    kinds = tuple(k for _, k in sensors)
    cols = residual_columns(u, fs, kinds)
    coefficients, res, misfit, errors = np.zeros((M, S)), np.zeros(S), {}, np.zeros((u.size, S))
    for s, (name, kind) in enumerate(sensors):
        p = KINDS.index(kind)
        parts = [R[:, :, p]] + ([cols[:, s : s + 1]] if residual else []) + [np.ones((u.size, 1))]
        X = np.column_stack(parts + [F[:, :, p] for F in free])
        # columns in very different units (m, m/s, m/s^2 per unit force, a unit decay): scale each
        scale = np.linalg.norm(X, axis=0)
        scale[scale == 0] = 1.0
        beta = np.linalg.lstsq(X / scale, y[:, s], rcond=None)[0] / scale
        coefficients[:, s] = beta[:M]
        if residual:
            res[s] = beta[M]
        fit_err = y[:, s] - X @ beta
        spread = np.std(y[:, s])
        misfit[name] = float(np.sqrt(np.mean(fit_err**2)) / spread) if spread > 0 else 0.0
        errors[:, s] = fit_err / spread if spread > 0 else 0.0
    return RecordFit(coefficients, res, misfit, errors)


def element_bounds(
    elements: tuple, modes: np.ndarray, forces, fs: float, coefficients=None, sensors=(), driving=None
) -> dict:
    """``{element name: (low, high)}``: default priors of the nonlinear elements from the
    rms of the linear unit response to the strongest of ``forces`` (means removed) of the
    element's coordinate x [m] and rate x' [m/s]: k2, k3 symmetric about 0 (:data:`ELEMENT_SHARE`
    of the stiffness force at the rms x), c3 in [0, top] (:data:`DAMPING_FACTOR` times the
    damping force at the rms x'), a friction's F in [0, :data:`ELEMENT_SHARE` of the stiffness
    force at the rms x], a clearance's kc in [0, :data:`CONTACT_FACTOR` times the stiffness]
    (whatever its gap), a Jenkins or Iwan element's kt in [0, :data:`SLIP_SHARE` of the stiffness] (whatever
    its slip).  In a mode: x = q, stiffness w^2, damping 2 zeta w.  At a
    sensor's point j (``coefficients`` (M, S), ``sensors``, ``driving`` the driving point's
    index; :mod:`.joints`): x = sum_m c_mj q_m (between the points of sensors i and j: c_mi - c_mj
    for c_mj here and below), the point's static stiffness per kg
    1 / sum_m (c_mj^2 / c_md) / w_m^2 (phi_jm^2 = c_mj^2 / c_md), and the damping 2 zeta w
    c_md / c_mj^2 of the mode that moves the point fastest (its damping seen at the point)."""
    units = [mode_responses(np.asarray(u, float) - np.mean(u), fs, modes[:, 0], modes[:, 1]) for u in forces]
    w, zeta = 2 * np.pi * modes[:, 0], modes[:, 1]
    names = [n for n, _ in sensors]
    out = {}
    for e in elements:
        if e.at is None:
            c, cd = np.eye(modes.shape[0])[e.index], np.ones(modes.shape[0])
        else:
            c, cd = point_weights(coefficients, names, e.at, e.to), coefficients[:, driving]
        rms = np.array([[np.sqrt(np.mean((R[:, :, p] * c) ** 2, axis=0)) for p in (0, 1)] for R in units])
        x_rms = max(float(np.sqrt(np.mean((R[:, :, 0] @ c) ** 2))) for R in units)
        xd_rms = max(float(np.sqrt(np.mean((R[:, :, 1] @ c) ** 2))) for R in units)
        if not (x_rms > 0 and xd_rms > 0):
            raise ValueError(f"the force is zero: no amplitude to scale the prior of {e.name} by; give bounds")
        seen = c != 0
        stiffness = 1.0 / np.sum(c[seen] ** 2 / cd[seen] / w[seen] ** 2)
        m = int(np.argmax(rms[:, 1].max(axis=0)))
        if e.kind == "c3":
            out[e.name] = (0.0, DAMPING_FACTOR * 2 * zeta[m] * w[m] * cd[m] / c[m] ** 2 / xd_rms**2)
        elif e.kind == "friction":
            out[e.name] = (0.0, ELEMENT_SHARE * stiffness * x_rms)
        elif e.kind == "clearance":
            out[e.name] = (0.0, CONTACT_FACTOR * stiffness)
        elif e.kind in ("jenkins", "iwan"):
            out[e.name] = (0.0, SLIP_SHARE * stiffness)
        else:
            power = 2 if e.kind == "k3" else 1
            top = ELEMENT_SHARE * stiffness / x_rms**power
            out[e.name] = (-top, top)
    return out


def coordinate_rms(modes: np.ndarray, coefficients: np.ndarray, sensors: tuple, force, fs: float, between=()) -> dict:
    """``{place: rms [m]}`` of the linear response to ``force`` [N] (mean removed) at ``fs`` [Hz]
    of ``modes`` (M, 2): each mode's coordinate q_m (place: its 1-based number), each sensor's
    point, x_j = sum_m c_mj q_m (place: the sensor's name; ``coefficients`` (M, S), ``sensors``
    ((name, kind), ...)), whatever the sensor's kind, and for each pair ``(i, j)`` of sensor names
    in ``between`` the displacement of i's point relative to j's (place ``"i-j"``)."""
    names = [name for name, _ in sensors]
    between = [tuple(p) for p in between]
    for pair in between:
        if len(pair) != 2 or pair[0] == pair[1] or not set(pair) <= set(names):
            raise ValueError(f"between: {pair!r} must name two different sensors of {names}")
    R = mode_responses(np.asarray(force, float) - np.mean(force), fs, modes[:, 0], modes[:, 1])[:, :, 0]
    out = {m + 1: float(np.std(R[:, m])) for m in range(modes.shape[0])}
    places = {name: (name, None) for name in names} | {f"{i}-{j}": (i, j) for i, j in between}
    out.update({p: float(np.std(R @ point_weights(coefficients, names, *ends))) for p, ends in places.items()})
    return out
