"""A ground-vibration-test (GVT) campaign of a wing with a store on a nonlinear joint, made the
way a laboratory makes it (a test helper: no tests here).

The structure (the "truth", another form than the modal model fitted to its records)
-------------------------------------------------------------------------------------
A cantilever wing-like beam in physical coordinates, with a store and a control surface.  Why
this form: a cantilever beam's second bending mode lies 3.6x (tapered as here) to 6.3x (uniform)
above its first, so six modes in 3-10 Hz need what a real wing carries: the store and the control
surface bring modes of their own, and the taper puts the second torsion mode at 1.8x the first,
so that bending, torsion and the subsystems' modes interleave.

* the wing: a straight tapered cantilever of span ``span_m`` [m], chord ``c(y) = c_r (1 - (1 -
  taper) y / L)``, in vertical bending and torsion.  Bending: Euler-Bernoulli Hermite elements
  (w [m], slope dw/dy [rad]) with EI(y) = EI_r (c/c_r)^p; torsion: linear elements (twist phi
  [rad]) with GJ(y) = GJ_r (c/c_r)^p; mass per length m(y) = m_r (c/c_r)^q, its centre of gravity
  ``cg_offset`` chords aft of the elastic axis (so bending and torsion couple through the
  consistent mass matrix) and its radius of gyration ``gyration`` chords about it.  Element
  matrices by 5-point Gauss quadrature of the varying properties; the slopes are condensed
  statically (Guyan: exact for the stiffness, the mass taken with the static shapes), which
  removes the stiff rotational modes an explicit integrator would have to resolve (the highest
  mode left is 0.5 kHz), so the model's degrees of freedom are w and phi at every node (a point
  at chord x, positive aft of the elastic axis, moves by w + x phi), the store's heave and pitch
  and the control surface's rotation;
* the store (the payload, ``store_mass`` [kg], a few % of the wing's mass; pitch inertia
  ``store_inertia`` [kg m^2] about its centre of gravity, which lies ``store_cg`` [m] from the
  attachment along the chord) hangs from node ``store_node`` on a pylon: its pitch on a linear
  spring ``pylon_pitch_stiffness`` [N m/rad] and its vertical load through THE JOINT at one point
  (chord ``attach_chord`` [m]): the relative vertical displacement d [m] = store point - wing
  point, carrying the joint force

      g = k0 d + sum_i z_i + f_cl(d)                                              [N]

  - ``joint_stiffness`` k0 [N/m]: a linear spring;
  - friction, a smooth Iwan element: ``len(slip_forces)`` Jenkins elements in parallel, element i
    of stick stiffness ``friction_stiffness / n`` and slip force ``slip_forces[i]`` [N] (spread),
    each smoothed as a Bouc-Wen law (exponent ``friction_exponent``):
    z_i' = k_i d' (1 - |z_i / F_i|^n) while loading (z_i d' > 0), k_i d' while unloading: stuck
    (elastic) at small force, sliding at F_i, dissipating z_i d' |z_i/F_i|^n >= 0;
  - clearance (backlash): a dead band of half-gap ``gap`` [m] with contact stiffness
    ``contact_stiffness`` [N/m] beyond it, D(u) = k_c (s(u - gap) - s(-u - gap)) with s(x) =
    eps log(1 + exp(x / eps)) (a smoothed ramp, ``contact_smoothing`` eps [m]), held closed at
    rest by a constant ``preload`` [N] (as a store's weight or a sway brace presses the lug on
    one face of its hook): f_cl(d) = D(d + u0) - D(u0), D(u0) = preload.  At small amplitude the
    contact stays closed (stiffness k_c); beyond d < -(u0 - gap) the lug lifts off into the gap
    (zero contact force inside it, only the constant preload) and the joint softens; the far face
    is reached at d < -(u0 + gap) (-18 mm by default: at the peaks of the high-level sweep only).
    ``preload=0`` gives the plain symmetric dead band, open at rest.
* the control surface (an aileron, ``aileron_mass`` [kg], rotation beta [rad]) on a hinge at
  chord ``hinge_chord`` [m] of node ``aileron_node``, its centre of gravity ``aileron_cg`` [m]
  aft of the hinge, inertia ``aileron_inertia`` [kg m^2] about it, the actuator a linear hinge
  spring ``hinge_stiffness`` [N m/rad] on beta - phi.

Damping: Rayleigh, C = a M + b K on the mass and the linear stiffness (wing, pylon pitch, hinge,
joint spring k0; not the friction or the contact), a and b such that the ratio is
``rayleigh_zeta`` (1.2 %) at both ends of ``rayleigh_band_hz`` (3-10 Hz); the linearised modes
then have 0.9-1.5 % (complex eigenanalysis, :meth:`GVTRig.linear_modes`).

The linear modes (:meth:`GVTRig.linear_modes`) are those of the structure linearised at rest with
the joint STUCK (every Jenkins element elastic, friction stiffness k_f) and the clearance CLOSED
(the preloaded contact, stiffness dD/du(u0) = k_c to 1e-9; with ``preload=0`` the gap is open at
rest and this term is ~0).  Defaults (wing 39.3 kg, store 1.9 kg = 4.8 %): eight modes below
15 Hz, six of them in 3-10 Hz::

    3.41 Hz 1.11 %  wing first bending               joint's share of the strain energy 0.09
    3.93 Hz 0.89 %  store heave on the joint         0.61   (the joint mode)
    4.48 Hz 1.01 %  wing first torsion (+ bending)   0.05
    6.97 Hz 1.01 %  control surface (+ store pitch)  0.05
    8.09 Hz 1.01 %  store pitch (+ control surface)  0.13
    9.27 Hz 1.12 %  wing second torsion              0.05
    12.86, 14.08 Hz: second bending, bending-torsion (above the excited band)

From the low to the high level (force rms 0.3, 0.9 and 2.7 N) the store heave mode softens by
3-4.5 % (2.7-4.5 % over random-phase realisations) and its damping rises from 0.9 % to 1.3-1.6 %
(medium) and 4-5 % (high): the friction elements slip, the lug lifts off its face 7 % of the time
at the high level, never at the others.  The first bending, the control surface and the store
pitch soften by 0.2-0.9 %, the two torsion modes by 0-0.4 % (they hardly load the joint); the
low level is linear to 0.02 % (the weakest Jenkins element below 60 % of its slip force, where
the Bouc-Wen law with n = 4 loses < 13 % of its stiffness at the peaks only).

Sensors (vertical acceleration [m/s^2]): ``tip`` (node 10, 0.18 m aft of the elastic axis: the
trailing edge of the 0.28 m tip chord, the elastic axis at 35 % chord), where the shaker drives
(the driving point, every mode in band seen there at >= 10 % of its largest shape); ``mid``
(node 5, 0.15 m forward of it) and ``store`` (the store's nose, 0.3 m ahead of its centre of
gravity).  The force F [N] acts at the tip sensor's point.

How it is recorded
------------------
:meth:`GVTRig.simulate` integrates M x'' + C x' + K x + b_j g(d, z) = b_f F(t) from rest with
classic RK4 at ``substeps`` steps per sample (compiled with numba), the friction states z_i
integrated with the structure, the force evaluated exactly at every step and half-step (the
excitation is known analytically: a finite sum of cosines, a sweep's closed form); it refuses a
step outside RK4's stability region.  :func:`make_campaign` makes five tests from one ``seed``:
random-phase periodic multisines on the lines of ``band_hz`` at three force levels (rms 1:3:9 by
default; ``n_periods`` periods of ``period`` samples from rest, the first period holding the
transient, ``period_samples`` declared) and two linear sine sweeps over the same band (up at the
low level, down at the high one; raised-cosine ends, the last 8 % of the record quiet).  Then
white noise on every channel: the force's sd 1 % of the lowest level's rms, each sensor's its own
share (``SENSOR_NOISE``: 0.6, 1.0, 1.5 %) of its rms in the lowest-level multisine, the same in
every test (a sensor's noise does not grow with the level), declared as each record's
``noise_sd``; and small constant offsets.

Every constant here is this module's own.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

import numpy as np
from numba import njit
from scipy import linalg

from bayes_update.data.dataset import Dataset, Record

FS_HZ = 50.0
PERIOD_SAMPLES = 1024  # 20.48 s at 50 Hz: lines 0.0488 Hz apart
N_PERIODS = 3
BAND_HZ = (2.0, 12.0)
SUBSTEPS = 32  # RK4 steps per sample (h = 0.625 ms at 50 Hz)
LEVELS_N = (0.3, 0.9, 2.7)  # force rms [N] of the low, medium and high tests
LEVEL_NAMES = ("low", "mid", "high")
SENSORS = (("tip", "acceleration"), ("mid", "acceleration"), ("store", "acceleration"))
FORCE_NOISE = 0.01  # sd / rms of the lowest level's force
SENSOR_NOISE = (0.006, 0.010, 0.015)  # sd / rms of each sensor in the lowest-level multisine
OFFSETS = 0.01  # offset sd, as a share of the lowest level's rms of each channel
SWEEP_ACTIVE = 0.92  # share of a sweep record the sweep takes (the rest: free decay)
SWEEP_TAPER_S = 0.5  # raised-cosine ends of a sweep [s]
TEST_NAMES = ("ms_low", "ms_mid", "ms_high", "sweep_low", "sweep_high")
DEFAULT_ROLES = {
    "ms_low": "linear",
    "ms_mid": "validation",
    "ms_high": "nonlinear",
    "sweep_low": "validation",
    "sweep_high": "validation",
}
RK4_MARGIN = 1.0 + 1e-12  # largest |amplification| of a linearised mode accepted per step


# ----------------------------------------------------------------------------- the joint's laws
def softplus(x, eps: float):
    """eps log(1 + exp(x / eps)): a ramp max(x, 0) smoothed over ``eps`` (overflow-safe)."""
    x = np.asarray(x, float) / eps
    return eps * (np.maximum(x, 0.0) + np.log1p(np.exp(-np.abs(x))))


def dead_band_force(u, gap: float, stiffness: float, eps: float):
    """The clearance's contact force D(u) [N] at relative displacement ``u`` [m]: zero inside the
    gap |u| < gap (to within stiffness eps exp(-(gap - |u|) / eps)), stiffness (|u| - gap) beyond."""
    u = np.asarray(u, float)
    return stiffness * (softplus(u - gap, eps) - softplus(-u - gap, eps))


def dead_band_stiffness(u, gap: float, stiffness: float, eps: float):
    """dD/du [N/m]."""
    u = np.asarray(u, float)
    sig = lambda x: 0.5 * (1.0 + np.tanh(0.5 * x / eps))  # noqa: E731  (the logistic function)
    return stiffness * (sig(u - gap) + sig(-u - gap))


@njit(cache=False)
def _softplus(x, eps):
    y = x / eps
    return eps * (max(y, 0.0) + math.log1p(math.exp(-abs(y))))


@njit(cache=False)
def _clearance(d, u0, f0, gap, kc, eps):
    """f_cl(d) = D(d + u0) - D(u0), D(u0) = f0 (the preload)."""
    if kc == 0.0:
        return 0.0
    u = d + u0
    return kc * (_softplus(u - gap, eps) - _softplus(-u - gap, eps)) - f0


@njit(cache=False)
def _iwan_rate(z, ddot, k, fslip, n_exp, out):
    """z_i' of the smooth Jenkins elements (Bouc-Wen, beta = gamma = 1/2)."""
    for i in range(z.size):
        if z[i] * ddot > 0.0:
            out[i] = k[i] * ddot * (1.0 - abs(z[i] / fslip[i]) ** n_exp)
        else:
            out[i] = k[i] * ddot


