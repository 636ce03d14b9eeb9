"""Numba kernels of the co-rotational beam: the static Newton and the
generalized-alpha transient, on the element of :mod:`fe._beam_element` (whose
kernels and discrete-element laws are re-exported here: ``fe._kernels`` is the
one namespace of the compiled beam).

Private: use :class:`fe.BeamModel`.  Conventions (dofs, elements) and the
element's formulation: :mod:`fe._beam_element`.
"""

import numpy as np
from numba import njit

from ._banded import band_lu, band_matvec, band_solve
from ._beam_element import (  # noqa: F401  (the element's kernels and laws, re-exported)
    LAW_COULOMB,
    LAW_DAMPER,
    LAW_QUADRATIC_DAMPER,
    LAW_SPRING,
    assemble,
    internal_force,
    strain_energy,
)


@njit(cache=True)
def apply_dirichlet(band, kd, fixed):
    """Replace the rows and columns of fixed dofs by the identity."""
    n = band.shape[0]
    for i in range(n):
        if fixed[i]:
            for j in range(max(0, i - kd), min(n, i + kd + 1)):
                band[i, kd + j - i] = 0.0
                band[j, kd + i - j] = 0.0
            band[i, kd] = 1.0


@njit(cache=True)
def static_newton(elements, discrete, fixed, f_ext, u, kd, n_increments, tol, max_iter):
    """Static equilibrium f_int(u) = f_ext by Newton with load increments (``elements``,
    ``discrete``: :mod:`fe._beam_element`; the viscosity plays no part).

    ``u`` is the start (modified in place).  Returns (status, iterations):
    status 0 converged, 1 no convergence, 2 singular tangent.
    """
    X, Y, L0, c0, s0, t0, EA, EI, _, shallow = elements
    elastic = (X, Y, L0, c0, s0, t0, EA, EI, 0.0, shallow)
    n = u.shape[0]
    v = np.zeros(n)
    fint = np.empty(n)
    res = np.empty(n)
    band = np.empty((n, 2 * kd + 1))
    total = 0
    for inc in range(1, n_increments + 1):
        lam = inc / n_increments
        converged = False
        for it in range(max_iter):
            band[:, :] = 0.0
            assemble(elastic, discrete, u, v, fint, True, 1.0, 0.0, band, kd)
            rmax = 0.0
            for i in range(n):
                res[i] = 0.0 if fixed[i] else lam * f_ext[i] - fint[i]
                rmax = max(rmax, abs(res[i]))
            total += 1
            if rmax < tol:
                converged = True
                break
            apply_dirichlet(band, kd, fixed)
            if band_lu(band, kd) >= 0:
                return 2, total
            band_solve(band, kd, res)
            for i in range(n):
                u[i] += res[i]
        if not converged:
            return 1, total
    return 0, total


