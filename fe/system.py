"""The editable description of a beam system that the kernels run on, and its
discrete elements: what :mod:`fe.effects` edit and :mod:`fe.model` assembles."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import _kernels as K

__all__ = ["DiscreteElement", "SystemDescription"]


@dataclass
class DiscreteElement:
    """A spring, damper or friction element from one dof to ground.

    law: 'spring' (f = p1 u), 'damper' (f = p1 v), 'quadratic_damper'
    (f = p1 ``|v|`` v) or 'coulomb' (f = p1 tanh(v / p2)); p1, p2 in SI.
    """

    dof: int
    law: str
    p1: float
    p2: float = 1.0

    _LAWS = {
        "spring": K.LAW_SPRING,
        "damper": K.LAW_DAMPER,
        "quadratic_damper": K.LAW_QUADRATIC_DAMPER,
        "coulomb": K.LAW_COULOMB,
    }


@dataclass
class SystemDescription:
    """Everything the kernels need, in editable form (effects edit this).

    node_x, node_y: reference node coordinates [m] (x along the beam from the
    clamp, y transverse); node_theta: reference rotation of the cross-section
    [rad] (the slope angle of a bowed axis; None: that of the straight chords,
    i.e. straight elements); fixed: boolean mask of held dofs; point_masses: list
    of (dof, mass [kg]); discrete: list of DiscreteElement; f_const: constant
    external load [N]; b_load: load pattern of the shaker force (per N).
    """

    node_x: np.ndarray
    node_y: np.ndarray
    fixed: np.ndarray
    point_masses: list = field(default_factory=list)
    discrete: list = field(default_factory=list)
    f_const: np.ndarray | None = None
    b_load: np.ndarray | None = None
    node_theta: np.ndarray | None = None

    @property
    def n_dof(self) -> int:
        return 3 * self.node_x.size
