"""Numba kernels of the co-rotational beam element: internal force, consistent
tangent and strain energy of the beam elements and of the discrete (nodal) ones.

Private: use :class:`fe.BeamModel`.  Apart from :mod:`fe._kernels`, which holds
the solvers that call these kernels (the static Newton and the generalized-alpha
transient) and re-exports them: the element is the physics, the solvers the
algorithm.

Conventions: node i carries the global dofs (3i, 3i+1, 3i+2) = (axial x,
transverse y, rotation theta); element e joins nodes e and e+1.

Every kernel takes the beam as two tuples (built once per parameter set by
``BeamModel._arrays``):

* ``elements = (X, Y, L0, c0, s0, t0, EA, EI, beta, shallow)``: the nodes'
  reference coordinates X, Y [m] (n_nodes,), each element's reference length
  L0 [m], chord cosine c0 and sine s0, reference end rotations t0 (n_el, 2)
  [rad], the axial and bending stiffness EA [N] and EI [N m^2], the
  Kelvin-Voigt ratio beta = eta_b / E [s] and the shallow-arch strain flag;
* ``discrete = (d_dof, d_law, d_p1, d_p2)``: each discrete element's dof, law
  (``LAW_*``) and its two constants (:class:`fe.model.DiscreteElement`).

Element (Crisfield 1991, vol. 1, ch. 7; Battini 2002): the co-rotational frame
follows the chord; the local deformations are the stretch u_l = L_n - L_0 and
the end rotations relative to the chord t1, t2.  With ``shallow`` the local
axial strain is the shallow-arch one,

    eps = u_l / L_0 + (2 t1^2 - t1 t2 + 2 t2^2) / 30,

(the element average of u' + w'^2 / 2 with a cubic w), which gives the
consistent geometric stiffness N L/30 [[4, -1], [-1, 4]] in the local frame and
converges far faster than the "string" form eps = u_l / L_0 (``shallow`` off,
the classic element of OpenSees' corotational transformation).

Initially curved elements (a bow): ``t0[e]`` holds the reference end rotations
relative to the reference chord; the end rotations t1, t2 of the code are
measured from them (the reference is stress free in bending), and the shallow
strain is that of the total rotations T = t0 + t minus its reference value,

    eps = u_l / L_0 + (A(T1, T2) - A(t0_1, t0_2)) / 30,   A = 2 a^2 - a b + 2 b^2,

the element average of (w0 + w)'^2 / 2 - w0'^2 / 2 with cubic w0 and w.  A bow
given by nodal offsets and slopes is then cubic inside each element, O(h^4),
where straight elements between bowed nodes were O(h^2).

Kelvin-Voigt viscosity: the stress sigma_v = eta_b * d(eps)/dt acts on the
true local deformation rates, so the local viscous force is
beta (E A L a a^T + K_bend) q_dot with beta = eta_b / E and a = d eps / d q:
it damps the material stiffness, never the preload's geometric term, and the
shortening rate inside the element is damped too (the nonlinear part a
constant beta K_0 would miss).
"""

import math

import numpy as np
from numba import njit

# discrete (nodal) element laws, see fe.model.DiscreteElement
LAW_SPRING = 0  # f = p1 u
LAW_DAMPER = 1  # f = p1 v
LAW_QUADRATIC_DAMPER = 2  # f = p1 |v| v
LAW_COULOMB = 3  # f = p1 tanh(v / p2)


@njit(cache=True, inline="always")
def _arch(t1, t2):
    """30 x the element average of w'^2 / 2 for a cubic w with end rotations
    t1, t2 relative to the chord."""
    return 2.0 * t1 * t1 - t1 * t2 + 2.0 * t2 * t2


