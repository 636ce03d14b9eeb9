"""Modal reduced-order model (ROM) of the preloaded beam rig.

:class:`ModalROM` integrates the rig's nonlinear dynamics in the first few
transverse modes of the preloaded, linearised beam.  It is a model of the rig
in the sense of :func:`fe.simulate` (same ``simulate`` signature, same
:class:`fe.SimulationResult`, same sign conventions as :class:`fe.BeamModel`)
and costs well under a millisecond per 4096-sample run instead of tens.

>>> rom = ModalROM(rig=Rig(bending_stiffness_factor=1.24))   # 3 modes, 30-element shapes
>>> fe.simulate(rom, Parameters(), force).sensor_velocity     # [m/s]

The model
---------
Transverse deflection w(x, t) = sum_i phi_i(x) q_i(t), with phi_i spanning the
first ``n_modes`` modes of the full FE's straight beam (its cubic Hermite
element, mesh, mass and boundary conditions) linearised at the static preload
P_eff = F K_b / (K_b + k_s).  The beam is shallow (von Karman) with a uniform
axial force.  With U the top's axial displacement (negative = shortening, as
in the full FE) and w0 an initial bow, the axial strain is

    eps = (U + s) / L,   s = 1/2 int w'^2 dx + int w0' w' dx

(s: the end shortening the bending draws in), and the beam's tension is
N = K_b (U + s) + beta K_b (U' + s'), K_b = E A / L, beta = eta_b / E with the
full FE's Kelvin-Voigt mapping eta_b = (2/3)(1 + nu)^2 eta: the viscosity acts
on the true axial strain rate, including the rate of the shortening s' (a
constant stiffness-proportional matrix would miss that nonlinear damping),
and on the curvature rate.  The massless top is in equilibrium between the
beam, the spring k_s, the damper c and the dead load F,

    N + k_s U + c U' = -F        (a first-order equation for U),

and the modal equations (mass-normalised) are

    q'' + K0 (q + beta q') + N (G q + g0) = b f(t)

with K0 = Phi^T K_bend Phi (EI includes the rig's bending_stiffness_factor),
G_ij = int phi_i' phi_j' dx (exact for the Hermite shapes on the FE mesh;
s = 1/2 q.G q + g0.q), g0_i = int w0' phi_i' dx, b_i = phi_i(x_shaker).
The preload shortens the axis by the stretch lam = 1 - P_eff / EA, which
stiffens bending (and its viscosity) by 1 / lam^2 and scales the shortening
form by 1 / lam; with that, K0 - P_eff G equals the full FE's tangent at the
preload to 1e-7 (without it f1 comes out 5e-5 low: 0.4 % of the FRF on the
resonance flanks at zeta1 = 1.3 %).  Within the span of the preloaded modes,
the coordinates are rotated so that K0 is diagonal (the same Galerkin
system; it saves a matrix product per stage).

Axial inertia is neglected: the first axial mode of the strip, a quarter wave
with the top nearly free (k_s << K_b) at sqrt(E / rho) / (4 L) ~ 2.5 kHz
(a half wave, 5 kHz, when the damper holds the top), lies 18x above the
0-140 Hz band; the shortening oscillates at twice the vibration frequency
(below 100 Hz on the paper's tests), where the axial response is quasi-static
to (100 / 2500)^2 ~ 0.2 %.

Effects: an effect fits the reduced form if it only moves the reference
geometry transversally (``node_y``, ``node_theta``: a bow,
:class:`fe.InitialImperfection`) independently of the parameters; the bow is
integrated on a 16x finer grid (mesh-converged: see ``_bow_vector``).  Any
other effect raises ``ValueError`` naming it.

Time integration
----------------
Classical RK4 for (q, q'), the force read at the stage times from the
band-limited (or linear) interpolation of :mod:`fe.excitation`, as in the full FE.  RK4 is stable
to ``|omega dt| = 2.8`` on the imaginary axis: the substeps hold the highest retained mode of the
*unloaded* beam (above any preloaded frequency) and its Kelvin-Voigt decay rate
beta omega^2 at omega dt <= 2 (one substep per 1/1024 s for 3 modes).  The
top equation is stiff for small c (relaxation time (c + beta K_b) / (K_b +
k_s): 3 ms at the paper's point, 20 us at c = 0, eta = 1 MPa s) and
algebraic at c = eta = 0, so U is not an RK4 state: it is integrated exactly
for the drive r(t) = -F - K_b s - beta K_b s' interpolated through the RK4
stage values (linearly to the mid-stages, quadratically through t_n, the
mid-stage average and t_n + h).  That is unconditionally stable and gives
the quasi-static top U = r / (K_b + k_s) exactly in the limit.

Cost: the FE matrices are assembled once per model (cached); the basis
depends only on P_eff and costs one partial symmetric eigenproblem of the
free transverse dofs (58 at 30 elements) plus projections, ~0.2 ms, cached
per P_eff (so the (F, k_s) ridge at one P_eff shares it).  The time loop
costs ~0.1 us per RK4 step with 3 modes (compiled in :mod:`fe._rom_kernels`;
benchmarks/bench_rom.py).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.linalg

from ._rom_kernels import _transient
from .effects import Effect
from .excitation import check_interpolation, upsample
from .model import BeamModel, BucklingError, ConvergenceError, SimulationResult, check_below_buckling, hermite_weights
from .rig import Parameters, Rig

try:  # a declared dependency; without it the default BLAS threading is used
    from threadpoolctl import ThreadpoolController
except ImportError:  # pragma: no cover
    ThreadpoolController = None

DEFAULT_ROM_ELEMENTS = 30
DEFAULT_ROM_MODES = 3
MAX_OMEGA_DT = 2.0  # RK4's limit is 2.83 on the imaginary axis: keep a margin
BOW_REFINEMENT = 16  # grid of the bow, per element of the ROM's mesh
_CACHE_SIZE = 64


_BLAS = []  # the process's ThreadpoolController, made on first use (~1 ms)


def _one_blas_thread():
    """Context with one BLAS thread: the per-preload eigenproblem (~0.1 ms) is
    not faster on more, and on a shared machine a multithreaded OpenBLAS made it
    1.7x slower at 30 elements and up to 20x at 40.  Costs ~20 us."""
    if ThreadpoolController is None:
        return contextlib.nullcontext()
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1, user_api="blas")


# ----------------------------------------------------------------- FE matrices
def _element_matrices(le: np.ndarray, rho_a: float, ei: float):
    """Hermite element matrices on (w1, theta1, w2, theta2), one per element:
    consistent mass [kg], bending stiffness [N/m] and the shortening form
    int N_i' N_j' dx [1/m] (all exact for the cubic shapes)."""
    l = le[:, None, None]
    one = np.ones_like(l)
    m = (
        rho_a
        * l
        / 420.0
        * np.block(
            [
                [156 * one, 22 * l, 54 * one, -13 * l],
                [22 * l, 4 * l**2, 13 * l, -3 * l**2],
                [54 * one, 13 * l, 156 * one, -22 * l],
                [-13 * l, -3 * l**2, -22 * l, 4 * l**2],
            ]
        )
    )
    k = (
        ei
        / l**3
        * np.block(
            [
                [12 * one, 6 * l, -12 * one, 6 * l],
                [6 * l, 4 * l**2, -6 * l, 2 * l**2],
                [-12 * one, -6 * l, 12 * one, -6 * l],
                [6 * l, 2 * l**2, -6 * l, 4 * l**2],
            ]
        )
    )
    g = (
        1.0
        / (30.0 * l)
        * np.block(
            [
                [36 * one, 3 * l, -36 * one, 3 * l],
                [3 * l, 4 * l**2, -3 * l, -(l**2)],
                [-36 * one, -3 * l, 36 * one, -3 * l],
                [3 * l, -(l**2), -3 * l, 4 * l**2],
            ]
        )
    )
    return m, k, g


def _assemble(blocks: np.ndarray) -> np.ndarray:
    """Dense assembly of 4x4 element blocks on a chain of (w, theta) nodes."""
    ne = blocks.shape[0]
    out = np.zeros((2 * (ne + 1), 2 * (ne + 1)))
    for e in range(ne):
        out[2 * e : 2 * e + 4, 2 * e : 2 * e + 4] += blocks[e]
    return out


@dataclass(frozen=True)
class RigMatrices:
    """Transverse FE matrices on the free dofs (w, theta of the inner nodes),
    assembled once per model.

    mass [kg], bending [N/m] (EI with the rig's factor), geometric [1/m]
    (int N_i' N_j' dx: the tangent per newton of tension), chol_inv: L^-1 with
    mass = L L^T, bending_t / geometric_t: L^-1 (.) L^-T, shaker: load vector of
    a unit shaker force, bow [-]: int w0' N_j' dx, buckling_load [N].
    """

    node_x: np.ndarray
    mass: np.ndarray
    bending: np.ndarray
    geometric: np.ndarray
    chol_inv: np.ndarray
    bending_t: np.ndarray
    geometric_t: np.ndarray
    shaker: np.ndarray
    bow: np.ndarray
    buckling_load: float


@dataclass(frozen=True)
class ReducedSystem:
    """The ROM's matrices at one preload, in mass-normalised coordinates.

    p_eff [N]: static compression of the beam; stretch [-]: lam = 1 - P_eff/EA;
    omega [rad/s]: natural frequencies of the straight beam at p_eff (the first
    n_modes, ascending); shapes: (n_free, n_modes) basis on the free transverse
    dofs (w, theta of the inner nodes), spanning the first n_modes preloaded
    modes, rotated so that the bending stiffness is diagonal; kappa [1/s^2]:
    that diagonal; G [1/(kg m)]: int phi_i' phi_j' dx / lam; g0 [1/kg^0.5]:
    int w0' phi_i' dx / lam; b [1/kg^0.5]: phi_i(x_shaker); outputs: cache of
    output weights (rows phi_i(x)) per position set.
    """

    p_eff: float
    stretch: float
    omega: np.ndarray
    shapes: np.ndarray
    kappa: np.ndarray
    G: np.ndarray
    g0: np.ndarray
    b: np.ndarray
    outputs: dict = field(default_factory=dict, repr=False, compare=False)  # positions -> W


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


@dataclass(frozen=True)
class ModalROM:
    """Modal reduced-order model of the preloaded beam (see the module docstring).

    Parameters
    ----------
    rig : geometry and material (its ``bending_stiffness_factor`` scales EI).
    n_modes : retained transverse modes of the preloaded straight beam
        (at most 2 (n_elements - 1), the mesh's free transverse dofs).
    n_elements : elements of the full-FE mesh the shapes and matrices come
        from (the full FE's mesh: nodes at the shaker and the sensor).
    effects : effects that fit the reduced form (a bow, see the module docstring).
    substeps : RK4 steps per sample; None (default) chooses them from the
        highest retained mode (:meth:`choose_substeps`).
    input_interpolation : the force between samples, ``"bandlimited"``
        (default) or ``"linear"`` (see :mod:`fe.excitation`); RK4 reads it at
        its stage times, i.e. at 2 x substeps points per sample.

    :meth:`simulate` is the model interface of :func:`fe.simulate`;
    :meth:`linear_frf`, :meth:`static_equilibrium` and :meth:`buckling_load`
    mirror :class:`fe.BeamModel`'s; :meth:`reduced` gives the per-preload
    matrices (cached, :meth:`cache_clear` forgets them).  Measured against the
    full FE in benchmarks/results/rom_validation.md, cost in bench_rom.md.
    """

    rig: Rig = field(default_factory=Rig)
    n_modes: int = DEFAULT_ROM_MODES
    n_elements: int = DEFAULT_ROM_ELEMENTS
    effects: tuple = ()
    substeps: int | None = None
    input_interpolation: str = "bandlimited"
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False, hash=False)

    def __post_init__(self):
        if not isinstance(self.rig, Rig):
            raise TypeError("rig must be an fe.Rig")
        if int(self.n_elements) != self.n_elements or self.n_elements < 3:
            raise ValueError(f"n_elements must be an integer >= 3, got {self.n_elements}")
        n_free = 2 * (int(self.n_elements) - 1)
        if int(self.n_modes) != self.n_modes or not 1 <= self.n_modes <= n_free:
            raise ValueError(
                f"n_modes must be an integer in [1, {n_free}]: a mesh of {int(self.n_elements)} "
                f"elements has {n_free} free transverse dofs; got {self.n_modes}"
            )
        if self.substeps is not None and (int(self.substeps) != self.substeps or self.substeps < 1):
            raise ValueError(f"substeps must be a positive integer or None, got {self.substeps}")
        object.__setattr__(self, "n_modes", int(self.n_modes))
        object.__setattr__(self, "n_elements", int(self.n_elements))
        if self.substeps is not None:
            object.__setattr__(self, "substeps", int(self.substeps))
        object.__setattr__(self, "effects", tuple(self.effects))
        for eff in self.effects:
            if not isinstance(eff, Effect):
                raise TypeError(f"effects must be fe.effects.Effect instances, got {eff!r}")
        check_interpolation(self.input_interpolation)
        self._fe_model  # raises if an effect does not fit the reduced form

    # ------------------------------------------------------ per-model precompute
    @cached_property
    def _fe_model(self) -> BeamModel:
        """The full FE model whose element, mesh and boundaries the ROM inherits.

        Checks each effect by applying it to a fresh description: the ROM
        carries an effect only if it changes nothing but ``node_y``."""
        model = BeamModel(rig=self.rig, n_elements=self.n_elements, effects=self.effects)
        params = Parameters()
        plain = model.describe(params, effects=False)
        for eff in self.effects:
            probe = model.describe(params, effects=False)
            eff.apply(probe, self.rig, params)
            changed = [
                name
                for name in ("node_x", "fixed", "f_const", "b_load")
                if not np.array_equal(getattr(probe, name), getattr(plain, name))
            ]
            if probe.point_masses != plain.point_masses:
                changed.append("point_masses")
            if probe.discrete != plain.discrete:
                changed.append("discrete elements")
            if changed:
                raise ValueError(
                    f"effect {eff.name!r} ({type(eff).__name__}) does not fit the modal ROM: it "
                    f"changes {', '.join(changed)} of the system, while the ROM carries only "
                    "effects that bow the reference geometry (node_y); use fe.BeamModel for it"
                )
        return model

    @cached_property
    def rig_matrices(self) -> RigMatrices:
        """The transverse FE matrices (assembled once per model)."""
        rig = self.rig
        model = self._fe_model
        x = model.node_x
        le = np.diff(x)
        m, k, g = (_assemble(a) for a in _element_matrices(le, rig.mass_per_length, rig.EI))
        free = slice(2, -2)  # clamp at the bottom; top transverse and rotation held
        m, k, g = (a[free, free] for a in (m, k, g))
        linv = scipy.linalg.solve_triangular(np.linalg.cholesky(m), np.eye(m.shape[0]), lower=True)
        kt = linv @ k @ linv.T
        gt = linv @ g @ linv.T
        # buckling: K / lam^2 = P G / lam with lam = 1 - P / EA, i.e. P lam = P0
        p0 = float(scipy.linalg.eigh(kt, gt, eigvals_only=True, subset_by_index=[0, 0])[0])
        p_cr = 2.0 * p0 / (1.0 + math.sqrt(1.0 - 4.0 * p0 / rig.EA))
        shaker = self._dof_weights(x, rig.shaker_position_m)
        return RigMatrices(
            node_x=x,
            mass=m,
            bending=k,
            geometric=g,
            chol_inv=linv,
            bending_t=kt,
            geometric_t=gt,
            shaker=shaker,
            bow=self._bow_vector(x),
            buckling_load=p_cr,
        )

    def _bow_vector(self, node_x: np.ndarray) -> np.ndarray:
        """g0_j = int w0' N_j' dx on the free transverse dofs (zeros without effects).

        w0 comes from the effects' reference geometry (``node_y``) on a mesh
        BOW_REFINEMENT times finer, taken piecewise linear there, so that
        int_k w0' N_j' dx = slope_k (N_j(x_k+1) - N_j(x_k)) is exact; the
        polygon's O(h^2) error is 256 times smaller on the fine grid than on the
        ROM's mesh, i.e. mesh-converged (the full FE carries the bow as cubics,
        O(h^4), and agrees: see tests/test_rom.py).
        """
        if not self.effects:
            return np.zeros(2 * node_x.size - 4)
        fine = BeamModel(rig=self.rig, n_elements=BOW_REFINEMENT * self.n_elements, effects=self.effects)
        xf = fine.node_x
        slope = np.diff(fine.describe(Parameters()).node_y) / np.diff(xf)
        values = np.array([self._dof_weights(node_x, xk) for xk in xf])  # N_j(x_k)
        return slope @ np.diff(values, axis=0)

    @staticmethod
    def _dof_weights(node_x: np.ndarray, position: float) -> np.ndarray:
        """Weights on the free transverse dofs giving w(position) (cubic Hermite)."""
        w = hermite_weights(node_x, float(position)).reshape(-1, 3)[:, 1:].ravel()
        return w[2:-2]

    @property
    def node_x(self) -> np.ndarray:
        """Node positions of the FE mesh the shapes live on [m]."""
        return self.rig_matrices.node_x

    def buckling_load(self) -> float:
        """Linear buckling load of the straight beam [N] (the tangent's, with the
        axis shortened by the load, as the full FE)."""
        return self.rig_matrices.buckling_load

    def modal_analysis(self, params: Parameters, n_modes: int | None = None):
        """Modes of the full FE the ROM is built on (its ``n_elements`` mesh),
        linearised about the preloaded state; ``n_modes`` defaults to the ROM's."""
        return self._fe_model.modal_analysis(params, self.n_modes if n_modes is None else n_modes)

    # ------------------------------------------------ per-parameter precompute
    def _check_params(self, params: Parameters) -> float:
        if not isinstance(params, Parameters):
            raise TypeError("params must be an fe.Parameters")
        return check_below_buckling(params, self.rig, self.buckling_load())

    def reduced(self, params: Parameters) -> ReducedSystem:
        """The reduced matrices at the preload of ``params`` (cached per P_eff)."""
        p_eff = self._check_params(params)
        hit = self._cache.get(p_eff)
        if hit is not None:
            return hit
        rm = self.rig_matrices
        n = self.n_modes
        lam = 1.0 - p_eff / self.rig.EA
        with _one_blas_thread():
            w2, y = scipy.linalg.eigh(rm.bending_t / lam**2 - p_eff / lam * rm.geometric_t, subset_by_index=[0, n - 1])
            phi = rm.chol_inv.T @ y  # mass-normalised preloaded modes
            kappa, rot = np.linalg.eigh(phi.T @ rm.bending @ phi / lam**2)
        phi = phi @ rot
        wdofs = phi[0::2]  # deterministic signs: largest transverse displacement positive
        phi = phi * np.sign(wdofs[np.argmax(np.abs(wdofs), axis=0), np.arange(n)])
        red = ReducedSystem(
            p_eff=p_eff,
            stretch=lam,
            omega=np.sqrt(np.maximum(w2, 0.0)),
            shapes=phi,
            kappa=kappa,
            G=phi.T @ rm.geometric @ phi / lam,
            g0=phi.T @ rm.bow / lam,
            b=phi.T @ rm.shaker,
        )
        if len(self._cache) >= _CACHE_SIZE:
            self._cache.pop(next(iter(self._cache)))
        self._cache[p_eff] = red
        return red

    def cache_clear(self) -> None:
        """Forget the per-preload precomputation (e.g. to time it)."""
        self._cache.clear()

    def _output_weights(self, red: ReducedSystem, positions: np.ndarray) -> np.ndarray:
        """Rows phi_i(x) of the output positions (cached with the basis)."""
        key = positions.tobytes()
        w = red.outputs.get(key)
        if w is None:
            w = np.array([self._dof_weights(self.node_x, p) for p in positions]) @ red.shapes
            w = red.outputs[key] = np.ascontiguousarray(w)
        return w

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

    # ---------------------------------------------------------------- transient
    def choose_substeps(self, params: Parameters, fs: float) -> int:
        """RK4 steps per sample: ``substeps`` if given, else the fewest that hold
        omega dt <= 2 for the highest retained mode of the unloaded beam (above
        any preloaded frequency) and for its Kelvin-Voigt decay rate beta omega^2."""
        if self.substeps is not None:
            return self.substeps
        red = self.reduced(params)
        beta = self.rig.beam_viscosity(params.eta) / self.rig.youngs_modulus_pa
        w = math.sqrt(float(red.kappa.max()))
        return max(1, math.ceil(max(w, beta * w * w) / (fs * MAX_OMEGA_DT)))

    def simulate(self, params: Parameters, force, fs: float = 1024.0, positions=None) -> SimulationResult:
        """Transient response to a sampled shaker force, from the static state.

        Parameters
        ----------
        params : the updated parameters (SI).
        force : shaker force samples [N], spacing 1/fs, interpolated between
            samples as ``input_interpolation`` says.
        fs : sampling rate [Hz].
        positions : transverse output positions from the clamp [m]
            (default: the sensor position).

        Returns a :class:`fe.SimulationResult`: transverse displacement [m] and
        velocity [m/s] at the positions, measured from the unloaded (possibly
        bowed) reference as in the full FE; the top's axial displacement [m]
        (negative = shortening); ``newton_iterations`` 0; ``final_displacement``
        and ``final_velocity`` are the modal coordinates q, q' at the last sample.
        """
        try:
            force = np.ascontiguousarray(force, dtype=float)
        except (TypeError, ValueError):
            raise ValueError("force must be a 1-D array of numbers [N]") from None
        if force.ndim != 1 or force.size < 2:
            raise ValueError(f"force must be a 1-D array with at least 2 samples, got shape {force.shape}")
        if not np.all(np.isfinite(force)):
            raise ValueError("force contains NaN or inf")
        try:
            fs = float(fs)
        except (TypeError, ValueError):
            raise ValueError(f"fs must be a positive sampling rate in Hz, got {fs!r}") from None
        if not (fs > 0 and math.isfinite(fs)):
            raise ValueError(f"fs must be a positive sampling rate in Hz, got {fs}")
        positions = np.atleast_1d(
            np.asarray(self.rig.sensor_position_m if positions is None else positions, dtype=float)
        )
        if positions.ndim != 1:
            raise ValueError("positions must be a scalar or a 1-D array of positions [m]")
        red = self.reduced(params)
        W = self._output_weights(red, positions)
        st = self.static_equilibrium(params)
        rig = self.rig
        beta = rig.beam_viscosity(params.eta) / rig.youngs_modulus_pa
        substeps = self.choose_substeps(params, fs)
        q = st.q.copy()
        qd = np.zeros(self.n_modes)
        ns = force.size
        out_d = np.empty((ns, positions.size))
        out_v = np.empty((ns, positions.size))
        out_a = np.empty(ns)
        _transient(
            red.kappa,
            red.G,
            red.g0,
            red.b,
            W,
            beta,
            rig.axial_stiffness,
            params.F,
            params.k_s,
            params.c,
            upsample(force, 2 * substeps, self.input_interpolation),
            ns,
            substeps,
            1.0 / (fs * substeps),
            q,
            qd,
            st.top_displacement,
            out_d,
            out_v,
            out_a,
        )
        if not (np.isfinite(out_v[-1]).all() and np.isfinite(out_a[-1])):
            raise ConvergenceError(
                f"the ROM's response diverged with {substeps} RK4 substeps per sample; "
                "leave substeps=None (automatic) or raise it"
            )
        return SimulationResult(
            time=np.arange(ns) / fs,
            force=force,
            positions=positions,
            displacement=out_d,
            velocity=out_v,
            axial_top=out_a,
            newton_iterations=0,
            final_displacement=q,
            final_velocity=qd,
        )
