"""Nonlinear elements at a sensor's point (a joint): the physics, the driving point's check, and
the weights the integrator takes (:mod:`bayes_update.models.modal`).

Derivation.  A proportionally damped structure, the force u [N] at point d and a joint's force
g_j(x_j, x_j') [N] at point j (k2 x^2, k3 x^3, c3 x'^3: N/m^2, N/m^3, N s^3/m^3; F tanh(x'/v0):
N; kc (x -+ gap) beyond +-gap: N/m)::

    M x'' + C x' + K x = e_d u - sum_j e_j g_j(x_j, x_j')

In the mass-normalised shapes phi (Phi^T M Phi = I, phi_jm [1/sqrt(kg)]), x = Phi q::

    q_m'' + 2 zeta_m w_m q_m' + w_m^2 q_m = phi_dm u - sum_j phi_jm g_j,   x_j = sum_m phi_jm q_m

The model's coordinates have unit input (the package docstring's q_m, here r_m):
r_m = q_m / (phi_dm m0), m0 = 1 kg, r_m [m], so::

    r_m'' + 2 zeta_m w_m r_m' + w_m^2 r_m = u / m0 - sum_j (phi_jm / phi_dm) g_j / m0

A displacement sensor at s reads x_s = sum_m phi_sm q_m = sum_m (phi_sm phi_dm m0) r_m: its
output coefficients are c_ms = phi_sm phi_dm m0 [-], what the fit of a record finds; a velocity
or acceleration sensor has the same c (its derivative order differs).  Hence, whatever sensor
j's kind, the displacement of its point is x_j = sum_m c_mj r_m, and the share of the joint's
force in mode m's equation is phi_jm / phi_dm = c_mj / c_md, with the coefficients of a sensor at
the driving point (the *driving-point sensor*), c_md = phi_dm^2 m0: positive for every mode,
whatever that sensor's kind (a mode the force excites is seen where the force acts, in phase).
The joint at the driving point itself has the share 1 in every mode.  A joint between the points
of sensors i and j (one body held on another) acts on both, +g at i and -g at j, on their relative
displacement x = x_i - x_j: its weights and its share are c_mi - c_mj and (c_mi - c_mj) / c_md.  So::

    r_m'' + 2 zeta_m w_m r_m' + w_m^2 r_m + sum_j (c_mj / c_md) kappa_j(x_j, x_j') = u [N] / m0

Units.  The parameter kappa_j (``k3_at_acc1``) is the joint's physical coefficient per the
1 kg of the unit input: 1/(m s^2), 1/(m^2 s^2), s/m^2, m/s^2, 1/s^2 for k2, k3, c3, friction,
clearance, numerically the physical coefficient in N/m^2, N/m^3, N s^3/m^3, N, N/m.  No mass
normalisation beyond the record's is needed: the measured force fixes the coefficients' scale
(c_md = phi_dm^2 m0 in absolute terms), so the fitted value is the joint's physical coefficient.
The shape constants v0 [m/s] and gap [m] are of x_j, the point's physical rate and displacement.

The modes outside the band are left out: the joint's force excites them too (as the residual
terms stand for them in the response to u, not to the joint's force).  A fitted c_md carries the
record's noise; a driving point is refused where a mode's c_md is not positive or below
:data:`DRIVING_SHARE` of that mode's largest coefficient over the sensors (phi_dm below that
share of the mode's largest shape seen): the share c_mj / c_md would then be of noise.
"""

from __future__ import annotations

import math

import numpy as np

from .spec import COLUMNS, IWAN_SLIDERS, SHAPE_COLUMNS, SHAPES, column, shape_column

__all__ = ["DRIVING_SHARE", "check_driving_point", "joint_matrices", "place_values", "point_weights"]

#: the smallest c_md / max_s abs(c_ms) of a mode at the driving point (phi_dm / max_s abs(phi_sm)): below it
#: the mode is not seen where the force acts, and its share of a joint's force (1 / phi_dm) not known
DRIVING_SHARE = 0.01


def check_driving_point(driving_point, sensors: tuple, coefficients: np.ndarray, elements: tuple) -> int | None:
    """The index of the driving-point sensor (None: none named, and no element at a sensor).
    Raises ``ValueError`` naming what is missing or wrong: an element at a sensor without a
    driving point, a name that is no sensor, a mode whose coefficient there is not positive."""
    names = [n for n, _ in sensors]
    joints = [e for e in elements if e.at is not None]
    if driving_point is None:
        if joints:
            raise ValueError(
                f"nonlinear: {joints[0].name} sits at {joints[0].where}, but no driving point is named: give "
                "driving_point=<the sensor at the point where the force acts>; its output coefficients "
                "scale the joint's force into each mode's equation (bayes_update.models.modal.joints)"
            )
        return None
    if driving_point not in names:
        raise ValueError(f"driving_point {driving_point!r} is not a sensor; the sensors are {names}")
    d = names.index(driving_point)
    c = coefficients[:, d]
    top = np.max(np.abs(coefficients), axis=1)
    for m, (cm, tm) in enumerate(zip(c, top), start=1):
        if not cm > DRIVING_SHARE * tm:
            raise ValueError(
                f"driving_point {driving_point!r}: its coefficient of mode {m} is {cm:.4g} (the mode's largest "
                f"is {tm:.4g}); at the driving point every mode's coefficient is phi_d^2 > 0, above "
                f"{DRIVING_SHARE:g} of its largest: the force does not act at this sensor (or its sign is "
                f"reversed), or mode {m} is not seen there"
            )
    return d


