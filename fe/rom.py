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

Code: :class:`ModalROM` and its time integration are here, the basis (FE
matrices, bow, per-preload reduction) in :mod:`fe.rom_basis`, the static state
and the linear FRF in :mod:`fe.rom_equilibrium` (both mixed into
:class:`ModalROM`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._rom_kernels import _transient
from .effects import Effect
from .excitation import check_interpolation, upsample
from .results import ConvergenceError, SimulationResult
from .rig import Parameters, Rig
from .rom_basis import BOW_REFINEMENT, ReducedSystem, RigMatrices, ROMBasis  # noqa: F401  (re-exported)
from .rom_equilibrium import ROMEquilibrium, ROMState  # noqa: F401  (re-exported)

DEFAULT_ROM_ELEMENTS = 30
DEFAULT_ROM_MODES = 3
MAX_OMEGA_DT = 2.0  # RK4's limit is 2.83 on the imaginary axis: keep a margin


@dataclass(frozen=True)
class ModalROM(ROMBasis, ROMEquilibrium):
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
            (red.kappa, red.G, red.g0, red.b),
            W,
            (beta, rig.axial_stiffness, params.F, params.k_s, params.c),
            upsample(force, 2 * substeps, self.input_interpolation),
            ns,
            substeps,
            1.0 / (fs * substeps),
            (q, qd, st.top_displacement),
            (out_d, out_v, out_a),
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
