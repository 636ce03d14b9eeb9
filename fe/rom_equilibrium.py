"""The modal ROM's static state and the linear analysis about it: :class:`ROMState`,
the static Newton solve of the modal equations and the linear FRF, mixed into
:class:`fe.ModalROM` by :class:`ROMEquilibrium`.

Apart from :mod:`fe.rom` as :mod:`fe.equilibrium` is apart from :mod:`fe.model`:
the static state and its linearisation, on the reduced matrices of
:mod:`fe.rom_basis`, are not the time integration.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .results import BucklingError, ConvergenceError
from .rig import Parameters


@dataclass(frozen=True)
class ROMState:
    """Static state of the ROM.

    q: modal coordinates; top_displacement [m] (negative = shortening);
    shortening [m]: s drawn in by the bending (and the bow); axial_force [N]:
    beam compression (positive in compression), as
    :class:`fe.StaticState`.
    """

    q: np.ndarray
    top_displacement: float
    shortening: float
    axial_force: float


class ROMEquilibrium:
    """Statics and the linear FRF of :class:`fe.ModalROM` (mixed into it; uses the
    model's ``rig``, ``n_modes``, ``reduced`` and ``_output_weights``)."""

    # ------------------------------------------------------------------ statics
    def static_equilibrium(self, params: Parameters, shaker_force: float = 0.0) -> ROMState:
        """Static state under the preload and a constant shaker force [N].

        Newton on the modal equations with the top eliminated
        (N = -P_eff + K_eff s, K_eff = K_b k_s / (K_b + k_s)), from the linear
        solution.  Raises BucklingError if P_eff reaches the buckling load or
        the tangent is not positive definite at the solution.
        """
        red = self.reduced(params)
        kb = self.rig.axial_stiffness
        ktop = kb + params.k_s
        k_eff = kb * params.k_s / ktop
        p_eff = red.p_eff
        G, g0 = red.G, red.g0
        shaker_force = float(shaker_force)
        if not math.isfinite(shaker_force):
            raise ValueError(f"shaker_force must be finite, got {shaker_force}")
        f = red.b * shaker_force
        if not (np.any(f) or np.any(g0)):
            # straight and unloaded: q = 0, stable since P_eff < P_cr (omega^2 > 0)
            return ROMState(
                q=np.zeros(self.n_modes), top_displacement=-params.F / ktop, shortening=0.0, axial_force=p_eff
            )
        K0 = np.diag(red.kappa)
        q = np.linalg.solve(K0 - p_eff * G, f + p_eff * g0)
        for _ in range(50):
            a = G @ q + g0
            N = -p_eff + k_eff * (0.5 * q @ G @ q + g0 @ q)
            elastic = K0 @ q
            res = f - elastic - N * a
            # relative to the largest term: near buckling K0 q >> f
            scale = np.linalg.norm(f) + p_eff * np.linalg.norm(g0) + np.linalg.norm(elastic)
            if np.linalg.norm(res) <= 1e-12 * scale:
                break
            q = q + np.linalg.solve(K0 + N * G + k_eff * np.outer(a, a), res)
        else:
            raise ConvergenceError(
                "static Newton solve of the ROM did not converge "
                f"(shaker force {shaker_force} N, P_eff = {p_eff:.2f} N)"
            )
        a = G @ q + g0
        s = 0.5 * q @ G @ q + g0 @ q
        N = -p_eff + k_eff * s
        try:
            np.linalg.cholesky(np.diag(red.kappa) + N * G + k_eff * np.outer(a, a))
        except np.linalg.LinAlgError:
            raise BucklingError(
                f"the static state of the ROM is unstable (tangent not positive definite) at P_eff = {p_eff:.2f} N"
            ) from None
        U = (-params.F - kb * s) / ktop
        return ROMState(q=q, top_displacement=float(U), shortening=float(s), axial_force=float(-N))

    # ------------------------------------------------------------------ linear
    def linear_frf(
        self, params: Parameters, freqs_hz, position: float | None = None, quantity: str = "velocity"
    ) -> np.ndarray:
        """FRF of the ROM linearised about its static state, from the shaker
        force to the transverse response at ``position`` (default: the sensor)
        [m/N or m/s/N].  Includes the top's dynamics (which enter at first
        order only with a bow)."""
        if quantity not in ("displacement", "velocity"):
            raise ValueError("quantity must be 'displacement' or 'velocity'")
        red = self.reduced(params)
        st = self.static_equilibrium(params)
        rig = self.rig
        kb = rig.axial_stiffness
        beta = rig.beam_viscosity(params.eta) / rig.youngs_modulus_pa
        ktop, dtop = kb + params.k_s, params.c + beta * kb
        a = red.G @ st.q + red.g0
        pos = rig.sensor_position_m if position is None else position
        out = self._output_weights(red, np.atleast_1d(np.asarray(pos, float)))[0]
        h = []
        for f in np.atleast_1d(np.asarray(freqs_hz, float)):
            om = 2 * np.pi * f
            # dN = kappa ds from the linearised top (k_s, c against K_b, beta K_b)
            kappa = (params.k_s + 1j * om * params.c) * kb * (1 + 1j * om * beta) / (ktop + 1j * om * dtop)
            dyn = (
                np.diag(red.kappa * (1 + 1j * om * beta))
                - st.axial_force * red.G
                + kappa * np.outer(a, a)
                - om**2 * np.eye(self.n_modes)
            )
            val = out @ np.linalg.solve(dyn, red.b)
            h.append(val * (1j * om if quantity == "velocity" else 1.0))
        return np.array(h)
