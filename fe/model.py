"""The full finite-element model of the preloaded beam rig.

:class:`BeamModel` holds the discretization (elements, substeps, integrator
settings, effects) and offers the static preloaded equilibrium, the linearised
modal analysis, the linear FRF, the linear buckling load and the transient
simulation behind one ``simulate`` method (the interface any model of the rig
implements, see :func:`fe.simulate`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.linalg

from . import _kernels as K
from ._banded import band_to_dense
from .effects import Effect
from .excitation import check_interpolation, upsample
from .rig import Parameters, Rig
from .system import DiscreteElement, SystemDescription

# Defaults of the updating model, chosen by the convergence study in
# benchmarks/convergence_study.py (README, "Solver defaults").
DEFAULT_ELEMENTS = 10
DEFAULT_SUBSTEPS = 4
DEFAULT_RHO_INF = 0.9
PAPER_RHO_INF = 0.01

KD = 5  # half bandwidth of a chain of 3-dof nodes


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


def generalized_alpha_coefficients(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, gamma, beta) of Chung and Hulbert (1993), paper eq. 7-10."""
    if not (math.isfinite(rho_inf) and 0.0 <= rho_inf <= 1.0):
        raise ValueError(f"rho_inf must lie in [0, 1], got {rho_inf}")
    alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    alpha_f = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 - alpha_m + alpha_f
    beta = 0.25 * (1.0 - alpha_m + alpha_f) ** 2
    return alpha_m, alpha_f, gamma, beta


def generalized_alpha_accuracy(rho_inf: float, omega_dt: float) -> tuple[float, float]:
    """Algorithmic damping ratio and relative period error of the scheme for an
    undamped mode at omega * dt (from the principal roots of its amplification
    matrix).  Returns (damping_ratio, period_elongation), both dimensionless."""
    am, af, g, b = generalized_alpha_coefficients(rho_inf)
    w2 = omega_dt**2
    lhs = np.array([[w2 * (1 - af), 0, 1 - am], [1, 0, -b], [0, 1, -g]])
    rhs = np.array([[-w2 * af, 0, -am], [1, 1, 0.5 - b], [0, 1, 1 - g]])
    lam = np.linalg.eigvals(np.linalg.solve(lhs, rhs))
    principal = lam[np.argmax(lam.imag)]
    phase = np.angle(principal)
    zeta = -np.log(abs(principal)) / phase
    # damped phase per step -> undamped numerical frequency
    omega_num = np.hypot(phase, np.log(abs(principal)))
    return float(zeta), float(omega_dt / omega_num - 1.0)


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


def _distribute(n: int, lengths: np.ndarray) -> np.ndarray:
    """Split n elements over segments proportionally (largest remainder, >= 1 each)."""
    if n < lengths.size:
        raise ValueError(
            f"n_elements = {n} is too small: the mesh needs at least {lengths.size} "
            "(a node at the shaker and one at the sensor)"
        )
    share = n * lengths / lengths.sum()
    counts = np.maximum(1, np.floor(share).astype(int))
    while counts.sum() < n:
        counts[np.argmax(share - counts)] += 1
    while counts.sum() > n:
        i = np.argmax(np.where(counts > 1, counts - share, -np.inf))
        counts[i] -= 1
    return counts


def hermite_weights(node_x: np.ndarray, x: float) -> np.ndarray:
    """Weights w (length 3 n_nodes) with w @ u = transverse displacement at x
    (cubic Hermite interpolation on the reference mesh)."""
    n_nodes = node_x.size
    if not node_x[0] <= x <= node_x[-1]:
        raise ValueError(f"position {x} m lies outside the beam [0, {node_x[-1]}] m")
    w = np.zeros(3 * n_nodes)
    hit = np.flatnonzero(np.isclose(node_x, x, rtol=0, atol=1e-12))
    if hit.size:
        w[3 * hit[0] + 1] = 1.0
        return w
    e = int(np.searchsorted(node_x, x) - 1)
    le = node_x[e + 1] - node_x[e]
    xi = (x - node_x[e]) / le
    w[3 * e + 1] = 1 - 3 * xi**2 + 2 * xi**3
    w[3 * e + 2] = le * (xi - 2 * xi**2 + xi**3)
    w[3 * e + 4] = 3 * xi**2 - 2 * xi**3
    w[3 * e + 5] = le * (-(xi**2) + xi**3)
    return w