@njit(cache=True, error_model="numpy")
def internal_force(elements, discrete, u, v, fint):
    """Internal force only (the hot path of the transient: no allocation)."""
    X, Y, L0, c0, s0, t0, EA, EI, beta, shallow = elements
    d_dof, d_law, d_p1, d_p2 = discrete
    ne = L0.shape[0]
    fint[:] = 0.0
    for e in range(ne):
        i0 = 3 * e
        L = L0[e]
        dx = X[e + 1] - X[e] + u[i0 + 3] - u[i0]
        dy = Y[e + 1] - Y[e] + u[i0 + 4] - u[i0 + 1]
        Ln = math.sqrt(dx * dx + dy * dy)
        c = dx / Ln
        s = dy / Ln
        alpha = math.atan2(c0[e] * s - s0[e] * c, c0[e] * c + s0[e] * s)
        ul = (Ln * Ln - L * L) / (Ln + L)
        t1 = u[i0 + 2] - alpha
        t2 = u[i0 + 5] - alpha
        dvx = v[i0 + 3] - v[i0]
        dvy = v[i0 + 4] - v[i0 + 1]
        qd0 = c * dvx + s * dvy
        zd = (s * dvx - c * dvy) / Ln  # z . v / Ln, z = (s, -c, 0, -s, c, 0)
        qd1 = v[i0 + 2] + zd
        qd2 = v[i0 + 5] + zd
        if shallow:
            # total end rotations (reference curvature + deformation): stress-free bow
            T1 = t0[e, 0] + t1
            T2 = t0[e, 1] + t2
            a1 = (4.0 * T1 - T2) / 30.0
            a2 = (-T1 + 4.0 * T2) / 30.0
            eps = ul / L + (_arch(T1, T2) - _arch(t0[e, 0], t0[e, 1])) / 30.0
        else:
            a1 = 0.0
            a2 = 0.0
            eps = ul / L
        kb = EI / L
        Nt = EA * eps + beta * EA * (qd0 / L + a1 * qd1 + a2 * qd2)
        f1 = kb * (4.0 * t1 + 2.0 * t2) + beta * kb * (4.0 * qd1 + 2.0 * qd2) + Nt * L * a1
        f2 = kb * (2.0 * t1 + 4.0 * t2) + beta * kb * (2.0 * qd1 + 4.0 * qd2) + Nt * L * a2
        # f_global = r Nt - z (f1 + f2) / Ln + e3 f1 + e6 f2
        fm = (f1 + f2) / Ln
        fint[i0] += -c * Nt - s * fm
        fint[i0 + 1] += -s * Nt + c * fm
        fint[i0 + 2] += f1
        fint[i0 + 3] += c * Nt + s * fm
        fint[i0 + 4] += s * Nt - c * fm
        fint[i0 + 5] += f2
    for j in range(d_dof.shape[0]):
        d = d_dof[j]
        law = d_law[j]
        if law == LAW_SPRING:
            fint[d] += d_p1[j] * u[d]
        elif law == LAW_DAMPER:
            fint[d] += d_p1[j] * v[d]
        elif law == LAW_QUADRATIC_DAMPER:
            fint[d] += d_p1[j] * abs(v[d]) * v[d]
        else:
            fint[d] += d_p1[j] * math.tanh(v[d] / d_p2[j])


