"""Effects: named, parameterised extensions of the beam model.

An effect edits the :class:`fe.model.SystemDescription` (geometry, point
masses, discrete springs/dampers, boundary conditions) before it is turned
into the arrays the numba kernels integrate, so new physics never touches the
element core.  Each effect documents its physical origin and the signature it
leaves in the data; the discrepancy workflow relies on both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .system import DiscreteElement


class Effect:
    """Base class.  Subclasses are frozen dataclasses with SI parameters."""

    name: ClassVar[str] = "effect"

    def apply(self, system, rig, params) -> None:  # pragma: no cover - interface
        raise NotImplementedError

    def parameters(self) -> dict:
        """The effect's own parameters (SI), for reports."""
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class InitialImperfection(Effect):
    """Initial bow of the unloaded beam, in the shape of the first buckling mode.

    Physical origin: a real strip is never straight; rolling, clamping and the
    preload screw leave a bow of a fraction of a millimetre.  The bow follows the
    first buckling mode of the clamped-guided beam,
    w0(x) = amplitude * (1 - cos(2 pi x / L)) / 2, with ``amplitude`` [m] at
    mid-span (sign: towards +y, the shaker's direction).

    Signature in the data: the preload amplifies the bow by 1 / (1 - P/P_cr);
    the bowed beam is no longer symmetric, so even-order kernels appear (a
    non-zero y2 and 2x harmonics in the sine tests), and the linear frequency
    rises slightly (the axial force now also stretches the bow).
    """

    amplitude: float = 0.0  # m

    name: ClassVar[str] = "initial_imperfection"

    def __post_init__(self):
        if not math.isfinite(self.amplitude):
            raise ValueError(f"initial_imperfection amplitude must be finite, got {self.amplitude}")

    def shape(self, x: np.ndarray, length: float) -> np.ndarray:
        """Initial transverse offset w0(x) [m] at axial positions x [m]."""
        return self.amplitude * 0.5 * (1.0 - np.cos(2.0 * np.pi * np.asarray(x) / length))

    def slope(self, x: np.ndarray, length: float) -> np.ndarray:
        """dw0/dx [-] at axial positions x [m]."""
        return self.amplitude * np.pi / length * np.sin(2.0 * np.pi * np.asarray(x) / length)

    def apply(self, system, rig, params) -> None:
        # offsets and slopes at the nodes: the elements follow the bow as cubics
        # (O(h^4)), not as chords between bowed nodes (O(h^2))
        x = system.node_x
        theta = np.zeros_like(x) if system.node_theta is None else system.node_theta  # straight beam along x
        system.node_y = system.node_y + self.shape(x, rig.length_m)
        system.node_theta = theta + np.arctan(self.slope(x, rig.length_m))


def _shaker_dof(system) -> int:
    """Transverse dof of the node at the shaker (the model puts a node there)."""
    return int(np.argmax(np.abs(system.b_load)))


def _check_non_negative(name, **values):
    for k, v in values.items():
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"{name} {k} must be a finite non-negative number, got {v}")


@dataclass(frozen=True)
class ShakerAttachment(Effect):
    """Moving mass and transverse stiffness of the stinger, load cell and shaker
    armature at the excitation point.

    Physical origin: the load cell measures the force *into* the beam, but
    everything between it and the beam (the load cell's top half, the stud,
    part of the stinger) moves with the beam, and the stinger and the shaker's
    suspension resist transverse motion.  ``mass`` [kg] is added at the
    shaker's node, ``stiffness`` [N/m] ties it to ground.

    Signature in the data: linear, so it survives into the low-level test; a
    mass lowers and a spring raises each mode by an amount that depends on the
    mode shape at 65 mm from the clamp, so the ratios of the modal frequencies
    (f2/f1, f3/f1) move in a way no preload can reproduce, and the FRF's
    anti-resonances shift.
    """

    mass: float = 0.0  # kg
    stiffness: float = 0.0  # N/m

    name: ClassVar[str] = "shaker_attachment"

    def __post_init__(self):
        _check_non_negative("shaker_attachment", mass=self.mass, stiffness=self.stiffness)

    def apply(self, system, rig, params) -> None:

        dof = _shaker_dof(system)
        if self.mass > 0:
            system.point_masses.append((dof, self.mass))
        if self.stiffness > 0:
            system.discrete.append(DiscreteElement(dof, "spring", self.stiffness))


