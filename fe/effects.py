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

    def apply(self, system, rig, params) -> None:
        system.node_y = system.node_y + self.shape(system.node_x, rig.length_m)


EFFECTS = {cls.name: cls for cls in (InitialImperfection,)}