@njit(cache=False)
def _rhs(x, v, z, f, A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, acc, zdot):
    """acc = M^-1 (b_f f - C v - K x - b_j g), zdot = the friction states' rates."""
    n = x.size
    d = 0.0
    dd = 0.0
    for i in range(n):
        d += bj[i] * x[i]
        dd += bj[i] * v[i]
    g = _clearance(d, u0, f0, gap, kc, eps)
    for i in range(z.size):
        g += z[i]
    for i in range(n):
        s = a_f[i] * f - a_j[i] * g
        for j in range(n):
            s -= A_K[i, j] * x[j] + A_C[i, j] * v[j]
        acc[i] = s
    _iwan_rate(z, dd, k, fslip, n_exp, zdot)


@njit(cache=False)
def _rk4(F, substeps, h, A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, keep_states):
    """RK4 from rest; F on the half-step grid (F[2 j] at step j).  Returns the accelerations at the
    samples (every ``substeps`` steps), and (when ``keep_states``) x, v and z there."""
    n = A_K.shape[0]
    m = k.size
    n_steps = (F.size - 1) // 2
    n_out = n_steps // substeps + 1
    acc_out = np.zeros((n_out, n))
    ns = n_out if keep_states else 1
    x_out, v_out, z_out = np.zeros((ns, n)), np.zeros((ns, n)), np.zeros((ns, m))
    x, v, z = np.zeros(n), np.zeros(n), np.zeros(m)
    xs, vs, zs = np.zeros(n), np.zeros(n), np.zeros(m)
    a1, a2, a3, a4 = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    v2, v3 = np.zeros(n), np.zeros(n)
    z1, z2, z3, z4 = np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(m)
    _rhs(x, v, z, F[0], A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, a1, z1)
    acc_out[0] = a1
    for j in range(n_steps):
        _rhs(x, v, z, F[2 * j], A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, a1, z1)
        for i in range(n):
            xs[i] = x[i] + 0.5 * h * v[i]
            vs[i] = v[i] + 0.5 * h * a1[i]
        for i in range(m):
            zs[i] = z[i] + 0.5 * h * z1[i]
        _rhs(xs, vs, zs, F[2 * j + 1], A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, a2, z2)
        for i in range(n):
            v2[i] = vs[i]
            xs[i] = x[i] + 0.5 * h * v2[i]
            vs[i] = v[i] + 0.5 * h * a2[i]
        for i in range(m):
            zs[i] = z[i] + 0.5 * h * z2[i]
        _rhs(xs, vs, zs, F[2 * j + 1], A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, a3, z3)
        for i in range(n):
            v3[i] = vs[i]
            xs[i] = x[i] + h * v3[i]
            vs[i] = v[i] + h * a3[i]
        for i in range(m):
            zs[i] = z[i] + h * z3[i]
        _rhs(xs, vs, zs, F[2 * j + 2], A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, a4, z4)
        for i in range(n):
            x[i] += h / 6.0 * (v[i] + 2.0 * v2[i] + 2.0 * v3[i] + vs[i])
            v[i] += h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i])
        for i in range(m):
            z[i] += h / 6.0 * (z1[i] + 2.0 * z2[i] + 2.0 * z3[i] + z4[i])
        if (j + 1) % substeps == 0:
            o = (j + 1) // substeps
            _rhs(x, v, z, F[2 * j + 2], A_K, A_C, a_f, a_j, bj, k, fslip, n_exp, u0, f0, gap, kc, eps, a1, z1)
            acc_out[o] = a1
            if keep_states:
                x_out[o] = x
                v_out[o] = v
                z_out[o] = z
    return acc_out, x_out, v_out, z_out