@njit(cache=True)
def assemble(elements, discrete, u, v, fint, want_k, kfac, cfac, band, kd):
    """Internal force (elastic + viscous + discrete elements) into ``fint``;
    if ``want_k``, adds kfac * (K + cfac * C) into ``band`` (half-bandwidth ``kd``).

    K is d fint / d u (consistent, including the viscous force's dependence on
    the co-rotational frame), C is d fint / d v.
    """
    X, Y, L0, c0, s0, t0, EA, EI, beta, shallow = elements
    d_dof, d_law, d_p1, d_p2 = discrete
    ne = L0.shape[0]
    fint[:] = 0.0
    B = np.empty((3, 6))
    Kl = np.empty((3, 3))
    BK = np.empty((3, 6))
    r = np.empty(6)
    z = np.empty(6)
    fg = np.empty(6)
    ke = np.empty((6, 6))
    for e in range(ne):
        i0 = 3 * e
        L = L0[e]
        dx = X[e + 1] - X[e] + u[i0 + 3] - u[i0]
        dy = Y[e + 1] - Y[e] + u[i0 + 4] - u[i0 + 1]
        Ln = math.sqrt(dx * dx + dy * dy)
        c = dx / Ln
        s = dy / Ln
        alpha = math.atan2(c0[e] * s - s0[e] * c, c0[e] * c + s0[e] * s)
        ul = (Ln * Ln - L * L) / (Ln + L)
        t1 = u[i0 + 2] - alpha
        t2 = u[i0 + 5] - alpha
        r[0] = -c
        r[1] = -s
        r[2] = 0.0
        r[3] = c
        r[4] = s
        r[5] = 0.0
        z[0] = s
        z[1] = -c
        z[2] = 0.0
        z[3] = -s
        z[4] = c
        z[5] = 0.0
        # local deformation rates
        qd0 = 0.0
        zd = 0.0
        for k in range(6):
            qd0 += r[k] * v[i0 + k]
            zd += z[k] * v[i0 + k]
        zd /= Ln
        qd1 = v[i0 + 2] - zd
        qd2 = v[i0 + 5] - zd
        a0 = 1.0 / L
        if shallow:
            # total end rotations (reference curvature + deformation): stress-free bow
            T1 = t0[e, 0] + t1
            T2 = t0[e, 1] + t2
            a1 = (4.0 * T1 - T2) / 30.0
            a2 = (-T1 + 4.0 * T2) / 30.0
            eps = ul / L + (_arch(T1, T2) - _arch(t0[e, 0], t0[e, 1])) / 30.0
        else:
            a1 = 0.0
            a2 = 0.0
            eps = ul / L
        kb = EI / L
        N = EA * eps
        epsd = a0 * qd0 + a1 * qd1 + a2 * qd2
        Nv = beta * EA * epsd
        Nt = N + Nv
        f0 = Nt
        f1 = kb * (4.0 * t1 + 2.0 * t2) + beta * kb * (4.0 * qd1 + 2.0 * qd2) + Nt * L * a1
        f2 = kb * (2.0 * t1 + 4.0 * t2) + beta * kb * (2.0 * qd1 + 4.0 * qd2) + Nt * L * a2
        for k in range(6):
            B[0, k] = r[k]
            B[1, k] = -z[k] / Ln
            B[2, k] = -z[k] / Ln
        B[1, 2] += 1.0
        B[2, 5] += 1.0
        for k in range(6):
            fg[k] = B[0, k] * f0 + B[1, k] * f1 + B[2, k] * f2
            fint[i0 + k] += fg[k]
        if want_k:
            # local material matrix (also the viscous matrix up to beta)
            eal = EA * L
            m00 = eal * a0 * a0
            m01 = eal * a0 * a1
            m02 = eal * a0 * a2
            m11 = eal * a1 * a1 + 4.0 * kb
            m12 = eal * a1 * a2 + 2.0 * kb
            m22 = eal * a2 * a2 + 4.0 * kb
            sk = 1.0 + cfac * beta
            Kl[0, 0] = sk * m00
            Kl[0, 1] = sk * m01
            Kl[0, 2] = sk * m02
            Kl[1, 0] = sk * m01
            Kl[1, 1] = sk * m11
            Kl[1, 2] = sk * m12
            Kl[2, 0] = sk * m02
            Kl[2, 1] = sk * m12
            Kl[2, 2] = sk * m22
            if shallow:
                # geometric part from the total (elastic + viscous) axial force
                g = Nt * L / 30.0
                Kl[1, 1] += 4.0 * g
                Kl[1, 2] -= g
                Kl[2, 1] -= g
                Kl[2, 2] += 4.0 * g
                # viscous force's dependence on the rotations through a(t)
                bq1 = beta * eal * (4.0 * qd1 - qd2) / 30.0
                bq2 = beta * eal * (-qd1 + 4.0 * qd2) / 30.0
                Kl[0, 1] += a0 * bq1
                Kl[0, 2] += a0 * bq2
                Kl[1, 1] += a1 * bq1
                Kl[1, 2] += a1 * bq2
                Kl[2, 1] += a2 * bq1
                Kl[2, 2] += a2 * bq2
            for i in range(3):
                for k in range(6):
                    BK[i, k] = Kl[i, 0] * B[0, k] + Kl[i, 1] * B[1, k] + Kl[i, 2] * B[2, k]
            if beta > 0.0:
                # the local rates q_dot = B(u) v also depend on u (the frame turns):
                # d q_dot0 = (z.v) z.du / Ln, d q_dot1,2 = ((r.v) z + (z.v) r).du / Ln^2
                zv = zd * Ln
                rv = qd0
                for k in range(6):
                    g0 = zv * z[k] / Ln
                    g12 = (rv * z[k] + zv * r[k]) / (Ln * Ln)
                    for i in range(3):
                        m0 = m00 if i == 0 else (m01 if i == 1 else m02)
                        m1 = m01 if i == 0 else (m11 if i == 1 else m12)
                        m2 = m02 if i == 0 else (m12 if i == 1 else m22)
                        BK[i, k] += beta * (m0 * g0 + (m1 + m2) * g12)
            fz = f0 / Ln
            fm = (f1 + f2) / (Ln * Ln)
            for i in range(6):
                for k in range(6):
                    ke[i, k] = (
                        B[0, i] * BK[0, k]
                        + B[1, i] * BK[1, k]
                        + B[2, i] * BK[2, k]
                        + fz * z[i] * z[k]
                        + fm * (r[i] * z[k] + z[i] * r[k])
                    )
            for i in range(6):
                gi = i0 + i
                for k in range(6):
                    band[gi, kd + k - i] += kfac * ke[i, k]
    # discrete elements (boundary spring/damper, effects)
    for j in range(d_dof.shape[0]):
        d = d_dof[j]
        law = d_law[j]
        p1 = d_p1[j]
        if law == LAW_SPRING:
            fint[d] += p1 * u[d]
            kk = p1
        elif law == LAW_DAMPER:
            fint[d] += p1 * v[d]
            kk = cfac * p1
        elif law == LAW_QUADRATIC_DAMPER:
            fint[d] += p1 * abs(v[d]) * v[d]
            kk = cfac * 2.0 * p1 * abs(v[d])
        else:  # LAW_COULOMB
            th = math.tanh(v[d] / d_p2[j])
            fint[d] += p1 * th
            kk = cfac * p1 / d_p2[j] * (1.0 - th * th)
        if want_k:
            band[d, kd] += kfac * kk