@dataclass(frozen=True)
class BeamModel:
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
        counts = _distribute(self.n_elements, np.diff(stations))
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
        return dict(
            X=X,
            Y=Y,
            L0=L0,
            c0=c0,
            s0=s0,
            t0=t0,
            EA=rig.EA,
            EI=rig.EI,
            beta=rig.beam_viscosity(params.eta) / rig.youngs_modulus_pa,
            shallow=self.formulation == "shallow_arch",
            d_dof=np.array([e.dof for e in d], dtype=np.int64),
            d_law=np.array([laws[e.law] for e in d], dtype=np.int64),
            d_p1=np.array([e.p1 for e in d], dtype=float),
            d_p2=np.array([e.p2 for e in d], dtype=float),
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
            K.assemble(
                a["X"],
                a["Y"],
                a["L0"],
                a["c0"],
                a["s0"],
                a["t0"],
                a["EA"],
                a["EI"],
                a["beta"],
                a["shallow"],
                a["d_dof"],
                a["d_law"],
                a["d_p1"],
                a["d_p2"],
                u,
                v,
                fint,
                True,
                1.0,
                cfac,
                band,
                KD,
            )
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
            K.assemble(
                a["X"],
                a["Y"],
                a["L0"],
                a["c0"],
                a["s0"],
                a["t0"],
                a["EA"],
                a["EI"],
                0.0,
                a["shallow"],
                a["d_dof"],
                a["d_law"],
                a["d_p1"],
                a["d_p2"],
                u,
                np.zeros(n),
                fint,
                True,
                1.0,
                0.0,
                band,
                KD,
            )
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
        status, _ = K.static_newton(
            a["X"],
            a["Y"],
            a["L0"],
            a["c0"],
            a["s0"],
            a["t0"],
            a["EA"],
            a["EI"],
            a["shallow"],
            a["d_dof"],
            a["d_law"],
            a["d_p1"],
            a["d_p2"],
            a["fixed"],
            a["f_const"],
            u,
            KD,
            n_inc,
            tol,
            50,
        )
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

    # ---------------------------------------------------------------- transient
    def simulate(
        self,
        params: Parameters,
        force,
        fs: float = 1024.0,
        positions=None,
        initial_displacement=None,
        initial_velocity=None,
    ) -> SimulationResult:
        """Transient response to a sampled shaker force.

        Parameters
        ----------
        params : the updated parameters (SI).
        force : shaker force samples [N], spacing 1/fs, interpolated between
            samples as ``input_interpolation`` says.
        fs : output sampling rate [Hz]; the integrator takes ``substeps`` steps
            per sample.
        positions : transverse output positions from the clamp [m]
            (default: the sensor position).
        initial_displacement, initial_velocity : optional initial state, added
            to the static preloaded equilibrium / replacing the zero velocity
            (length n_dof; for verification studies).

        The transient starts from the static preloaded equilibrium.
        """
        force = np.ascontiguousarray(force, dtype=float)
        if force.ndim != 1 or force.size < 2:
            raise ValueError("force must be a 1-D array with at least 2 samples")
        if not np.all(np.isfinite(force)):
            raise ValueError("force contains NaN or inf")
        if not (fs > 0 and math.isfinite(fs)):
            raise ValueError(f"fs must be a positive sampling rate in Hz, got {fs}")
        positions = np.atleast_1d(self.rig.sensor_position_m if positions is None else positions)
        positions = positions.astype(float)
        state = self.static_equilibrium(params)
        system = self.describe(params)
        a = self._arrays(system, params)
        n = system.n_dof
        u = state.u.copy()
        v = np.zeros(n)
        if initial_displacement is not None:
            u += np.asarray(initial_displacement, float)
        if initial_velocity is not None:
            v[:] = np.asarray(initial_velocity, float)
        u[a["fixed"]] = 0.0
        v[a["fixed"]] = 0.0
        W = np.array([hermite_weights(self.node_x, p) for p in positions])
        am, af, gam, bet = generalized_alpha_coefficients(self.rho_inf)
        dt = 1.0 / (fs * self.substeps)
        tol = self.newton_rtol * (params.F + np.abs(force).max()) + self._roundoff_force
        ns = force.size
        if self.input_interpolation == "linear":
            fine, m = force, 1  # the kernel interpolates linearly between samples
        else:
            # one step per point of the upsampled force; every substeps-th is a sample
            fine, m = upsample(force, self.substeps, self.input_interpolation), self.substeps
        out_d = np.empty((fine.size, positions.size))
        out_v = np.empty((fine.size, positions.size))
        out_a = np.empty(fine.size)
        status, failed, iters = K.transient(
            a["X"],
            a["Y"],
            a["L0"],
            a["c0"],
            a["s0"],
            a["t0"],
            a["EA"],
            a["EI"],
            a["beta"],
            a["shallow"],
            a["d_dof"],
            a["d_law"],
            a["d_p1"],
            a["d_p2"],
            a["fixed"],
            a["m_band"],
            a["f_const"],
            a["b_load"],
            fine,
            self.substeps // m,
            dt,
            am,
            af,
            gam,
            bet,
            u,
            v,
            tol,
            self.max_newton_iterations,
            W,
            self.top_axial_dof,
            out_d,
            out_v,
            out_a,
        )
        out_d, out_v, out_a = out_d[::m], out_v[::m], out_a[::m]
        failed = -(-failed // m)
        if status != 0:
            what = "did not converge" if status == 1 else "hit a singular Newton matrix"
            raise ConvergenceError(
                f"Newton {what} in the time step ending at sample {failed} "
                f"(t = {failed / fs:.4f} s); the response may be diverging or the "
                "step too large: try more substeps"
            )
        return SimulationResult(
            time=np.arange(ns) / fs,
            force=force,
            positions=positions,
            displacement=out_d,
            velocity=out_v,
            axial_top=out_a,
            newton_iterations=int(iters),
            final_displacement=u,
            final_velocity=v,
        )

    def energy(self, params: Parameters, u: np.ndarray, v: np.ndarray) -> float:
        """Total mechanical energy [J]: kinetic + strain + springs + potential of F."""
        system = self.describe(params)
        a = self._arrays(system, params)
        mv = band_to_dense(a["m_band"], KD) @ v
        strain = K.strain_energy(
            a["X"],
            a["Y"],
            a["L0"],
            a["c0"],
            a["s0"],
            a["t0"],
            a["EA"],
            a["EI"],
            a["shallow"],
            a["d_dof"],
            a["d_law"],
            a["d_p1"],
            u,
        )
        return float(0.5 * v @ mv + strain - a["f_const"] @ u)


def _beam_axial_force(model: BeamModel, u: np.ndarray, a: dict) -> float:
    """Compressive axial force carried by the top element [N] (positive in compression)."""
    e = a["L0"].size - 1
    i0 = 3 * e
    dx = a["X"][e + 1] - a["X"][e] + u[i0 + 3] - u[i0]
    dy = a["Y"][e + 1] - a["Y"][e] + u[i0 + 4] - u[i0 + 1]
    ln = math.hypot(dx, dy)
    return -model.rig.EA * (ln - a["L0"][e]) / a["L0"][e]


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