@njit(cache=True, error_model="numpy")
def transient(elements, discrete, fixed, m_band, loads, substeps, scheme, u, v, newton, W, axial_dof, outputs):
    """Generalized-alpha (Chung and Hulbert 1993) transient, the paper's eq. 4-10
    (inertia and internal/external forces weighted by alpha_m, alpha_f).

    ``elements``, ``discrete``: the beam (:mod:`fe._beam_element`); ``fixed`` the
    fixed dofs, ``m_band`` the banded mass; ``loads = (f_const, b_load, force)``:
    the constant load, the shaker's load vector and the force samples ``force``
    (one per output sample, spacing ``substeps * dt``), interpolated linearly
    within a sample interval; ``scheme = (dt, alpha_m, alpha_f, gamma, beta_n)``;
    ``newton = (tol, max_iter)``.  ``u, v`` are the initial state (modified in
    place; the final state on return).  ``outputs = (out_disp, out_vel,
    out_axial)`` receive at every sample W @ u, W @ v and u[axial_dof].

    Newton with the consistent tangent, refactored whenever the residual has not
    dropped tenfold since the last iteration (else the factors are reused).
    Returns (status, failed_sample, iterations): status 0 ok, 1 no convergence,
    2 singular Newton matrix.
    """
    f_const, b_load, force = loads
    dt, alpha_m, alpha_f, gamma, beta_n = scheme
    tol, max_iter = newton
    out_disp, out_vel, out_axial = outputs
    n = u.shape[0]
    kd = m_band.shape[1] // 2
    ns = force.shape[0]
    nout = W.shape[0]
    mfac = (1.0 - alpha_m) / (beta_n * dt * dt)
    cfac = gamma / (beta_n * dt)
    kfac = 1.0 - alpha_f
    a = np.zeros(n)
    fint = np.empty(n)
    fint_old = np.empty(n)
    fext = np.empty(n)
    res = np.empty(n)
    ma = np.empty(n)
    u_new = np.empty(n)
    v_new = np.empty(n)
    a_new = np.empty(n)
    atmp = np.empty(n)
    band = np.empty((n, 2 * kd + 1))
    # initial acceleration: M a0 = f_ext(0) - f_int(u0, v0)
    internal_force(elements, discrete, u, v, fint_old)
    for i in range(n):
        a[i] = 0.0 if fixed[i] else f_const[i] + b_load[i] * force[0] - fint_old[i]
    band[:, :] = m_band
    apply_dirichlet(band, kd, fixed)
    if band_lu(band, kd) >= 0:
        return 2, 0, 0
    band_solve(band, kd, a)
    have_factors = False
    iterations = 0
    for o in range(nout):
        s = 0.0
        sv = 0.0
        for i in range(n):
            s += W[o, i] * u[i]
            sv += W[o, i] * v[i]
        out_disp[0, o] = s
        out_vel[0, o] = sv
    out_axial[0] = u[axial_dof]
    for k in range(ns - 1):
        f0 = force[k]
        df = force[k + 1] - force[k]
        for sub in range(substeps):
            fload = f0 + df * (sub + 1.0 - alpha_f) / substeps
            for i in range(n):
                fext[i] = f_const[i] + b_load[i] * fload
                u_new[i] = u[i] + dt * v[i] + 0.5 * dt * dt * a[i]
            converged = False
            last = 1e300
            for it in range(max_iter):
                for i in range(n):
                    a_new[i] = (u_new[i] - u[i] - dt * v[i] - dt * dt * (0.5 - beta_n) * a[i]) / (beta_n * dt * dt)
                    v_new[i] = v[i] + dt * ((1.0 - gamma) * a[i] + gamma * a_new[i])
                    atmp[i] = (1.0 - alpha_m) * a_new[i] + alpha_m * a[i]
                internal_force(elements, discrete, u_new, v_new, fint)
                band_matvec(m_band, kd, atmp, ma)
                rmax = 0.0
                for i in range(n):
                    if fixed[i]:
                        res[i] = 0.0
                    else:
                        res[i] = fext[i] - ma[i] - kfac * fint[i] - alpha_f * fint_old[i]
                        rmax = max(rmax, abs(res[i]))
                iterations += 1
                # at least one correction: a predictor that happens to lie within
                # the tolerance would otherwise be accepted, and such steps add
                # up at small shaker forces (the tolerance scales with F)
                if rmax < tol and it > 0:
                    converged = True
                    break
                if not (rmax == rmax):
                    break
                if (not have_factors) or rmax > 0.1 * last:
                    band[:, :] = 0.0
                    for i in range(n):
                        for j in range(2 * kd + 1):
                            band[i, j] = mfac * m_band[i, j]
                    assemble(elements, discrete, u_new, v_new, fint, True, kfac, cfac, band, kd)
                    apply_dirichlet(band, kd, fixed)
                    if band_lu(band, kd) >= 0:
                        return 2, k + 1, iterations
                    have_factors = True
                last = rmax
                band_solve(band, kd, res)
                for i in range(n):
                    u_new[i] += res[i]
            if not converged:
                return 1, k + 1, iterations
            for i in range(n):
                u[i] = u_new[i]
                v[i] = v_new[i]
                a[i] = a_new[i]
                fint_old[i] = fint[i]
        for o in range(nout):
            s = 0.0
            sv = 0.0
            for i in range(n):
                s += W[o, i] * u[i]
                sv += W[o, i] * v[i]
            out_disp[k + 1, o] = s
            out_vel[k + 1, o] = sv
        out_axial[k + 1] = u[axial_dof]
    return 0, 0, iterations