# ----------------------------------------------------------------------------- the structure
def _hermite(s: float, l: float):
    """Hermite cubic shape functions at s in [0, 1] of an element of length l, and their second
    derivatives d2/dy2 (dofs w1, w1', w2, w2')."""
    N = np.array([1 - 3 * s**2 + 2 * s**3, l * (s - 2 * s**2 + s**3), 3 * s**2 - 2 * s**3, l * (-(s**2) + s**3)])
    N2 = np.array([-6 + 12 * s, l * (-4 + 6 * s), 6 - 12 * s, l * (-2 + 6 * s)]) / l**2
    return N, N2


@dataclass
class LinearModes:
    """Modes of the linearised structure (joint stuck, clearance closed).

    freq_hz : natural frequencies |lambda| / 2 pi [Hz] (complex eigenanalysis with C);
    damping_ratio : -Re(lambda) / |lambda| [-];
    shapes : (3, n) real mass-normalised undamped shapes at the sensors [1/sqrt(kg)]
        (``tip``, ``mid``, ``store``), each mode's largest entry positive;
    joint_share : share of each undamped mode's strain energy in the joint's stiffness [-];
    store_share : share of each undamped mode's kinetic energy in the store [-].
    """

    freq_hz: np.ndarray
    damping_ratio: np.ndarray
    shapes: np.ndarray
    joint_share: np.ndarray
    store_share: np.ndarray

    def to_dict(self) -> dict:
        return {k: np.asarray(v).tolist() for k, v in asdict(self).items()}


