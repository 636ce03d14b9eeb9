"""The modal ROM's compiled time integrator (:class:`fe.rom.ModalROM`): RK4 for the
modal coordinates, the massless top integrated exactly for its interpolated drive
(the method and its stability: :mod:`fe.rom`'s docstring, "Time integration")."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _ik(a, k):
    """I_k(a) = a int_0^1 exp(-a y) (1 - y)^k dy for k = 0, 1, 2 (I_k(inf) = 1)."""
    if math.isinf(a):
        return 1.0
    if a < 1.0:  # series a sum_j (-a)^j k! / (j + k + 1)!: the recurrence cancels here
        term = a / (k + 1.0)
        total = 0.0
        j = 0
        while abs(term) > 1e-17 * abs(total) or j == 0:
            total += term
            j += 1
            term *= -a / (j + k + 1.0)
        return total
    val = -math.expm1(-a)
    for j in range(1, k + 1):
        val = 1.0 - j * val / a
    return val


@njit(cache=True)
def _top_weights(damping, stiffness, h, out):
    """Weights of the exact solution of D U' + K U = r(t) over a step with r
    interpolated: U(h/2) = out[0] U0 + out[1] r(0) + out[2] r(h/2) (linear) and
    U(h) = out[3] U0 + out[4] r(0) + out[5] r(h/2) + out[6] r(h) (quadratic).
    D = 0 gives the quasi-static U = r / K."""
    for j in range(2):
        theta = 0.5 * h if j == 0 else h
        a = math.inf if damping == 0.0 else theta * stiffness / damping
        e = 0.0 if math.isinf(a) else math.exp(-a)
        p0 = _ik(a, 0) / stiffness
        p1 = _ik(a, 1) / stiffness
        p2 = _ik(a, 2) / stiffness
        if j == 0:
            out[0] = e
            out[1] = p0 - p1
            out[2] = p1
        else:
            out[3] = e
            out[4] = p0 - 3.0 * p1 + 2.0 * p2
            out[5] = 4.0 * p1 - 4.0 * p2
            out[6] = -p1 + 2.0 * p2


@njit(cache=True, inline="always")
def _drive(G, g0, q, qd, a, F, kb, bkb):
    """a = G q + g0 (into ``a``, the gradient of s) and the top's drive
    r = -F - K_b s - beta K_b s'."""
    n = q.shape[0]
    s = 0.0
    sd = 0.0
    for i in range(n):
        gq = 0.0
        for j in range(n):
            gq += G[i, j] * q[j]
        a[i] = gq + g0[i]
        s += q[i] * (0.5 * gq + g0[i])
        sd += a[i] * qd[i]
    return -F - kb * s - bkb * sd


@njit(cache=True, inline="always")
def _accel(kappa, b, beta, q, qd, a, N, f, out):
    """q'' = b f - kappa (q + beta q') - N a (kappa: the diagonal bending stiffness)."""
    for i in range(q.shape[0]):
        out[i] = b[i] * f - kappa[i] * (q[i] + beta * qd[i]) - N * a[i]


@njit(cache=True)
def _transient(reduced, W, top, force, ns, substeps, h, state, outputs):
    """RK4 in (q, q') with the top state U integrated exactly for an
    interpolated drive (see :func:`_top_weights`).

    ``reduced = (kappa, G, g0, b)``: the reduced beam (:class:`fe.rom_basis.ReducedSystem`);
    ``top = (beta, kb, F, ks, c)``: the Kelvin-Voigt ratio [s], the beam's axial
    stiffness, the preload, the top spring and damper; ``force`` holds the force
    at every RK4 stage time, 2 substeps points per sample, ``h`` the step [s];
    ``state = (q, qd, U)`` the start (``q``, ``qd`` hold the final state on
    return).  ``outputs = (out_d, out_v, out_a)`` receive W q, W q' and U at
    each of the ``ns`` samples."""
    kappa, G, g0, b = reduced
    beta, kb, F, ks, c = top
    q, qd, U = state
    out_d, out_v, out_a = outputs
    n = q.shape[0]
    nout = W.shape[0]
    bkb = beta * kb
    ktop = kb + ks
    dtop = c + bkb
    # beam tension from the top's balance, N = -F - k_s U - c U' with
    # c U' = (c / D)(r - K U): finite as D -> 0 (then U = r / K)
    cd = c / dtop if dtop > 0.0 else 0.0
    wts = np.empty(7)
    _top_weights(dtop, ktop, h, wts)
    eh, a0, a1, ef, b0, bm, b1 = wts[0], wts[1], wts[2], wts[3], wts[4], wts[5], wts[6]
    a = np.empty(n)
    q2 = np.empty(n)
    v2 = np.empty(n)
    q3 = np.empty(n)
    v3 = np.empty(n)
    q4 = np.empty(n)
    v4 = np.empty(n)
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    r1 = _drive(G, g0, q, qd, a, F, kb, bkb)
    for k in range(ns):
        if k > 0:
            for sub in range(substeps):
                j = 2 * (substeps * (k - 1) + sub)
                fa = force[j]
                fm = force[j + 1]
                fb = force[j + 2]
                # stage 1 (t); ``a`` holds G q + g0 of the current state
                N = -F - ks * U - cd * (r1 - ktop * U)
                _accel(kappa, b, beta, q, qd, a, N, fa, k1)
                for i in range(n):
                    q2[i] = q[i] + 0.5 * h * qd[i]
                    v2[i] = qd[i] + 0.5 * h * k1[i]
                # stage 2 (t + h/2)
                r2 = _drive(G, g0, q2, v2, a, F, kb, bkb)
                U2 = eh * U + a0 * r1 + a1 * r2
                N = -F - ks * U2 - cd * (r2 - ktop * U2)
                _accel(kappa, b, beta, q2, v2, a, N, fm, k2)
                for i in range(n):
                    q3[i] = q[i] + 0.5 * h * v2[i]
                    v3[i] = qd[i] + 0.5 * h * k2[i]
                # stage 3 (t + h/2)
                r3 = _drive(G, g0, q3, v3, a, F, kb, bkb)
                U3 = eh * U + a0 * r1 + a1 * r3
                N = -F - ks * U3 - cd * (r3 - ktop * U3)
                _accel(kappa, b, beta, q3, v3, a, N, fm, k3)
                for i in range(n):
                    q4[i] = q[i] + h * v3[i]
                    v4[i] = qd[i] + h * k3[i]
                # stage 4 (t + h); the mid-stage average is an O(h^3) midpoint
                rm = 0.5 * (r2 + r3)
                r4 = _drive(G, g0, q4, v4, a, F, kb, bkb)
                U4 = ef * U + b0 * r1 + bm * rm + b1 * r4
                N = -F - ks * U4 - cd * (r4 - ktop * U4)
                _accel(kappa, b, beta, q4, v4, a, N, fb, k4)
                for i in range(n):
                    q[i] += h / 6.0 * (qd[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i])
                    qd[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
                r_new = _drive(G, g0, q, qd, a, F, kb, bkb)  # also the next stage 1's a
                U = ef * U + b0 * r1 + bm * rm + b1 * r_new
                r1 = r_new
        for o in range(nout):
            sd = 0.0
            sv = 0.0
            for i in range(n):
                sd += W[o, i] * q[i]
                sv += W[o, i] * qd[i]
            out_d[k, o] = sd
            out_v[k, o] = sv
        out_a[k] = U
