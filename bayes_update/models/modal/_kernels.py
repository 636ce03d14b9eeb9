"""The modal model's compiled time loops (:class:`~bayes_update.models.modal.ModalModel`).

Private: the physics, units and conventions are in :mod:`bayes_update.models.modal`.
Every mode starts from its ``state0`` (rest for a simulation) at the first
sample; ``out[i, m, 0:3]`` is q, q', q'' of mode m at sample i, q'' from the
equation of motion at the sample (the force is continuous there).  The elements of
one place are its coefficients (k2, k3, c3, friction F, clearance kc, Jenkins kt: the
order of :data:`~bayes_update.models.modal.spec.ELEMENTS`) and its shape constants as the
loops take them, (1 / v0, gap, slip) [s/m, m, m]: the reciprocal, as a division in the loop
would carry numba's check for a zero divisor, which made the coupled loop 3-4x slower.

A Jenkins element has a state, its slider's travel z [m] (0 at rest, at the first sample).
Within an RK4 step z is held at its value at the step's start and each stage sees the slider
where x puts it, ``clip(z, x - slip, x + slip)`` (:func:`slider`); after the step z moves there
for the step's end.  While x moves one way within a step this is the slider's exact travel
(the play operator); a reversal inside a step costs an O(dt^2) error, as a clearance's kink.
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
def slider(z, x, slip):
    """Where a Jenkins slider at ``z`` goes when its spring's end moves to ``x``: it stays while
    the stretch |x - z| is below ``slip``, else it is dragged to x -+ slip [m]."""
    return min(max(z, x - slip), x + slip)


@njit(cache=True, inline="always")
def element_force(x, xd, z, k2, k3, c3, fr, kc, kj, rv0, gap, slip):
    """The force of one place's elements at displacement x and rate xd, its Jenkins slider at ``z``
    at the step's start: k2 x^2 + k3 x^3 + c3 x'^3 + fr tanh(x' / v0) + kc (x -+ gap) beyond +-gap
    - kj slider(z, x, slip), ``rv0`` = 1 / v0.  With fr, kc and kj exactly 0 (at their null, or
    not there) the force is the polynomial's, to the last bit."""
    g = k2 * x * x + k3 * x * x * x + c3 * xd * xd * xd
    if fr != 0.0 or kc != 0.0 or kj != 0.0:
        g += _joint_force(x, xd, z, fr, kc, kj, rv0, gap, slip)
    return g


@njit(cache=True)
def _joint_force(x, xd, z, fr, kc, kj, rv0, gap, slip):
    """fr tanh(x' rv0) + kc (x -+ gap) beyond +-gap - kj slider(z, x, slip); where one is absent
    (0, and its constant 0) it adds an exact 0.  A call, not inlined: inlined, it made a run with
    none of them 16 % slower (a cubic spring in one mode, 70 000 samples: 7.7 ms for 6.6 ms)."""
    g = fr * math.tanh(xd * rv0)
    if x > gap:
        g += kc * (x - gap)
    elif x < -gap:
        g += kc * (x + gap)
    if kj != 0.0:
        g -= kj * slider(z, x, slip)
    return g


@njit(cache=True)
def nonlinear_mode(u, h, substeps, w2, zw2, c, s, q0, v0, out):
    """One mode with its nonlinear elements (``c`` (6,), ``s`` (3,): :func:`element_force`) by RK4,
    ``substeps`` steps per sample interval ``h`` [s], the force linear between samples
    (exact at each stage's time); fills ``out`` (n, 3) from the state (q0, v0) at the first sample,
    a Jenkins slider at 0.  Returns -1, or the sample at which the run diverged (|q| or |q'| beyond
    :data:`DIVERGED`, or not finite)."""
    n = u.shape[0]
    dt = h / substeps
    k2, k3, c3, fr, kc, kj = c[0], c[1], c[2], c[3], c[4], c[5]
    rv0, gap, slip = s[0], s[1], s[2]
    q = q0
    v = v0
    z = 0.0
    out[0, 0] = q
    out[0, 1] = v
    out[0, 2] = u[0] - zw2 * v - w2 * q - element_force(q, v, z, k2, k3, c3, fr, kc, kj, rv0, gap, slip)
    for i in range(n - 1):
        du = (u[i + 1] - u[i]) / substeps
        for k in range(substeps):
            fa = u[i] + du * k
            fm = fa + 0.5 * du
            fb = fa + du
            a1 = fa - zw2 * v - w2 * q - element_force(q, v, z, k2, k3, c3, fr, kc, kj, rv0, gap, slip)
            q2 = q + 0.5 * dt * v
            v2 = v + 0.5 * dt * a1
            a2 = fm - zw2 * v2 - w2 * q2 - element_force(q2, v2, z, k2, k3, c3, fr, kc, kj, rv0, gap, slip)
            q3 = q + 0.5 * dt * v2
            v3 = v + 0.5 * dt * a2
            a3 = fm - zw2 * v3 - w2 * q3 - element_force(q3, v3, z, k2, k3, c3, fr, kc, kj, rv0, gap, slip)
            q4 = q + dt * v3
            v4 = v + dt * a3
            a4 = fb - zw2 * v4 - w2 * q4 - element_force(q4, v4, z, k2, k3, c3, fr, kc, kj, rv0, gap, slip)
            q += dt * (v + 2.0 * v2 + 2.0 * v3 + v4) / 6.0
            v += dt * (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
            if kj != 0.0:
                z = slider(z, q, slip)
        # "not <" also catches NaN
        if not (math.fabs(q) < DIVERGED and math.fabs(v) < DIVERGED):
            return i + 1
        out[i + 1, 0] = q
        out[i + 1, 1] = v
        out[i + 1, 2] = u[i + 1] - zw2 * v - w2 * q - element_force(q, v, z, k2, k3, c3, fr, kc, kj, rv0, gap, slip)
    return -1


@njit(cache=True)
def _coupled_accel(q, v, f, w2, zw2, own, weights, shares, values, shapes, z, a):
    """``a`` = r'' of the coupled modes: each mode's linear terms and its own polynomial elements
    (``own`` (K, 3): k2, k3, c3 on r), less each point's force (:func:`element_force`: ``values``
    (P, 6), ``shapes`` (P, 3), ``z`` (P,) its Jenkins slider, x = weights[j] . r) times its share in
    the mode (``shares`` (P, K)).  A mode's own friction, clearance or Jenkins element comes as a
    point whose weights and shares pick that mode: the modes' loop stays free of branches, which
    cost a quarter of the run time there."""
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
        c = values[j]
        g = element_force(x, xd, z[j], c[0], c[1], c[2], c[3], c[4], c[5], shapes[j, 0], shapes[j, 1], shapes[j, 2])
        for m in range(K):
            a[m] -= shares[j, m] * g


@njit(cache=True)
def _move_sliders(q, weights, values, shapes, z):
    """Each point's Jenkins slider ``z`` (P,) dragged to where the coordinates ``q`` put it."""
    for j in range(weights.shape[0]):
        if values[j, 5] != 0.0:
            x = 0.0
            for m in range(q.shape[0]):
                x += weights[j, m] * q[m]
            z[j] = slider(z[j], x, shapes[j, 2])


@njit(cache=True)
def coupled_modes(u, h, substeps, w2, zw2, own, weights, shares, values, shapes, state0, out):
    """The modes coupled by elements at points, together by RK4 (``substeps`` steps per
    sample interval ``h`` [s], the force linear between samples); ``w2``, ``zw2`` (K,),
    ``own``, ``weights``, ``shares``, ``values``, ``shapes`` as in :func:`_coupled_accel`; fills
    ``out`` (n, K, 3) from ``state0`` (K, 2), the Jenkins sliders at 0.  Returns -1, or the sample
    at which the run diverged (a coordinate or rate beyond :data:`DIVERGED`, or not finite)."""
    n = u.shape[0]
    K = w2.shape[0]
    dt = h / substeps
    q = state0[:, 0].copy()
    v = state0[:, 1].copy()
    z = np.zeros(weights.shape[0])
    sliders = np.any(values[:, 5] != 0.0)
    stage = np.empty((10, K))  # the RK4 stages' coordinates, rates and accelerations
    q2, v2, q3, v3, q4, v4 = stage[0], stage[1], stage[2], stage[3], stage[4], stage[5]
    a1, a2, a3, a4 = stage[6], stage[7], stage[8], stage[9]
    _coupled_accel(q, v, u[0], w2, zw2, own, weights, shares, values, shapes, z, a1)
    out[0, :, 0] = q
    out[0, :, 1] = v
    out[0, :, 2] = a1
    for i in range(n - 1):
        du = (u[i + 1] - u[i]) / substeps
        for s in range(substeps):
            fa = u[i] + du * s
            fm = fa + 0.5 * du
            _coupled_accel(q, v, fa, w2, zw2, own, weights, shares, values, shapes, z, a1)
            for m in range(K):
                q2[m] = q[m] + 0.5 * dt * v[m]
                v2[m] = v[m] + 0.5 * dt * a1[m]
            _coupled_accel(q2, v2, fm, w2, zw2, own, weights, shares, values, shapes, z, a2)
            for m in range(K):
                q3[m] = q[m] + 0.5 * dt * v2[m]
                v3[m] = v[m] + 0.5 * dt * a2[m]
            _coupled_accel(q3, v3, fm, w2, zw2, own, weights, shares, values, shapes, z, a3)
            for m in range(K):
                q4[m] = q[m] + dt * v3[m]
                v4[m] = v[m] + dt * a3[m]
            _coupled_accel(q4, v4, fa + du, w2, zw2, own, weights, shares, values, shapes, z, a4)
            for m in range(K):
                q[m] += dt * (v[m] + 2.0 * v2[m] + 2.0 * v3[m] + v4[m]) / 6.0
                v[m] += dt * (a1[m] + 2.0 * a2[m] + 2.0 * a3[m] + a4[m]) / 6.0
            if sliders:
                _move_sliders(q, weights, values, shapes, z)
        for m in range(K):
            # "not <" also catches NaN
            if not (math.fabs(q[m]) < DIVERGED and math.fabs(v[m]) < DIVERGED):
                return i + 1
        _coupled_accel(q, v, u[i + 1], w2, zw2, own, weights, shares, values, shapes, z, a1)
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
