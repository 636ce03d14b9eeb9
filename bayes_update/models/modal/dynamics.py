"""The modal model's time response: every mode's q, q', q'' at the samples, and the
sensors' outputs from them (:mod:`bayes_update.models.modal` states the physics).

The force is linear between samples (docs/models.md, "What the samples of the
force mean").  A linear mode is advanced by its exact discretisation for that
input (first-order hold): the state-transition and input matrices come from
closed forms (:func:`foh_matrices`), computed once per run in numpy, so that a linear
mode carries no time-step error at any sampling rate.  A mode with a
nonlinear element is integrated by RK4 with substeps, the force interpolated
linearly at each stage; the modes coupled by elements at points (joints:
:class:`Coupling`, :mod:`.joints`) are integrated together, by one RK4 over all of them.

Accuracy against DOP853 (tests/test_modal_joints.py, the default four substeps).  The smooth
elements keep RK4's order 4: a friction leaves 1e-8 to 5e-8 of the response's rms, the error
falling 14-16x per halved step.  A clearance's kink costs the order: a step that crosses it
integrates a jump of the acceleration's slope, an O(dt^2) error at each crossing whose sign
and size depend on where in the step the crossing falls; the error falls as dt^2 on average
(least-squares order 1.6-2.1 over 1 to 32 substeps) but erratically from one doubling to the
next (0.4x to 28x), and four substeps leave 1e-4 to 5e-3 of the rms (a mode, four forces; a
chain's joint 3e-4).  The steps are sized to the contact spring at the top of its prior
(:func:`step_rate_hz`), which bounds kc dt^2 and so each crossing's error; raise ``substeps``
where that is too much (the framework's model error, ``refined()``, sees it).  A clearance
stiff against the structure can make the response itself sensitive (a 1e-5 change of the force
grown to 3e-2 of it in 10 s): then no model follows a long record sample by sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bayes_update.core.model_errors import ModelError

from . import _kernels
from .spec import COLUMNS, ELEMENTS

__all__ = [
    "STEP_RAD",
    "Coupling",
    "foh_matrices",
    "rk4_substeps",
    "step_rate_hz",
    "mode_responses",
    "residual_columns",
    "outputs",
]

#: before the ``substeps`` factor, an RK4 step spans at most this much of the nonlinear mode's
#: linear cycle at the top of its frequency prior [rad]; with the default 4 substeps each step is
#: at most 0.125 rad (50 steps a cycle), where RK4's phase error is about 2e-7 rad a step
STEP_RAD = 0.5
#: terms of the Taylor series of phi_k(z) for |z| < 1: the first left out is below 1 / 27!
_SERIES_TERMS = 24


def _phi123(z: np.ndarray) -> tuple:
    """phi_k(z) = sum_j z^j / (j + k)! for k = 1, 2, 3 (complex z): the Taylor series where
    |z| < 1 (the recurrence below cancels there), else phi_1 = (e^z - 1) / z and
    phi_(k+1) = (phi_k - 1/k!) / z."""
    small = np.abs(z) < 1.0
    zs = np.where(small, z, 0.0)
    series = []
    for k in (1, 2, 3):
        term = np.full_like(zs, 1.0 / math.factorial(k))
        total = term.copy()
        for j in range(1, _SERIES_TERMS):
            term = term * zs / (j + k)
            total = total + term
        series.append(total)
    zl = np.where(small, 1.0, z)
    p1 = np.where(small, series[0], np.expm1(zl.real) * np.exp(1j * zl.imag) / zl + (np.exp(1j * zl.imag) - 1) / zl)
    p2 = np.where(small, series[1], (p1 - 1.0) / zl)
    p3 = np.where(small, series[2], (p2 - 0.5) / zl)
    return p1, p2, p3


def foh_matrices(w: np.ndarray, zeta: np.ndarray, h: float) -> tuple:
    """``phi`` (M, 2, 2), ``g0``, ``g1`` (M, 2) of ``x[i+1] = phi x[i] + g0 u[i] + g1 u[i+1]``,
    x = (q, q'), exact for q'' + 2 zeta w q' + w^2 q = u with u linear over the step
    ``h`` [s]; ``w`` [rad/s], 0 < zeta < 1.

    Closed form: with the pole lam = -zeta w + j w_d and z = lam h, the impulse response
    is g(t) = Im(e^(lam t)) / w_d, and its integrals over the step, S0 = int g and
    S1 = int t g, are h Im(z phi_2(z)) / w_d and h^2 Im(z (phi_2 - phi_3)(z)) / w_d
    (:func:`_phi123`: no cancellation however small w h is).  Then the response to
    u[i] (1 - t/h) + u[i+1] t/h is g0 = (S1 / h, g(h) - S0 / h), g1 = (S0 - S1 / h, S0 / h)."""
    w = np.asarray(w, float)
    a = zeta * w
    wd = w * np.sqrt(1.0 - zeta**2)
    z = (-a + 1j * wd) * h
    _, p2, p3 = _phi123(z)
    decay, c, s = np.exp(-a * h), np.cos(wd * h), np.sin(wd * h)
    g_h = decay * s / wd
    s0 = h * (z * p2).imag / wd
    s1 = h * h * (z * (p2 - p3)).imag / wd
    phi = np.empty((w.size, 2, 2))
    phi[:, 0, 0] = decay * (c + a * s / wd)
    phi[:, 0, 1] = g_h
    phi[:, 1, 0] = -(w**2) * g_h
    phi[:, 1, 1] = decay * (c - a * s / wd)
    g0 = np.column_stack([s1 / h, g_h - s0 / h])
    g1 = np.column_stack([s0 - s1 / h, s0 / h])
    return phi, g0, g1


def rk4_substeps(f_top_hz: float, fs: float, substeps: int) -> int:
    """RK4 steps per sample of a nonlinear mode: ``substeps`` times enough steps that
    each spans at most :data:`STEP_RAD` of the mode's cycle at ``f_top_hz``, the top of
    its frequency prior (:func:`step_rate_hz` with a friction or clearance).  A constant of
    the model (not of theta): a step count that moved with theta would make the response
    jump between neighbouring points."""
    return int(substeps) * max(1, math.ceil(2 * math.pi * f_top_hz / fs / STEP_RAD))


def step_rate_hz(f_top_hz: float, contact: float = 0.0, slope: float = 0.0) -> float:
    """The rate [Hz] RK4's step is sized for (:func:`rk4_substeps`) where clearances and frictions
    act: the highest frequency ``f_top_hz`` raised by the contact springs, sqrt(f^2 + contact /
    (2 pi)^2), or the frictions' slope / (2 pi) if that is faster.  ``contact`` [1/s^2] and
    ``slope`` [1/s] sum kc and F / v0 (the friction's viscous slope through x' = 0) at the top of
    their priors, each times w . s, the eigenvalue of its rank-one term in the modes' equations
    (w . s = 1 in a mode, sum_m c_mj^2 / c_md at a point j: :mod:`.joints`): a step that spans
    at most :data:`STEP_RAD` / substeps of the stiffest linearised motion, as of a mode's cycle
    (an explicit RK4 is unstable beyond 2.8 rad, which a small v0 would otherwise pass)."""
    return max(math.sqrt(f_top_hz**2 + contact / (2 * math.pi) ** 2), slope / (2 * math.pi))


@dataclass(frozen=True)
class Coupling:
    """Elements at points, as the integrator takes them (:mod:`.joints`): the displacement of
    point j is x_j = weights[j] @ r (``weights`` (P, M)); its force g_j (``values`` (P, 6): k2,
    k3, c3, friction, clearance, Jenkins in SI units per unit modal mass; ``shapes`` (P, 3): v0,
    gap, slip)
    enters mode m's equation times ``shares[j, m]``.  The modes it couples (a weight or share
    not 0) are integrated together by RK4, ``steps`` steps per sample; ``points`` names the
    points (for a message)."""

    weights: np.ndarray
    shares: np.ndarray
    values: np.ndarray
    shapes: np.ndarray
    steps: int
    points: tuple = ()

    @property
    def modes(self) -> np.ndarray:
        """The 0-based indices of the coupled modes."""
        return np.flatnonzero(np.any(self.weights != 0, axis=0) | np.any(self.shares != 0, axis=0))


def mode_responses(
    force: np.ndarray,
    fs: float,
    f_hz: np.ndarray,
    zeta: np.ndarray,
    elements: dict | None = None,
    steps: dict | None = None,
    state0: np.ndarray | None = None,
    coupling: Coupling | None = None,
) -> np.ndarray:
    """q [m], q' [m/s], q'' [m/s^2] of every mode at every sample, (n, M, 3), each mode
    from ``state0`` (M, 2) (default rest) at the first sample.

    elements : ``{mode index (0-based): (coefficients, shapes)}``, the mode's (k2, k3, c3,
        friction, clearance, Jenkins) in SI units and (v0, gap, slip) [m/s, m, m]; these modes are integrated
        by RK4, ``steps[index]`` steps per sample; the others are linear.
    coupling : elements at points; the modes they couple are integrated together (with
        their own ``elements``), ``coupling.steps`` steps per sample.

    Raises :class:`~bayes_update.ModelError` when a nonlinear mode diverges."""
    u = np.ascontiguousarray(force, dtype=float)
    w = 2 * np.pi * np.asarray(f_hz, float)
    n, M = u.size, w.size
    zeta = np.asarray(zeta, float)
    elements = elements or {}
    state0 = np.zeros((M, 2)) if state0 is None else np.asarray(state0, float)
    coupled = coupling.modes if coupling is not None else np.zeros(0, np.int64)
    out = np.empty((n, M, 3))
    lin = np.array([m for m in range(M) if m not in elements and m not in coupled], dtype=np.int64)
    if lin.size:
        phi, g0, g1 = foh_matrices(w[lin], zeta[lin], 1.0 / fs)
        part = np.empty((n, lin.size, 3))
        _kernels.linear_modes(
            u, phi, g0, g1, w[lin] ** 2, 2 * zeta[lin] * w[lin], np.ascontiguousarray(state0[lin]), part
        )
        if lin.size == M:
            return part
        out[:, lin] = part
    for m, (c, shape) in elements.items():
        if m in coupled:
            continue
        col = np.empty((n, 3))
        c, shape = np.asarray(c, float), _loop_shapes(shape)
        bad = _kernels.nonlinear_mode(
            u, 1.0 / fs, steps[m], w[m] ** 2, 2 * zeta[m] * w[m], c, shape, state0[m, 0], state0[m, 1], col
        )
        if bad >= 0:
            raise ModelError(
                f"mode {m + 1} diverged at sample {bad} (t = {bad / fs:.4g} s) with {_named(c)}: a softening "
                "element past its barrier, or negative damping"
            )
        out[:, m] = col
    if coupled.size:
        out[:, coupled] = _coupled(u, fs, w, zeta, elements, state0, coupling, coupled)
    return out


def _coupled(u, fs, w, zeta, elements, state0, coupling: Coupling, coupled: np.ndarray) -> np.ndarray:
    """(n, K, 3): the coupled modes by one RK4; ModelError when they diverge.  A coupled mode's
    own friction, clearance or Jenkins element goes in as one more point, whose weights and shares pick that mode
    (x = its coordinate, exactly: the other weights are 0), as the loop takes them."""
    K = coupled.size
    own = np.zeros((K, 3))
    weights, shares = [coupling.weights[:, coupled]], [coupling.shares[:, coupled]]
    values, shapes = [coupling.values], [coupling.shapes]
    for k, m in enumerate(coupled):
        if m not in elements:
            continue
        c, shape = (np.asarray(a, float) for a in elements[m])
        own[k] = c[:3]
        if np.any(shape):  # a friction, a clearance or a Jenkins element in this mode
            weights.append(np.eye(K)[k : k + 1])
            shares.append(np.eye(K)[k : k + 1])
            values.append(np.concatenate([np.zeros(3), c[3:]])[None])
            shapes.append(shape[None])
    part = np.empty((u.size, K, 3))
    bad = _kernels.coupled_modes(
        u,
        1.0 / fs,
        coupling.steps,
        w[coupled] ** 2,
        2 * zeta[coupled] * w[coupled],
        own,
        np.vstack(weights),
        np.vstack(shares),
        np.vstack(values),
        _loop_shapes(np.vstack(shapes)),
        np.ascontiguousarray(state0[coupled]),
        part,
    )
    if bad >= 0:
        values = "; ".join(f"{p}: {_named(c)}" for p, c in zip(coupling.points, coupling.values))
        raise ModelError(
            f"modes {[int(m) + 1 for m in coupled]}, coupled by the joint(s) at {values} (per kg), "
            f"diverged at sample {bad} (t = {bad / fs:.4g} s): a softening element past its barrier, "
            "or negative damping"
        )
    return part


def _loop_shapes(shapes) -> np.ndarray:
    """Shape constants (v0 [m/s], gap [m], slip [m]) as the loops take them: (1 / v0, gap, slip), 0
    where no v0."""
    out = np.array(shapes, dtype=float)
    v0 = out[..., 0]
    out[..., 0] = np.divide(1.0, v0, out=np.zeros_like(v0), where=v0 > 0)
    return out


def _named(coefficients) -> str:
    """``k3 = 1e+09 1/(m^2 s^2), ...``: a place's coefficients that are not 0, for a message."""
    named = [f"{k} = {c:.4g} {ELEMENTS[k][1]}" for k, c in zip(COLUMNS, coefficients) if c != 0]
    return ", ".join(named) or "every element at its null"