@dataclass(frozen=True)
class GVTRig:
    """The wing, its store on the joint and its control surface (module docstring); SI units.

    ``joint_law``: ``"nonlinear"`` (friction and clearance as described), ``"linear"`` (the
    joint replaced by its linearisation at rest: stuck and closed, the linear modes' structure).
    """

    # the wing
    span_m: float = 4.0
    root_chord_m: float = 0.8
    taper: float = 0.35  # tip chord / root chord
    n_elements: int = 10
    mass_per_length: float = 20.0  # m_r at the root [kg/m]
    bending_stiffness: float = 1.0e5  # EI_r at the root [N m^2]
    torsion_stiffness: float = 1.25e3  # GJ_r at the root [N m^2]
    stiffness_exponent: float = 4.0  # EI, GJ ~ c^p
    mass_exponent: float = 2.0  # m, I ~ c^q (and c^(q+2))
    cg_offset: float = 0.04  # centre of gravity aft of the elastic axis [chords]
    gyration: float = 0.25  # radius of gyration about the centre of gravity [chords]
    # the store and its pylon
    store_node: int = 4
    store_mass: float = 1.9  # [kg]
    store_inertia: float = 0.02  # about its centre of gravity [kg m^2]
    store_cg: float = -0.068  # its centre of gravity from the attachment, along the chord [m]
    attach_chord: float = 0.096  # the joint's chord position [m]
    pylon_pitch_stiffness: float = 40.0  # [N m/rad]
    # the joint
    joint_stiffness: float = 300.0  # k0 [N/m]
    friction_stiffness: float = 700.0  # k_f, total stick stiffness of the Jenkins elements [N/m]
    slip_forces: tuple = (0.6, 0.9, 1.3, 2.0)  # F_i [N]
    friction_exponent: float = 4.0  # Bouc-Wen n
    gap: float = 6.0e-3  # half-gap [m]
    contact_stiffness: float = 405.0  # k_c [N/m]
    contact_smoothing: float = 2.0e-4  # eps [m]
    preload: float = 2.5  # [N]
    joint_law: str = "nonlinear"
    # the control surface
    aileron_node: int = 7
    aileron_mass: float = 0.55  # [kg]
    aileron_inertia: float = 0.004  # about its centre of gravity [kg m^2]
    hinge_chord: float = 0.14  # [m]
    aileron_cg: float = 0.06  # aft of the hinge [m]
    hinge_stiffness: float = 12.5  # [N m/rad]
    # damping
    rayleigh_zeta: float = 0.012
    rayleigh_band_hz: tuple = (3.0, 10.0)
    # sensors and shaker: (node, chord [m]); the store's sensor at chord store_sensor from its cg
    tip_sensor: tuple = (10, 0.18)
    mid_sensor: tuple = (5, -0.15)
    store_sensor: float = -0.3
    include_store: bool = True
    include_aileron: bool = True
    rayleigh: bool = True

    # ------------------------------------------------------------------ matrices
    def chord(self, y) -> np.ndarray:
        return self.root_chord_m * (1.0 - (1.0 - self.taper) * np.asarray(y, float) / self.span_m)

    def node_y(self) -> np.ndarray:
        return np.linspace(0.0, self.span_m, self.n_elements + 1)

    def wing_mass(self) -> float:
        y, w = np.polynomial.legendre.leggauss(20)
        y = 0.5 * self.span_m * (y + 1.0)
        c = self.chord(y) / self.root_chord_m
        return float(0.5 * self.span_m * np.sum(w * self.mass_per_length * c**self.mass_exponent))

    def _full(self):
        """Full matrices (w, w', phi per free node, then store z, alpha, then aileron beta)."""
        ne = self.n_elements
        l = self.span_m / ne
        nw = 3 * (ne + 1)
        n_extra = 2 * self.include_store + self.include_aileron
        n = nw + n_extra
        K, M = np.zeros((n, n)), np.zeros((n, n))
        gp, gw = np.polynomial.legendre.leggauss(5)
        cr = self.root_chord_m
        for e in range(ne):
            ib = [3 * e, 3 * e + 1, 3 * e + 3, 3 * e + 4]
            it = [3 * e + 2, 3 * e + 5]
            for p, wgt in zip(gp, gw):
                s = 0.5 * (p + 1.0)
                c = float(self.chord((e + s) * l))
                r = c / cr
                EI = self.bending_stiffness * r**self.stiffness_exponent
                GJ = self.torsion_stiffness * r**self.stiffness_exponent
                m = self.mass_per_length * r**self.mass_exponent
                xcg = self.cg_offset * c
                Ia = m * (self.gyration * c) ** 2 + m * xcg**2
                N, N2 = _hermite(s, l)
                Lt, Lt1 = np.array([1.0 - s, s]), np.array([-1.0, 1.0]) / l
                jac = 0.5 * l * wgt
                K[np.ix_(ib, ib)] += jac * EI * np.outer(N2, N2)
                K[np.ix_(it, it)] += jac * GJ * np.outer(Lt1, Lt1)
                M[np.ix_(ib, ib)] += jac * m * np.outer(N, N)
                M[np.ix_(it, it)] += jac * Ia * np.outer(Lt, Lt)
                M[np.ix_(ib, it)] += jac * m * xcg * np.outer(N, Lt)
                M[np.ix_(it, ib)] += jac * m * xcg * np.outer(Lt, N)
        bj = np.zeros(n)
        k = nw
        if self.include_store:
            j = self.store_node
            iz, ia = k, k + 1
            M[iz, iz] += self.store_mass
            M[ia, ia] += self.store_inertia
            # d = store point - wing point at the attachment chord (the store's cg at attach + store_cg)
            bj[iz], bj[ia] = 1.0, -self.store_cg
            bj[3 * j], bj[3 * j + 2] = -1.0, -self.attach_chord
            rp = np.zeros(n)
            rp[ia], rp[3 * j + 2] = 1.0, -1.0
            K += self.pylon_pitch_stiffness * np.outer(rp, rp)
            K += self.joint_stiffness * np.outer(bj, bj)
            k += 2
        if self.include_aileron:
            j = self.aileron_node
            ib_ = k
            t = np.zeros(n)
            t[3 * j], t[3 * j + 2], t[ib_] = 1.0, self.hinge_chord, self.aileron_cg
            M += self.aileron_mass * np.outer(t, t)
            M[ib_, ib_] += self.aileron_inertia
            rh = np.zeros(n)
            rh[ib_], rh[3 * j + 2] = 1.0, -1.0
            K += self.hinge_stiffness * np.outer(rh, rh)
        return K, M, bj, nw

    def _point(self, n: int, node: int, chord: float) -> np.ndarray:
        r = np.zeros(n)
        r[3 * node], r[3 * node + 2] = 1.0, chord
        return r

    def matrices(self) -> dict:
        """The model's matrices after clamping the root and condensing the slopes (Guyan).

        ``M``, ``K`` (linear part: wing, pylon pitch, hinge, joint spring k0), ``C`` (Rayleigh),
        ``b_force`` (the shaker's point), ``b_joint`` (d = b_joint . x), ``sensors`` (3, n) rows
        (the sensors' displacements), ``T`` (full free dofs = T reduced), ``dofs`` (names)."""
        K, M, bj, nw = self._full()
        n_full = K.shape[0]
        sensors = [self._point(n_full, *self.tip_sensor), self._point(n_full, *self.mid_sensor)]
        if self.include_store:
            s = np.zeros(n_full)
            s[nw], s[nw + 1] = 1.0, self.store_sensor
            sensors.append(s)
        else:
            sensors.append(self._point(n_full, self.store_node, self.attach_chord))
        b_force = self._point(n_full, *self.tip_sensor)
        free = np.arange(3, n_full)  # the root clamped
        slopes = np.array([i for i in free if i < nw and i % 3 == 1])
        keep = np.array([i for i in free if i not in set(slopes.tolist())])
        T = np.zeros((n_full, keep.size))
        T[keep, np.arange(keep.size)] = 1.0
        T[slopes] = -np.linalg.solve(K[np.ix_(slopes, slopes)], K[np.ix_(slopes, keep)])
        T = T[free]
        Kf, Mf = K[np.ix_(free, free)], M[np.ix_(free, free)]
        Kr, Mr = T.T @ Kf @ T, T.T @ Mf @ T
        Kr, Mr = 0.5 * (Kr + Kr.T), 0.5 * (Mr + Mr.T)
        a, b = self.rayleigh_coefficients()
        Cr = a * Mr + b * Kr if self.rayleigh else np.zeros_like(Kr)
        names = {0: "w", 1: "w'", 2: "phi"}
        dofs = [f"{names[i % 3]}{i // 3}" if i < nw else ["z_store", "a_store", "beta"][i - nw] for i in keep]
        return {
            "M": Mr,
            "K": Kr,
            "C": Cr,
            "b_force": (b_force[free] @ T),
            "b_joint": (bj[free] @ T),
            "sensors": np.array([s[free] @ T for s in sensors]),
            "T": T,
            "dofs": dofs,
        }

    def rayleigh_coefficients(self) -> tuple:
        """(a [1/s], b [s]) of C = a M + b K: ratio ``rayleigh_zeta`` at both ends of the band."""
        w1, w2 = 2 * np.pi * np.asarray(self.rayleigh_band_hz, float)
        z = self.rayleigh_zeta
        return 2 * z * w1 * w2 / (w1 + w2), 2 * z / (w1 + w2)

    # ------------------------------------------------------------------ the joint
    def friction_elements(self) -> tuple:
        """(k_i [N/m], F_i [N]) of the Jenkins elements."""
        F = np.asarray(self.slip_forces, float)
        return np.full(F.size, self.friction_stiffness / max(F.size, 1)), F

    def clearance_rest(self) -> float:
        """u0 [m]: the contact's closure at rest, D(u0) = preload (0 without a preload)."""
        if self.preload <= 0.0 or self.contact_stiffness == 0.0:
            return 0.0
        g, kc, eps = self.gap, self.contact_stiffness, self.contact_smoothing
        u = g + self.preload / kc
        for _ in range(60):  # Newton on D(u) = P (D increasing, convex for u > 0)
            r = float(dead_band_force(u, g, kc, eps)) - self.preload
            u -= r / float(dead_band_stiffness(u, g, kc, eps))
            if abs(r) < 1e-13 * self.preload:
                break
        return float(u)

    def clearance_force(self, d):
        """f_cl(d) [N] of the preloaded clearance at relative displacement d [m] (0 at d = 0)."""
        u0 = self.clearance_rest()
        return dead_band_force(np.asarray(d) + u0, self.gap, self.contact_stiffness, self.contact_smoothing) - float(
            dead_band_force(u0, self.gap, self.contact_stiffness, self.contact_smoothing)
        )

    def joint_tangent(self) -> float:
        """The joint's nonlinear part's stiffness at rest [N/m]: friction stuck + clearance's tangent."""
        u0 = self.clearance_rest()
        kc = float(dead_band_stiffness(u0, self.gap, self.contact_stiffness, self.contact_smoothing))
        return self.friction_stiffness + kc

    def tangent_matrices(self) -> dict:
        """:meth:`matrices` with K the linearised stiffness at rest (joint stuck, clearance closed)."""
        mats = self.matrices()
        bj = mats["b_joint"]
        mats["K_linear"] = mats["K"]
        mats["K"] = mats["K"] + self.joint_tangent() * np.outer(bj, bj)
        return mats

    # ------------------------------------------------------------------ modes
    def linear_modes(self, max_hz: float = 15.0) -> LinearModes:
        """Modes below ``max_hz`` of the structure linearised at rest (the joint stuck, the
        clearance closed), C included: :class:`LinearModes`."""
        mats = self.tangent_matrices()
        M, K, C = mats["M"], mats["K"], mats["C"]
        n = M.shape[0]
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
        lam = np.linalg.eigvals(A)
        lam = lam[lam.imag > 0]
        lam = lam[np.argsort(np.abs(lam))]
        w2, V = linalg.eigh(K, M)
        keep = np.sqrt(w2) / (2 * np.pi) <= max_hz
        w2, V = w2[keep], V[:, keep]
        lam = lam[: w2.size]
        shapes = mats["sensors"] @ V
        sign = np.sign(shapes[np.argmax(np.abs(shapes), axis=0), np.arange(shapes.shape[1])])
        V, shapes = V * sign, shapes * sign
        bj = mats["b_joint"]
        kj = self.joint_stiffness + self.joint_tangent()
        joint = kj * (bj @ V) ** 2 / w2
        store = np.zeros(w2.size)
        if self.include_store:
            i = mats["dofs"].index("z_store")
            Ms = np.zeros_like(M)
            Ms[i, i], Ms[i + 1, i + 1] = self.store_mass, self.store_inertia
            store = np.einsum("im,ij,jm->m", V, Ms, V)
        return LinearModes(np.abs(lam) / (2 * np.pi), -lam.real / np.abs(lam), shapes, joint, store)

    # ------------------------------------------------------------------ time
    def _arrays(self):
        mats = self.matrices()
        M, K, C = mats["M"], mats["K"], mats["C"]
        kf, F = self.friction_elements()
        u0 = self.clearance_rest()
        f0 = float(dead_band_force(u0, self.gap, self.contact_stiffness, self.contact_smoothing))
        kc = self.contact_stiffness
        if self.joint_law == "linear":
            K = K + self.joint_tangent() * np.outer(mats["b_joint"], mats["b_joint"])
            kf, F, kc, f0 = np.zeros(0), np.zeros(0), 0.0, 0.0
        elif self.joint_law != "nonlinear":
            raise ValueError(f"joint_law is 'nonlinear' or 'linear', got {self.joint_law!r}")
        Minv = np.linalg.inv(M)
        return mats, {
            "A_K": np.ascontiguousarray(Minv @ K),
            "A_C": np.ascontiguousarray(Minv @ C),
            "a_f": Minv @ mats["b_force"],
            "a_j": Minv @ mats["b_joint"],
            "bj": np.ascontiguousarray(mats["b_joint"]),
            "k": np.ascontiguousarray(kf),
            "fslip": np.ascontiguousarray(F),
            "n_exp": float(self.friction_exponent),
            "u0": float(u0),
            "f0": f0,
            "gap": float(self.gap),
            "kc": float(kc),
            "eps": float(self.contact_smoothing),
        }

    def rk4_amplification(self, h: float) -> float:
        """Largest |R(lambda h)| of RK4 over the modes of the structure linearised at its stiffest
        (joint stuck, contact closed, the full contact stiffness): <= 1 is stable."""
        mats = self.matrices()
        M, K, C = mats["M"], mats["K"], mats["C"]
        bj = mats["b_joint"]
        K = K + (self.friction_stiffness + self.contact_stiffness) * np.outer(bj, bj)
        n = M.shape[0]
        A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
        z = np.linalg.eigvals(A) * h
        return float(np.max(np.abs(1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)))

    def simulate(self, force_function, n_samples: int, fs: float, substeps: int = SUBSTEPS, return_states=False):
        """Accelerations (n_samples, 3) [m/s^2] at the sensors ``tip``, ``mid``, ``store``, from rest
        at t = 0, for the force F(t) [N] at the shaker (``force_function(t)``, t [s] an array,
        evaluated at every RK4 step and half-step; an object with ``grid(dt, count)`` gives those
        values itself), RK4 at ``substeps`` steps per sample of rate ``fs`` [Hz].

        ``return_states``: also a dict of the states at the samples: ``x`` [m, rad] and ``v``
        (n_samples, n_dofs), ``z`` (n_samples, n_friction) [N], ``force`` (n_samples,) [N]."""
        n_samples, substeps = int(n_samples), int(substeps)
        h = 1.0 / (fs * substeps)
        amp = self.rk4_amplification(h)
        if amp > RK4_MARGIN:
            raise ValueError(
                f"RK4 is unstable at {substeps} substeps per sample at {fs} Hz (amplification {amp:.4f} per "
                "step of the stiffest mode): take more substeps"
            )
        count = 2 * substeps * (n_samples - 1) + 1
        if hasattr(force_function, "grid"):
            F = np.asarray(force_function.grid(0.5 * h, count), float)
        else:
            F = np.asarray(force_function(0.5 * h * np.arange(count)), float)
        mats, ar = self._arrays()
        acc, x, v, z = _rk4(np.ascontiguousarray(F), substeps, h, keep_states=bool(return_states), **ar)
        out = acc @ mats["sensors"].T
        if not return_states:
            return out
        return out, {"x": x, "v": v, "z": z, "force": F[:: 2 * substeps]}

    def energy(self, states: dict) -> np.ndarray:
        """The mechanical energy [J] at the samples of ``simulate(..., return_states=True)``: kinetic,
        the linear stiffness's, the Jenkins elements' z_i^2 / (2 k_i) and the clearance's potential
        (the integral of f_cl over d, by quadrature on a fine grid)."""
        mats = self.matrices()
        x, v, z = states["x"], states["v"], states["z"]
        K = mats["K"]
        if self.joint_law == "linear":
            K = K + self.joint_tangent() * np.outer(mats["b_joint"], mats["b_joint"])
        e = 0.5 * np.einsum("ti,ij,tj->t", v, mats["M"], v) + 0.5 * np.einsum("ti,ij,tj->t", x, K, x)
        if self.joint_law == "nonlinear":
            kf, _ = self.friction_elements()
            if kf.size:
                e += np.sum(z**2 / (2 * kf), axis=1)
            if self.contact_stiffness:
                d = x @ mats["b_joint"]
                lim = 1.05 * np.max(np.abs(d)) + 1e-9
                grid = np.linspace(-lim, lim, 20001)
                f = self.clearance_force(grid)
                U = np.concatenate([[0.0], np.cumsum(0.5 * (f[1:] + f[:-1]) * np.diff(grid))])
                U -= np.interp(0.0, grid, U)
                e += np.interp(d, grid, U)
        return e

    def truth(self) -> dict:
        """The linear modes and every parameter, JSON-ready."""
        params = {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}
        return {
            "model": "tests/gvt_rig.py: tapered wing (bending + torsion), store on a friction + clearance joint",
            "parameters": params,
            "wing_mass_kg": self.wing_mass(),
            "joint_tangent_n_per_m": self.joint_stiffness + self.joint_tangent(),
            "linear_modes": self.linear_modes().to_dict(),
        }