@njit(cache=True)
def strain_energy(elements, discrete, u):
    """Elastic energy of the beam elements and the discrete springs [J]."""
    X, Y, L0, c0, s0, t0, EA, EI, _, shallow = elements
    d_dof, d_law, d_p1, _ = discrete
    ne = L0.shape[0]
    energy = 0.0
    for e in range(ne):
        i0 = 3 * e
        L = L0[e]
        dx = X[e + 1] - X[e] + u[i0 + 3] - u[i0]
        dy = Y[e + 1] - Y[e] + u[i0 + 4] - u[i0 + 1]
        Ln = math.sqrt(dx * dx + dy * dy)
        c = dx / Ln
        s = dy / Ln
        alpha = math.atan2(c0[e] * s - s0[e] * c, c0[e] * c + s0[e] * s)
        ul = (Ln * Ln - L * L) / (Ln + L)
        t1 = u[i0 + 2] - alpha
        t2 = u[i0 + 5] - alpha
        eps = ul / L
        if shallow:
            eps += (_arch(t0[e, 0] + t1, t0[e, 1] + t2) - _arch(t0[e, 0], t0[e, 1])) / 30.0
        energy += 0.5 * EA * L * eps * eps + EI / L * (2.0 * t1 * t1 + 2.0 * t1 * t2 + 2.0 * t2 * t2)
    for j in range(d_dof.shape[0]):
        if d_law[j] == LAW_SPRING:
            energy += 0.5 * d_p1[j] * u[d_dof[j]] ** 2
    return energy