def joint_matrices(elements: tuple, sensors: tuple, coefficients: np.ndarray, driving: int | None) -> tuple:
    """``(points, weights, shares, shapes)`` of the elements at sensors: ``points`` the sensors'
    names that carry one (P,), ``weights`` (P, M) with x_j = weights[j] @ r (c_mj), ``shares``
    (P, M) the share of point j's force in mode m's equation (c_mj / c_md), ``shapes`` (P, 3) the
    shape constants of its friction, clearance and Jenkins element (v0 [m/s], gap [m], slip [m]; 0
    where there is none).  A point is a sensor's name, or ``"i-j"`` for an element between two.
    An Iwan element, at a point or in a mode, is :data:`~.spec.IWAN_SLIDERS` rows of its own,
    ``"<its name>[i]"``, one Jenkins slider each (in a mode: weights and shares pick the mode)."""
    names = [n for n, _ in sensors]
    ends = {e.point: (e.at, e.to) for e in elements if e.at is not None and e.kind != "iwan"}
    iwans = [e for e in elements if e.kind == "iwan"]
    points = tuple(ends) + tuple(row for e in iwans for row in _iwan_rows(e))
    M = coefficients.shape[0]
    weights, shares = np.zeros((len(points), M)), np.zeros((len(points), M))
    shapes = np.zeros((len(points), len(SHAPE_COLUMNS)))
    for e in elements:
        if e.kind == "iwan":
            rows = [points.index(row) for row in _iwan_rows(e)]
            shapes[rows, shape_column("iwan")] = e.shape * np.arange(1, IWAN_SLIDERS + 1) / IWAN_SLIDERS
            w = np.eye(M)[e.index] if e.at is None else point_weights(coefficients, names, e.at, e.to)
            weights[rows] = w
            shares[rows] = w if e.at is None else w / coefficients[:, driving]
        elif e.at is not None and e.kind in SHAPES:
            shapes[points.index(e.point), shape_column(e.kind)] = e.shape
    for p, name in enumerate(ends):
        weights[p] = point_weights(coefficients, names, *ends[name])
        shares[p] = weights[p] / coefficients[:, driving]
    for p, name in enumerate(points):
        if not np.any(weights[p]):
            raise ValueError(f"nonlinear: sensor(s) {name!r} see no mode (its coefficients are all 0): no joint there")
    return points, weights, shares, shapes


def _iwan_rows(element) -> list:
    """The names of an Iwan element's slider rows."""
    return [f"{element.name}[{i}]" for i in range(IWAN_SLIDERS)]


def place_values(elements: tuple, theta, candidates: tuple, points: tuple) -> tuple:
    """``({mode index: (coefficients (6,), shapes (3,))}, values (P, 6))``: each element's
    coefficient at ``theta`` in its place's integrator column (:data:`~.spec.COLUMNS`), a mode's
    own or its point's row; an Iwan element's kt split evenly over its sliders' rows; a candidate
    absent from ``theta`` at its null 0."""
    modes, values = {}, np.zeros((len(points), len(COLUMNS)))
    for e in elements:
        value = float(theta.get(e.name, 0.0) if e in candidates else theta[e.name])
        if not math.isfinite(value):
            raise ValueError(f"theta['{e.name}'] = {value!r} {e.unit}: must be finite")
        if e.kind == "iwan":
            values[[points.index(row) for row in _iwan_rows(e)], column("iwan")] = value / IWAN_SLIDERS
        elif e.at is not None:
            values[points.index(e.point), column(e.kind)] = value
        else:
            c, shapes = modes.setdefault(e.index, (np.zeros(len(COLUMNS)), np.zeros(len(SHAPE_COLUMNS))))
            c[column(e.kind)] = value
            if e.kind in SHAPES:
                shapes[shape_column(e.kind)] = e.shape
    return modes, values


def point_weights(coefficients: np.ndarray, names: list, at: str, to: str | None = None) -> np.ndarray:
    """(M,): x = weights @ r, the displacement of sensor ``at``'s point, or of it relative to
    sensor ``to``'s: c_m,at - c_m,to."""
    w = coefficients[:, names.index(at)].astype(float)
    return w if to is None else w - coefficients[:, names.index(to)]