# ----------------------------------------------------------------------------- excitation
@dataclass
class Multisine:
    """F(t) = sum_k A cos(2 pi k t / T + phase_k) on the lines k / T [Hz] inside ``band_hz``, of rms
    ``rms`` [N] (A = rms sqrt(2 / n_lines)), period T = ``period_s`` [s]."""

    period_s: float
    band_hz: tuple
    rms: float
    phases: np.ndarray = field(repr=False)

    @classmethod
    def random(cls, period_s: float, band_hz, rms: float, rng) -> Multisine:
        k = cls.lines_of(period_s, band_hz)
        return cls(period_s, tuple(band_hz), float(rms), 2 * np.pi * rng.random(k.size))

    @staticmethod
    def lines_of(period_s: float, band_hz) -> np.ndarray:
        return np.arange(int(np.ceil(band_hz[0] * period_s - 1e-9)), int(np.floor(band_hz[1] * period_s + 1e-9)) + 1)

    @property
    def lines(self) -> np.ndarray:
        return self.lines_of(self.period_s, self.band_hz)

    @property
    def amplitude(self) -> float:
        return self.rms * math.sqrt(2.0 / self.lines.size)

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        out = np.zeros(t.shape)
        w = 2 * np.pi * self.lines / self.period_s
        for i in range(0, w.size, 16):
            out += np.cos(np.multiply.outer(t, w[i : i + 16]) + self.phases[i : i + 16]).sum(axis=-1)
        return self.amplitude * out

    def grid(self, dt: float, count: int) -> np.ndarray:
        """F at t = j dt, j < count: exact (an inverse FFT of the lines) when T / dt is an integer."""
        per = self.period_s / dt
        if abs(per - round(per)) > 1e-9 * per or round(per) < 2 * self.lines.max() + 2:
            return self(dt * np.arange(count))
        per = int(round(per))
        X = np.zeros(per // 2 + 1, complex)
        X[self.lines] = 0.5 * per * self.amplitude * np.exp(1j * self.phases)
        one = np.fft.irfft(X, per)
        return np.resize(one, count)


@dataclass
class Sweep:
    """A linear sine sweep of amplitude ``amplitude`` [N] from ``f_start`` to ``f_end`` [Hz] over
    ``duration_s`` [s] (raised-cosine ends of ``taper_s``), zero after it."""

    f_start: float
    f_end: float
    duration_s: float
    amplitude: float
    taper_s: float = SWEEP_TAPER_S

    def __call__(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        T = self.duration_s
        phase = 2 * np.pi * (self.f_start * t + 0.5 * (self.f_end - self.f_start) * t**2 / T)
        env = np.ones_like(t)
        a = np.clip(t / self.taper_s, 0.0, 1.0)
        b = np.clip((T - t) / self.taper_s, 0.0, 1.0)
        env *= 0.5 - 0.5 * np.cos(np.pi * a)
        env *= 0.5 - 0.5 * np.cos(np.pi * b)
        return np.where((t >= 0) & (t <= T), self.amplitude * env * np.sin(phase), 0.0)


# ----------------------------------------------------------------------------- the campaign
def make_campaign(
    seed: int = 0,
    rig: GVTRig | None = None,
    levels=LEVELS_N,
    roles: dict | None = None,
    *,
    fs: float = FS_HZ,
    period: int = PERIOD_SAMPLES,
    n_periods: int = N_PERIODS,
    band_hz=BAND_HZ,
    substeps: int = SUBSTEPS,
    noise: bool = True,
    offsets: bool = True,
    clean: dict | None = None,
) -> Dataset:
    """The GVT campaign: ``ms_low``, ``ms_mid``, ``ms_high`` (periodic multisines of force rms
    ``levels`` [N]), ``sweep_low`` (up, the low level) and ``sweep_high`` (down, the high level),
    each ``n_periods * period`` samples at ``fs`` [Hz], from one numpy Generator of ``seed``.

    roles : {test name: "linear" | "nonlinear" | "validation"} over :data:`DEFAULT_ROLES`.
    noise, offsets : add the sensors' and the force's white noise, the channels' offsets.
    clean : a dict that receives each test's noise-free ``(force, response)``, if given.
    The truth (:meth:`GVTRig.truth`, the noise sd added, the seed) is ``dataset.extra["truth"]``."""
    rig = rig or GVTRig()
    roles = {**DEFAULT_ROLES, **(roles or {})}
    unknown = sorted(set(roles) - set(TEST_NAMES))
    if unknown:
        raise ValueError(f"roles names unknown tests {unknown}; the tests are {list(TEST_NAMES)}")
    levels = tuple(float(x) for x in levels)
    if len(levels) != 3:
        raise ValueError(f"levels: three force rms [N] (low, mid, high), got {levels}")
    rng = np.random.default_rng(seed)
    n = int(n_periods) * int(period)
    period_s = period / fs
    t = np.arange(n) / fs
    excitations = {}
    for name, level, lname in zip(TEST_NAMES[:3], levels, LEVEL_NAMES):
        excitations[name] = (Multisine.random(period_s, band_hz, level, rng), "multisine", level, lname)
    duration = SWEEP_ACTIVE * n / fs
    lo, hi = band_hz
    excitations["sweep_low"] = (Sweep(lo, hi, duration, math.sqrt(2) * levels[0]), "sweep", levels[0], "low")
    excitations["sweep_high"] = (Sweep(hi, lo, duration, math.sqrt(2) * levels[2]), "sweep", levels[2], "high")
    runs = {name: (exc(t), rig.simulate(exc, n, fs, substeps)) for name, (exc, *_) in excitations.items()}
    # the noise: sized on the lowest-level multisine, the same sd in every test
    f_ref, y_ref = runs["ms_low"]
    tail = slice(period, n)
    sd_force = FORCE_NOISE * float(np.std(f_ref[tail]))
    sd_sensors = np.asarray(SENSOR_NOISE) * np.std(y_ref[tail], axis=0)
    off = OFFSETS * np.concatenate([[np.std(f_ref[tail])], np.std(y_ref[tail], axis=0)])
    names = [s for s, _ in SENSORS]
    noise_sd = {"force": sd_force, **{s: float(sd) for s, sd in zip(names, sd_sensors)}}
    records = []
    for name, (exc, kind, level, level_name) in excitations.items():
        f, y = runs[name]
        if clean is not None:
            clean[name] = (f.copy(), y.copy())
        e_f, e_y = rng.standard_normal(n), rng.standard_normal((n, 3))
        o = rng.standard_normal(4) * off
        fm, ym = f.copy(), y.copy()
        if noise:
            fm += sd_force * e_f
            ym += sd_sensors * e_y
        if offsets:
            fm += o[0]
            ym += o[1:]
        meta = {"force_rms_n": level, "band_hz": list(band_hz)}
        if kind == "sweep":
            meta["sweep_hz"] = [exc.f_start, exc.f_end]
        records.append(
            Record(
                f"{name}.csv",
                kind,
                level_name,
                roles[name],
                t,
                fm,
                ym,
                meta,
                sensors=SENSORS,
                period_samples=int(period) if kind == "multisine" else None,
                noise_sd=dict(noise_sd) if noise else {},
            )
        )
    truth = {**rig.truth(), "seed": int(seed), "levels_n": list(levels), "noise_sd": noise_sd, "substeps": substeps}
    return Dataset("gvt-wing", float(fs), None, records, {"truth": truth})


def truth(rig: GVTRig | None = None) -> dict:
    """The linear modes and the joint's (and every other) parameter of ``rig`` (default rig)."""
    return (rig or GVTRig()).truth()