def residual_columns(force: np.ndarray, fs: float, kinds: tuple) -> np.ndarray:
    """(n, S): what each sensor's residual coefficient multiplies.  Displacement: the
    force [N] (residual flexibility of the modes above the band, [m/N]); acceleration:
    the force (the mass line of the modes below it, [1/kg]); velocity: the force's
    rate [N/s] (residual flexibility seen in velocity, [m/N]), the slope of the
    linear join averaged over the two intervals at each sample (central difference;
    one-sided at the record's ends)."""
    u = np.asarray(force, float)
    rate = np.gradient(u, 1.0 / fs) if "velocity" in kinds and u.size > 1 else np.zeros_like(u)
    return np.column_stack([rate if k == "velocity" else u for k in kinds])


def outputs(R: np.ndarray, coefficients: np.ndarray, orders: np.ndarray, residual, columns) -> np.ndarray:
    """(n, S) sensor outputs: ``sum_m c_ms R[:, m, p_s] + d_s columns[:, s]``, p_s = the
    sensor's derivative order (0 displacement, 1 velocity, 2 acceleration)."""
    y = np.empty((R.shape[0], orders.size))
    _kernels.combine(R, np.ascontiguousarray(coefficients, dtype=float), np.asarray(orders, np.int64), y)
    if columns is not None:
        y += columns * residual
    return y
