"""The preloaded equilibrium of :class:`fe.BeamModel` and the linear analyses about
it: the linear buckling load, the static Newton solve, the modes and the linear FRF.

Apart from :mod:`fe.model` because these analyses solve the assembled system
rather than build it: the model assembles, :class:`BeamEquilibrium` (mixed into
:class:`fe.BeamModel`) finds its static state and linearises about it.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np
import scipy.linalg

from . import _kernels as K
from ._banded import band_to_dense
from .mesh import KD, hermite_weights
from .results import BucklingError, ConvergenceError, Modes, StaticState, check_below_buckling
from .rig import Parameters


class BeamEquilibrium:
    """Statics and linear analyses of :class:`fe.BeamModel` (mixed into it; uses the
    model's settings, ``describe``, ``_arrays`` and ``matrices``)."""

    # ------------------------------------------------------------------ statics
    def buckling_load(self) -> float:
        """Linear buckling load of the straight beam, as beam axial force [N].

        From K_0 phi = P K_g phi with K_g the geometric stiffness per newton of
        compression (effects other than the geometry are included).
        """
        return self._buckling_load

    @cached_property
    def _buckling_load(self) -> float:
        params = Parameters(eta=0.0, c=0.0, F=0.0, k_s=0.0)
        system = self.describe(params)
        system.node_y = np.zeros_like(system.node_y)  # perfect geometry
        system.node_theta = None
        a = self._arrays(system, params)
        n = system.n_dof
        free = ~a["fixed"]

        def stiffness(p):
            u = np.zeros(n)
            u[0::3] = -p * self.node_x / self.rig.EA  # uniform compression by p
            band = np.zeros((n, 2 * KD + 1))
            fint = np.empty(n)
            K.assemble(a["elements"], a["discrete"], u, np.zeros(n), fint, True, 1.0, 0.0, band, KD)
            return band_to_dense(band, KD)[np.ix_(free, free)]

        p_ref = 1.0
        k0 = stiffness(0.0)
        kg = (k0 - stiffness(p_ref)) / p_ref
        mu = scipy.linalg.eigvals(kg, k0)
        mu = mu.real[np.abs(mu.imag) < 1e-9 * np.abs(mu).max()]
        return float(1.0 / mu.max())

    def static_equilibrium(self, params: Parameters) -> StaticState:
        """Newton solve of the preloaded equilibrium (no shaker force).

        Raises BucklingError when P_eff = F K_b/(K_b + k_s) reaches the buckling
        load or the tangent is not positive definite at the solution.
        """
        p_eff = check_below_buckling(params, self.rig, self.buckling_load())
        p_cr = self.buckling_load()
        system = self.describe(params)
        a = self._arrays(system, params)
        n = system.n_dof
        u = np.zeros(n)
        tol = self.newton_rtol * params.F + self._roundoff_force
        n_inc = 1 if not self.effects else 10
        status, _ = K.static_newton(a["elements"], a["discrete"], a["fixed"], a["f_const"], u, KD, n_inc, tol, 50)
        if status != 0:
            raise ConvergenceError(
                f"static Newton solve of the preloaded equilibrium failed (status {status}) at "
                f"F = {params.F} N; the preload may be too close to buckling ({p_eff:.2f} of {p_cr:.2f} N)"
            )
        _, kt, _, fint = self.matrices(params, u)
        free = ~a["fixed"]
        try:
            np.linalg.cholesky(kt[np.ix_(free, free)])
        except np.linalg.LinAlgError:
            raise BucklingError(
                f"the preloaded equilibrium is unstable (tangent not positive definite) at "
                f"P_eff = {p_eff:.2f} N, buckling load {p_cr:.2f} N"
            ) from None
        return StaticState(
            u=u, axial_force=float(_beam_axial_force(self, u, a)), top_displacement=float(u[self.top_axial_dof])
        )

    # ------------------------------------------------------------------ linear
    def modal_analysis(self, params: Parameters, n_modes: int = 6) -> Modes:
        """Modes of the model linearised about the preloaded equilibrium."""
        state = self.static_equilibrium(params)
        m, kt, c, _ = self.matrices(params, state.u)
        free = ~self.describe(params).fixed
        mf, kf, cf = (x[np.ix_(free, free)] for x in (m, kt, c))
        n_free = mf.shape[0]
        if not 1 <= n_modes <= n_free:
            raise ValueError(f"n_modes must lie in [1, {n_free}] for this mesh, got {n_modes}")
        w2, phi = scipy.linalg.eigh(kf, mf)
        order = np.argsort(w2)[:n_modes]
        w2, phi = w2[order], phi[:, order]
        omega = np.sqrt(np.maximum(w2, 0.0))
        # damping ratios from the state-space eigenvalues closest to each mode
        a = np.block(
            [[np.zeros((n_free, n_free)), np.eye(n_free)], [-np.linalg.solve(mf, kf), -np.linalg.solve(mf, cf)]]
        )
        lam = np.linalg.eigvals(a)
        lam = lam[lam.imag > 0]
        zeta = np.empty(n_modes)
        for i, w in enumerate(omega):
            j = np.argmin(np.abs(np.abs(lam) - w))
            zeta[i] = -lam[j].real / abs(lam[j])
        shapes = np.zeros((self.n_dof, n_modes))
        shapes[free] = phi
        return Modes(frequencies_hz=omega / (2 * np.pi), damping_ratios=zeta, shapes=shapes, node_x=self.node_x.copy())

    def linear_frf(
        self, params: Parameters, freqs_hz, position: float | None = None, quantity: str = "velocity"
    ) -> np.ndarray:
        """FRF of the linearised model from the shaker force to the transverse
        response at ``position`` (default: the sensor) [m/N or m/s/N]."""
        if quantity not in ("displacement", "velocity"):
            raise ValueError("quantity must be 'displacement' or 'velocity'")
        state = self.static_equilibrium(params)
        m, kt, c, _ = self.matrices(params, state.u)
        system = self.describe(params)
        free = ~system.fixed
        mf, kf, cf = (x[np.ix_(free, free)] for x in (m, kt, c))
        b = system.b_load[free]
        pos = self.rig.sensor_position_m if position is None else position
        w_out = hermite_weights(self.node_x, pos)[free]
        out = []
        for f in np.atleast_1d(freqs_hz):
            om = 2 * np.pi * f
            h = w_out @ np.linalg.solve(kf - om**2 * mf + 1j * om * cf, b)
            out.append(h * (1j * om if quantity == "velocity" else 1.0))
        return np.array(out)


def _beam_axial_force(model: BeamEquilibrium, u: np.ndarray, a: dict) -> float:
    """Compressive axial force carried by the top element [N] (positive in compression)."""
    e = a["L0"].size - 1
    i0 = 3 * e
    dx = a["X"][e + 1] - a["X"][e] + u[i0 + 3] - u[i0]
    dy = a["Y"][e + 1] - a["Y"][e] + u[i0 + 4] - u[i0 + 1]
    ln = math.hypot(dx, dy)
    return -model.rig.EA * (ln - a["L0"][e]) / a["L0"][e]
