"""What a model of the rig returns and how it fails: the result records
(:class:`StaticState`, :class:`Modes`, :class:`SimulationResult`) and the errors
(:class:`BucklingError` with its check :func:`check_below_buckling`,
:class:`ConvergenceError`).

Apart from the models because both :class:`fe.BeamModel` and :class:`fe.ModalROM`
return and raise them (:class:`SimulationResult` is the result of any model of
the rig, see :func:`fe.simulate`); re-exported by :mod:`fe.model`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rig import Parameters, Rig


class BucklingError(ValueError):
    """The preload is at or beyond the beam's buckling load."""


def check_below_buckling(params: Parameters, rig: Rig, p_cr: float) -> float:
    """P_eff [N] of ``params``; raises BucklingError at or beyond ``p_cr`` [N]."""
    p_eff = params.effective_preload(rig)
    if p_eff >= p_cr:
        raise BucklingError(
            f"the preload is at or beyond buckling: P_eff = F K_b / (K_b + k_s) = {p_eff:.2f} N "
            f">= buckling load {p_cr:.2f} N of this beam (F = {params.F} N, k_s = {params.k_s} N/m); "
            "lower F or raise k_s"
        )
    return p_eff


class ConvergenceError(RuntimeError):
    """Newton's method failed; the message names the time step."""


@dataclass(frozen=True)
class StaticState:
    """Preloaded equilibrium: displacements u [m, rad], beam axial force [N]."""

    u: np.ndarray
    axial_force: float
    top_displacement: float


@dataclass(frozen=True)
class Modes:
    """Linearised modes about the preloaded equilibrium.

    frequencies_hz: undamped natural frequencies; damping_ratios: from the
    complex eigenvalues of the damped linearisation; shapes: (n_dof, n_modes)
    mass-normalised; node_x: node positions [m].
    """

    frequencies_hz: np.ndarray
    damping_ratios: np.ndarray
    shapes: np.ndarray
    node_x: np.ndarray

    def transverse(self, mode: int) -> np.ndarray:
        """Transverse nodal displacements of one mode (index from 0)."""
        return self.shapes[1::3, mode]


@dataclass
class SimulationResult:
    """Time histories at the output positions (SI units).

    displacement, velocity: transverse, shape (n_samples, n_positions);
    axial_top: axial displacement of the top [m] (negative = shortening).
    Displacements are measured from the unloaded reference configuration.
    final_displacement, final_velocity: the full dof vectors at the last sample.
    """

    time: np.ndarray
    force: np.ndarray
    positions: np.ndarray
    displacement: np.ndarray
    velocity: np.ndarray
    axial_top: np.ndarray
    newton_iterations: int = 0
    final_displacement: np.ndarray | None = None
    final_velocity: np.ndarray | None = None

    @property
    def sensor_velocity(self) -> np.ndarray:
        """Transverse velocity at the first output position (the sensor) [m/s]."""
        return self.velocity[:, 0]

    @property
    def sensor_displacement(self) -> np.ndarray:
        """Transverse displacement at the first output position [m]."""
        return self.displacement[:, 0]
