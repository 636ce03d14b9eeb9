"""The full finite-element model of the preloaded beam rig.

:class:`BeamModel` holds the discretization (elements, substeps, integrator
settings, effects) and offers the static preloaded equilibrium, the linearised
modal analysis, the linear FRF, the linear buckling load and the transient
simulation behind one ``simulate`` method (the interface any model of the rig
implements, see :func:`fe.simulate`).

This module holds the model itself: its settings, mesh, system description and
assembled matrices.  The analyses are mixed in from :mod:`fe.equilibrium` (the
static state and the linear analyses about it) and :mod:`fe.transient` (the
generalized-alpha transient); the mesh helpers are in :mod:`fe.mesh`, the result
records and errors in :mod:`fe.results`, all importable from here as before.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from . import _kernels as K
from ._banded import band_to_dense
from .effects import Effect
from .equilibrium import BeamEquilibrium
from .excitation import check_interpolation
from .mesh import KD, distribute, hermite_weights
from .results import (  # noqa: F401  (the result records and errors, re-exported)
    BucklingError,
    ConvergenceError,
    Modes,
    SimulationResult,
    StaticState,
    check_below_buckling,
)
from .rig import Parameters, Rig
from .system import DiscreteElement, SystemDescription
from .transient import (  # noqa: F401  (generalized_alpha_accuracy: re-exported)
    BeamTransient,
    generalized_alpha_accuracy,
    generalized_alpha_coefficients,
)

# Defaults of the updating model, chosen by the convergence study in
# benchmarks/convergence_study.py (README, "Solver defaults").
DEFAULT_ELEMENTS = 10
DEFAULT_SUBSTEPS = 4
DEFAULT_RHO_INF = 0.9
PAPER_RHO_INF = 0.01


@dataclass(frozen=True)
class BeamModel(BeamEquilibrium, BeamTransient):
    """Planar co-rotational Euler-Bernoulli model of the preloaded beam rig.

    Bottom clamped; top: transverse displacement and rotation held, axial
    displacement free and loaded by the constant compressive force F in
    parallel with the spring k_s and the damper c to ground.  Consistent mass,
    Kelvin-Voigt viscosity at element level (eta_b = (2/3)(1 + nu)^2 eta on the
    material stiffness), shaker point force at ``rig.shaker_position_m``.

    Parameters
    ----------
    rig : geometry and material.
    n_elements : number of beam elements (a node is placed at the shaker and
        at the sensor).
    substeps : generalized-alpha steps per output sample.
    rho_inf : spectral radius at infinite frequency of the generalized-alpha
        scheme (the paper uses 0.01).
    formulation : 'shallow_arch' (local strain with the w'^2 / 2 term:
        consistent geometric stiffness, the default) or 'linear' (the classic
        co-rotational element with the chord-only axial strain, as in OpenSees).
    effects : extensions of the model (see :mod:`fe.effects`).
    max_newton_iterations : Newton iterations per time step before the run is
        declared failed.
    input_interpolation : the force between samples, ``"bandlimited"``
        (default) or ``"linear"`` (see :mod:`fe.excitation`).
    newton_rtol : Newton tolerance on the residual, relative to
        F + max ``|shaker force|`` [-] (plus a floor at the round-off of the
        internal forces, 8 eps EA L / L_element).
    """

    rig: Rig = field(default_factory=Rig)
    n_elements: int = DEFAULT_ELEMENTS
    substeps: int = DEFAULT_SUBSTEPS
    rho_inf: float = DEFAULT_RHO_INF
    formulation: str = "shallow_arch"
    effects: tuple = ()
    newton_rtol: float = 1e-9
    max_newton_iterations: int = 30
    input_interpolation: str = "bandlimited"

    def __post_init__(self):
        if not isinstance(self.rig, Rig):
            raise TypeError("rig must be an fe.Rig")
        if int(self.n_elements) != self.n_elements or self.n_elements < 3:
            raise ValueError(f"n_elements must be an integer >= 3, got {self.n_elements}")
        if int(self.substeps) != self.substeps or self.substeps < 1:
            raise ValueError(f"substeps must be a positive integer, got {self.substeps}")
        generalized_alpha_coefficients(self.rho_inf)
        if self.formulation not in ("shallow_arch", "linear"):
            raise ValueError(f"formulation must be 'shallow_arch' or 'linear', got {self.formulation!r}")
        object.__setattr__(self, "effects", tuple(self.effects))
        for eff in self.effects:
            if not isinstance(eff, Effect):
                raise TypeError(f"effects must be fe.effects.Effect instances, got {eff!r}")
        check_interpolation(self.input_interpolation)
        if not (self.newton_rtol > 0 and math.isfinite(self.newton_rtol)):
            raise ValueError(f"newton_rtol must be positive, got {self.newton_rtol}")

    # ------------------------------------------------------------------ mesh
    @cached_property
    def node_x(self) -> np.ndarray:
        """Reference node positions along the beam [m]."""
        rig = self.rig
        stations = np.unique([0.0, rig.shaker_position_m, rig.sensor_position_m, rig.length_m])
        counts = distribute(self.n_elements, np.diff(stations))
        parts = [np.linspace(stations[j], stations[j + 1], counts[j] + 1)[:-1] for j in range(counts.size)]
        return np.concatenate(parts + [[rig.length_m]])

    @property
    def n_dof(self) -> int:
        return 3 * self.node_x.size

    @property
    def top_axial_dof(self) -> int:
        return 3 * (self.node_x.size - 1)

    # ----------------------------------------------------------- system arrays
    def describe(self, params: Parameters, effects: bool = True) -> SystemDescription:
        """Editable description of the system at ``params`` (effects applied)."""
        if not isinstance(params, Parameters):
            raise TypeError("params must be an fe.Parameters")
        x = self.node_x.copy()
        n = 3 * x.size
        fixed = np.zeros(n, dtype=bool)
        fixed[0:3] = True  # clamp
        fixed[n - 2] = True  # top: transverse held
        fixed[n - 1] = True  # top: rotation held
        top = n - 3
        f_const = np.zeros(n)
        f_const[top] = -params.F
        discrete = []
        if params.k_s > 0:
            discrete.append(DiscreteElement(top, "spring", params.k_s))
        if params.c > 0:
            discrete.append(DiscreteElement(top, "damper", params.c))
        system = SystemDescription(
            node_x=x,
            node_y=np.zeros_like(x),
            fixed=fixed,
            discrete=discrete,
            f_const=f_const,
            b_load=hermite_weights(x, self.rig.shaker_position_m),
        )
        if effects:
            for eff in self.effects:
                eff.apply(system, self.rig, params)
        return system

    def _arrays(self, system: SystemDescription, params: Parameters) -> dict:
        """Kernel arrays from a description."""
        rig = self.rig
        X, Y = system.node_x, system.node_y
        dx, dy = np.diff(X), np.diff(Y)
        L0 = np.hypot(dx, dy)
        c0, s0 = dx / L0, dy / L0
        # reference end rotations relative to the chord (zero: straight elements)
        t0 = np.zeros((L0.size, 2))
        if system.node_theta is not None:
            chord = np.arctan2(dy, dx)
            t0[:, 0] = system.node_theta[:-1] - chord
            t0[:, 1] = system.node_theta[1:] - chord
        n = system.n_dof
        mband = np.zeros((n, 2 * KD + 1))
        rho_a = rig.mass_per_length
        for e in range(L0.size):
            me = _element_mass(rho_a, L0[e], c0[e], s0[e])
            i0 = 3 * e
            for i in range(6):
                for j in range(6):
                    mband[i0 + i, KD + j - i] += me[i, j]
        for dof, mass in system.point_masses:
            mband[dof, KD] += mass
        laws = DiscreteElement._LAWS
        d = system.discrete
        beta = rig.beam_viscosity(params.eta) / rig.youngs_modulus_pa
        shallow = self.formulation == "shallow_arch"
        return dict(
            X=X,
            Y=Y,
            L0=L0,
            # the kernels' two tuples (fe._beam_element): the beam elements, the discrete ones
            elements=(X, Y, L0, c0, s0, t0, float(rig.EA), float(rig.EI), float(beta), bool(shallow)),
            discrete=(
                np.array([e.dof for e in d], dtype=np.int64),
                np.array([laws[e.law] for e in d], dtype=np.int64),
                np.array([e.p1 for e in d], dtype=float),
                np.array([e.p2 for e in d], dtype=float),
            ),
            fixed=system.fixed.astype(np.bool_),
            m_band=mband,
            f_const=np.asarray(system.f_const, float),
            b_load=np.asarray(system.b_load, float),
        )

    def matrices(
        self, params: Parameters, u: np.ndarray | None = None, v: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Dense (M, K_t, C, f_int) at state (u, v) (default: the reference state).

        K_t = d f_int / d u, C = d f_int / d v (all dofs; apply ``fixed`` yourself).
        """
        a = self._arrays(self.describe(params), params)
        n = a["fixed"].size
        u = np.zeros(n) if u is None else np.asarray(u, float)
        v = np.zeros(n) if v is None else np.asarray(v, float)
        fint = np.empty(n)

        def tangent(cfac):
            band = np.zeros((n, 2 * KD + 1))
            K.assemble(a["elements"], a["discrete"], u, v, fint, True, 1.0, cfac, band, KD)
            return band_to_dense(band, KD)

        Kt = tangent(0.0)
        C = tangent(1.0) - Kt
        return band_to_dense(a["m_band"], KD), Kt, C, fint.copy()

    @property
    def _roundoff_force(self) -> float:
        # internal forces carry a round-off of a few eps * EA * L / L_element
        # (the stretch is a small difference of lengths); residuals below it are noise
        shortest = np.diff(self.node_x).min()
        return 8 * np.finfo(float).eps * self.rig.EA * self.rig.length_m / shortest

    def energy(self, params: Parameters, u: np.ndarray, v: np.ndarray) -> float:
        """Total mechanical energy [J]: kinetic + strain + springs + potential of F."""
        system = self.describe(params)
        a = self._arrays(system, params)
        mv = band_to_dense(a["m_band"], KD) @ v
        strain = K.strain_energy(a["elements"], a["discrete"], u)
        return float(0.5 * v @ mv + strain - a["f_const"] @ u)


def _element_mass(rho_a: float, L: float, c: float, s: float) -> np.ndarray:
    """Consistent mass of a straight 2D beam element in global coordinates."""
    m = np.zeros((6, 6))
    ma = rho_a * L / 6.0
    m[0, 0] = m[3, 3] = 2 * ma
    m[0, 3] = m[3, 0] = ma
    mt = rho_a * L / 420.0
    idx = [1, 2, 4, 5]
    mb = mt * np.array(
        [
            [156, 22 * L, 54, -13 * L],
            [22 * L, 4 * L**2, 13 * L, -3 * L**2],
            [54, 13 * L, 156, -22 * L],
            [-13 * L, -3 * L**2, -22 * L, 4 * L**2],
        ]
    )
    m[np.ix_(idx, idx)] = mb
    t = np.zeros((6, 6))
    rot = np.array([[c, s], [-s, c]])
    t[0:2, 0:2] = rot
    t[3:5, 3:5] = rot
    t[2, 2] = t[5, 5] = 1.0
    return t.T @ m @ t
