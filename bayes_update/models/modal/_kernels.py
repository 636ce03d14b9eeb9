"""The modal model's compiled time loops (:class:`~bayes_update.models.modal.ModalModel`).

Private: the physics, units and conventions are in :mod:`bayes_update.models.modal`.
Every mode starts from its ``state0`` (rest for a simulation) at the first
sample; ``out[i, m, 0:3]`` is q, q', q'' of mode m at sample i, q'' from the
equation of motion at the sample (the force is continuous there).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit

from bayes_update.core.runs import default_root

# before the decorators below: numba fixes a function's cache folder when it is decorated
# (the project's cache folder, where the runs are kept too, not numba's default: __pycache__ beside
# the source would leave files pip never removes in an installed package)
if not numba.config.CACHE_DIR:
    numba.config.CACHE_DIR = str(default_root() / "numba")

#: a modal coordinate or rate beyond this is a run that diverged (a softening spring past its
#: barrier): its cube would overflow to inf within a few steps, so stop while it is still finite
DIVERGED = 1e100


@njit(cache=True)
def linear_modes(u, phi, g0, g1, w2, zw2, state0, out):
    """Exact first-order-hold recursion of each linear mode:
    ``x[i+1] = phi x[i] + g0 u[i] + g1 u[i+1]`` with x = (q, q'); ``phi`` (M, 2, 2),
    ``g0``, ``g1`` (M, 2), ``w2`` = w^2, ``zw2`` = 2 zeta w (M,) [rad^2/s^2, rad/s];
    ``state0`` (M, 2) the state at the first sample; fills ``out`` (n, M, 3)."""
    n = u.shape[0]
    for m in range(phi.shape[0]):
        q = state0[m, 0]
        v = state0[m, 1]
        out[0, m, 0] = q
        out[0, m, 1] = v
        out[0, m, 2] = u[0] - zw2[m] * v - w2[m] * q
        for i in range(n - 1):
            qn = phi[m, 0, 0] * q + phi[m, 0, 1] * v + g0[m, 0] * u[i] + g1[m, 0] * u[i + 1]
            v = phi[m, 1, 0] * q + phi[m, 1, 1] * v + g0[m, 1] * u[i] + g1[m, 1] * u[i + 1]
            q = qn
            out[i + 1, m, 0] = q
            out[i + 1, m, 1] = v
            out[i + 1, m, 2] = u[i + 1] - zw2[m] * v - w2[m] * q


@njit(cache=True, inline="always")
def _accel(q, v, f, w2, zw2, k2, k3, c3):
    """q'' = f - 2 zeta w q' - w^2 q - (k2 q^2 + k3 q^3 + c3 q'^3)."""
    return f - zw2 * v - w2 * q - (k2 * q * q + k3 * q * q * q + c3 * v * v * v)


@njit(cache=True)
def nonlinear_mode(u, h, substeps, w2, zw2, k2, k3, c3, q0, v0, out):
    """One mode with its nonlinear elements by RK4, ``substeps`` steps per sample
    interval ``h`` [s], the force linear between samples (exact at each stage's
    time); fills ``out`` (n, 3) from the state (q0, v0) at the first sample.
    Returns -1, or the sample at which the run diverged (|q| or |q'| beyond
    :data:`DIVERGED`, or not finite)."""
    n = u.shape[0]
    dt = h / substeps
    q = q0
    v = v0
    out[0, 0] = q
    out[0, 1] = v
    out[0, 2] = _accel(q, v, u[0], w2, zw2, k2, k3, c3)
    for i in range(n - 1):
        du = (u[i + 1] - u[i]) / substeps
        for s in range(substeps):
            fa = u[i] + du * s
            fm = fa + 0.5 * du
            fb = fa + du
            a1 = _accel(q, v, fa, w2, zw2, k2, k3, c3)
            q2 = q + 0.5 * dt * v
            v2 = v + 0.5 * dt * a1
            a2 = _accel(q2, v2, fm, w2, zw2, k2, k3, c3)
            q3 = q + 0.5 * dt * v2
            v3 = v + 0.5 * dt * a2
            a3 = _accel(q3, v3, fm, w2, zw2, k2, k3, c3)
            q4 = q + dt * v3
            v4 = v + dt * a3
            a4 = _accel(q4, v4, fb, w2, zw2, k2, k3, c3)
            q += dt * (v + 2.0 * v2 + 2.0 * v3 + v4) / 6.0
            v += dt * (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
        # "not <" also catches NaN
        if not (math.fabs(q) < DIVERGED and math.fabs(v) < DIVERGED):
            return i + 1
        out[i + 1, 0] = q
        out[i + 1, 1] = v
        out[i + 1, 2] = _accel(q, v, u[i + 1], w2, zw2, k2, k3, c3)
    return -1


@njit(cache=True)
def _coupled_accel(q, v, f, w2, zw2, own, weights, shares, values, a):
    """``a`` = r'' of the coupled modes: each mode's linear terms and its own elements
    (``own`` (K, 3): k2, k3, c3 on r), less each point's force g = k2 x^2 + k3 x^3 + c3 x'^3
    (``values`` (P, 3), x = weights[j] . r) times its share in the mode (``shares`` (P, K))."""
    K = q.shape[0]
    for m in range(K):
        qm = q[m]
        vm = v[m]
        a[m] = (
            f - zw2[m] * vm - w2[m] * qm - (own[m, 0] * qm * qm + own[m, 1] * qm * qm * qm + own[m, 2] * vm * vm * vm)
        )
    for j in range(weights.shape[0]):
        x = 0.0
        xd = 0.0
        for m in range(K):
            x += weights[j, m] * q[m]
            xd += weights[j, m] * v[m]
        g = values[j, 0] * x * x + values[j, 1] * x * x * x + values[j, 2] * xd * xd * xd
        for m in range(K):
            a[m] -= shares[j, m] * g


@njit(cache=True)
def coupled_modes(u, h, substeps, w2, zw2, own, weights, shares, values, state0, out):
    """The modes coupled by elements at points, together by RK4 (``substeps`` steps per
    sample interval ``h`` [s], the force linear between samples); ``w2``, ``zw2`` (K,),
    ``own``, ``weights``, ``shares``, ``values`` as in :func:`_coupled_accel`; fills
    ``out`` (n, K, 3) from ``state0`` (K, 2).  Returns -1, or the sample at which the run
    diverged (a coordinate or rate beyond :data:`DIVERGED`, or not finite)."""
    n = u.shape[0]
    K = w2.shape[0]
    dt = h / substeps
    q = state0[:, 0].copy()
    v = state0[:, 1].copy()
    stage = np.empty((10, K))  # the RK4 stages' coordinates, rates and accelerations
    q2, v2, q3, v3, q4, v4 = stage[0], stage[1], stage[2], stage[3], stage[4], stage[5]
    a1, a2, a3, a4 = stage[6], stage[7], stage[8], stage[9]
    _coupled_accel(q, v, u[0], w2, zw2, own, weights, shares, values, a1)
    out[0, :, 0] = q
    out[0, :, 1] = v
    out[0, :, 2] = a1
    for i in range(n - 1):
        du = (u[i + 1] - u[i]) / substeps
        for s in range(substeps):
            fa = u[i] + du * s
            fm = fa + 0.5 * du
            _coupled_accel(q, v, fa, w2, zw2, own, weights, shares, values, a1)
            for m in range(K):
                q2[m] = q[m] + 0.5 * dt * v[m]
                v2[m] = v[m] + 0.5 * dt * a1[m]
            _coupled_accel(q2, v2, fm, w2, zw2, own, weights, shares, values, a2)
            for m in range(K):
                q3[m] = q[m] + 0.5 * dt * v2[m]
                v3[m] = v[m] + 0.5 * dt * a2[m]
            _coupled_accel(q3, v3, fm, w2, zw2, own, weights, shares, values, a3)
            for m in range(K):
                q4[m] = q[m] + dt * v3[m]
                v4[m] = v[m] + dt * a3[m]
            _coupled_accel(q4, v4, fa + du, w2, zw2, own, weights, shares, values, a4)
            for m in range(K):
                q[m] += dt * (v[m] + 2.0 * v2[m] + 2.0 * v3[m] + v4[m]) / 6.0
                v[m] += dt * (a1[m] + 2.0 * a2[m] + 2.0 * a3[m] + a4[m]) / 6.0
        for m in range(K):
            # "not <" also catches NaN
            if not (math.fabs(q[m]) < DIVERGED and math.fabs(v[m]) < DIVERGED):
                return i + 1
        _coupled_accel(q, v, u[i + 1], w2, zw2, own, weights, shares, values, a1)
        out[i + 1, :, 0] = q
        out[i + 1, :, 1] = v
        out[i + 1, :, 2] = a1
    return -1


@njit(cache=True)
def combine(R, coefficients, orders, out):
    """``out[i, s] = sum_m coefficients[m, s] R[i, m, orders[s]]``: a loop, not a BLAS
    product, whose threads would spin against the other model runs of a worker pool."""
    n, M, _ = R.shape
    for i in range(n):
        for s in range(orders.shape[0]):
            acc = 0.0
            for m in range(M):
                acc += coefficients[m, s] * R[i, m, orders[s]]
            out[i, s] = acc