@dataclass(frozen=True)
class ClampCompliance(Effect):
    """A rotational spring at the bottom clamp instead of a rigid clamp.

    Physical origin: a clamp holds the strip by friction between two blocks
    tightened by bolts; the blocks, the bolts and the strip's surface layer
    give way a little, so the clamped end rotates under moment.  The bottom
    node's rotation is freed and tied to ground by ``stiffness`` [N m/rad]
    (EI/L = 0.58 N m/rad for the default strip: a clamp stiffness of 100 EI/L
    is a good clamp).

    Signature in the data: the boundary softens, all modes drop, the first
    buckling load falls (so the same preload carries the beam closer to
    buckling: the frequency drops more than the modal mass alone would say),
    and the mode shapes' curvature near the clamp changes.  Linear, so it is
    in the low-level test, and partly absorbed by P_eff: the tell-tale is the
    frequency ratios and the buckling margin.
    """

    stiffness: float = math.inf  # N m/rad

    name: ClassVar[str] = "clamp_compliance"

    def __post_init__(self):
        if not (self.stiffness > 0):
            raise ValueError(f"clamp_compliance stiffness must be positive (inf = rigid), got {self.stiffness}")

    def apply(self, system, rig, params) -> None:

        if math.isinf(self.stiffness):
            return
        system.fixed[2] = False  # bottom node: rotation
        system.discrete.append(DiscreteElement(2, "spring", self.stiffness))


@dataclass(frozen=True)
class AmplitudeDependentDamping(Effect):
    """A nonlinear dissipative force at the top guide.

    Physical origin: the top of the beam slides axially in a guide (a linear
    bearing or a pair of rollers) that rubs.  The beam's shortening, quadratic
    in the transverse amplitude, drives the top axially at twice the response
    frequency, and the guide's friction dissipates energy in proportion to
    how far it moves: damping that grows with amplitude.  ``kind``:

    * ``"coulomb"``: f = friction_force tanh(v / velocity_scale), a Coulomb
      friction regularised below ``velocity_scale`` [m/s];
    * ``"quadratic"``: ``f = coefficient |v| v``, a quadratic (turbulent-like)
      damper, ``coefficient`` [N s^2/m^2].

    Signature in the data: nothing at the low level (the top hardly moves);
    at the high level the resonance peak flattens more than the axial damper c
    alone explains, the free decay's damping changes with amplitude, and the
    third-order kernel's share changes while the second's does not.  (The top
    slides by the end shortening, ~A^2 for a bending amplitude A, so Coulomb
    friction here takes an energy ~A^2 per cycle: the decay stays about
    exponential, unlike a Coulomb-damped oscillator's linear envelope; checked
    against energy balance in tests/test_effects.py.)
    """

    kind: str = "coulomb"
    friction_force: float = 0.0  # N
    velocity_scale: float = 1e-4  # m/s
    coefficient: float = 0.0  # N s^2/m^2

    name: ClassVar[str] = "amplitude_dependent_damping"

    def __post_init__(self):
        if self.kind not in ("coulomb", "quadratic"):
            raise ValueError(f"amplitude_dependent_damping kind must be 'coulomb' or 'quadratic', got {self.kind!r}")
        _check_non_negative(
            "amplitude_dependent_damping", friction_force=self.friction_force, coefficient=self.coefficient
        )
        if not (self.velocity_scale > 0 and math.isfinite(self.velocity_scale)):
            raise ValueError(f"amplitude_dependent_damping velocity_scale must be positive, got {self.velocity_scale}")

    def apply(self, system, rig, params) -> None:

        top = system.n_dof - 3  # top node: axial dof
        if self.kind == "coulomb" and self.friction_force > 0:
            system.discrete.append(DiscreteElement(top, "coulomb", self.friction_force, self.velocity_scale))
        elif self.kind == "quadratic" and self.coefficient > 0:
            system.discrete.append(DiscreteElement(top, "quadratic_damper", self.coefficient))


EFFECTS = {cls.name: cls for cls in (InitialImperfection, ShakerAttachment, ClampCompliance, AmplitudeDependentDamping)}
