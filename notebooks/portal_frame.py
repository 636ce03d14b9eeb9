"""A lab-scale steel portal frame with a nonlinear beam-column joint, in OpenSeesPy.

A user's model file for ``bayes_update`` (docs/models.md): the class
:class:`PortalFrame` and the virtual rig :func:`make_dataset` that makes a data
folder from a finer version of it.

The frame (2-D, in the x-y plane, y up; SI units: m, kg, N, s)::

        m_top                         m_top
    TL o==============beam=============o TR   <- force F(t), horizontal, at TR
       |k_j, k2, k3 (joint)            |
       |                               |
  mid  x (sensor disp_mid)             |      columns: H = 0.60 m
       |                               |      beam:    L = 0.50 m
       |                               |
    ///////                        ///////    fixed bases

* columns: steel flat bars 40 x 8 mm bent about their weak axis, fixed at
  the base; beam: a 40 x 10 mm flat bar, rigidly welded to the right column;
* a lumped mass ``m_top`` [kg] at each top corner (both translations);
* the top-LEFT joint is a bolted connection: a rotational spring between the
  column top and the beam end (two coincident nodes, translations tied with
  ``equalDOF``, a ``zeroLength`` element on the rotation) with the moment-
  rotation law M = k_j theta + k2 theta^2 + k3 theta^3, tabulated into an
  ``ElasticMultiLinear`` material;
* members: ``ElasticTimoshenkoBeam`` (shear area 5/6 A; or ``elasticBeamColumn``,
  Euler-Bernoulli, 2.8 times slower per step in OpenSees 3.7) with the
  ``PDelta`` transformation and the consistent mass matrix (``-cMass``),
  E = 200 GPa, nu = 0.3, rho = 7850 kg/m^3;
* damping: Rayleigh, C = alpha M + beta K0, the ratio ``zeta`` on modes 1 and
  2 of an ``eigen`` of the frame at rest; K0 is the *initial* stiffness, the
  joint spring's included (``-doRayleigh 1``), so the damping stays linear
  viscous (the joint's k3 does not stiffen it);
* no gravity: no static preload; the P-Delta softening of the weight on the
  columns (about 35 N with m_top = 1 kg) would be about 0.3 % of the sway
  stiffness (21.8 kN/m at k_j = 0.5 kN m/rad), and is left out;
* time integration: generalized-alpha (``HHTGeneralized``, ``RHO_INF`` =
  0.95), ``substeps`` steps per sample, the recorded force interpolated
  band-limited between samples (:func:`upsample`), Newton to an unbalance of
  ``NEWTON_TOLERANCE``; a step that does not converge is retried in 10 then
  100 smaller steps, then the run raises ``ModelError``;
* excitation: the recorded force [N] horizontal at the top-right corner;
  response: two sensors, ``acc_top``, the horizontal acceleration [m/s^2] of
  the top-left corner, and ``disp_mid``, the horizontal displacement [m] of
  the left column at mid-height (a laser displacement sensor).

Modes (default mesh, at the rig's truth k_j = 0.5 kN m/rad, m_top = 1 kg):
11.1 Hz (sway), 82.7 Hz and 91.1 Hz (the columns bending against the
corner masses), 129 Hz; a rigid joint would put the sway mode at 13.2 Hz.

OpenSees keeps one global domain per process: every :meth:`PortalFrame.simulate`
wipes it and rebuilds everything, so runs never interleave (also in worker
processes), and sends OpenSees' messages to the null device.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import openseespy.opensees as ops

from bayes_update import ModelError, Parameter

# ------------------------------------------------------------------ the frame's constants
COLUMN_HEIGHT_M = 0.60  # base to beam axis [m]
BEAM_SPAN_M = 0.50  # column axis to column axis [m]
COLUMN_SECTION_M = (0.040, 0.008)  # flat bar width x thickness [m], bent about the weak axis
BEAM_SECTION_M = (0.040, 0.010)  # flat bar width x thickness [m]
YOUNGS_MODULUS_PA = 200e9  # steel [Pa]
POISSON_RATIO = 0.3  # steel [-]: shear modulus E / (2 (1 + nu))
SHEAR_COEFFICIENT = 5.0 / 6.0  # rectangular section: shear area = 5/6 A
DENSITY_KG_M3 = 7850.0  # steel [kg/m^3]
ROTATION_RANGE_RAD = 0.025  # the joint's table spans +- this rotation [rad]
TANGENT_FLOOR = 0.05  # the table ends where the joint's tangent falls below this share of k_j

K_J_UNIT = 1e3  # k_j in kN m/rad
K2_UNIT = 1e3  # k2 in kN m/rad^2
K3_UNIT = 1e6  # k3 in MN m/rad^3
#: generalized-alpha (Chung and Hulbert 1993; OpenSees HHTGeneralized(rho_inf)) with a spectral radius of
#: 0.95 at infinite frequency: it damps the ringing of the members' axial modes (kHz, far above the time
#: step's Nyquist frequency), which Newmark's average acceleration leaves undamped and which aliases into
#: the sampled acceleration (2 % of its rms at the low level against the continuous-time FRF, 0.6 % with
#: it: tests/test_portal_frame.py); second-order accurate, negligible damping in the band
RHO_INF = 0.95
NEWTON_TOLERANCE = 1e-6  # norm of the unbalanced forces [N, N m] at convergence
RIGID_COMPLIANCE = 1e-6  # a right-joint compliance c_r below this [rad/(kN m)] is the rigid weld

#: the member elements: both with the consistent (Hermite) mass matrix; the Timoshenko one adds the
#: flat bars' shear flexibility (-0.02 % on the sway frequency here) and costs 2.8 times less per step
ELEMENTS = ("ElasticTimoshenkoBeam", "elasticBeamColumn")

# node and element tags
_LEFT, _RIGHT, _BEAM = 100, 200, 300  # node tags: base + i (i = 0 at the bottom / the left end)
_SPRING_MAT, _RIGHT_MAT, _TRANSF, _FORCE_SERIES, _FORCE_PATTERN = 1, 2, 1, 1, 1


def _section(width_thickness):
    """(A [m^2], I [m^4], mass per length [kg/m]) of a flat bar bent about its weak axis."""
    b, t = width_thickness
    return b * t, b * t**3 / 12.0, DENSITY_KG_M3 * b * t


def upsample(force, factor: int, lobes: int = 10, beta: float = 9.0) -> np.ndarray:
    """Band-limited interpolation of the sampled force: ``(n - 1) * factor + 1``
    points, sample ``j * factor`` equal to ``force[j]``.

    A Kaiser-windowed sinc (``lobes`` zero crossings each side, Kaiser ``beta``),
    each polyphase branch normalised to unit gain; the force is taken as zero
    before the first and after the last sample (the record starts from rest).
    Error below 1e-4 of the amplitude up to 40 % of the Nyquist frequency
    (tests/test_portal_frame.py), where linear interpolation loses
    1 - sinc^2(f / fs): 3.7 % at 110 Hz with fs = 1024 Hz."""
    force = np.asarray(force, float)
    factor = int(factor)
    if factor == 1:
        return force.copy()
    k = np.arange(-lobes * factor, lobes * factor + 1)
    h = np.sinc(k / factor) * np.kaiser(k.size, beta)
    for p in range(factor):
        branch = (k % factor) == p
        h[branch] /= h[branch].sum()
    stuffed = np.zeros((force.size - 1) * factor + 1)
    stuffed[::factor] = force
    return np.convolve(stuffed, h, mode="same")


class PortalFrame:
    """The portal frame of the module docstring as a ``bayes_update`` model.

    Parameters (``theta``, each in its unit)
    ----------------------------------------
    k_j : rotational stiffness of the top-left joint [kN m/rad].
    k3 : cubic coefficient of the joint's moment-rotation law [MN m/rad^3]
        (M = k_j theta + k2 theta^2 + k3 theta^3).
    zeta : damping ratio of modes 1 and 2 [-].
    m_top : lumped mass at each top corner [kg].

    Candidate effects (the discrepancy workflow): ``k2``, the quadratic term of
    the joint [kN m/rad^2] (an asymmetric joint: it opens and closes with
    different stiffness); ``right_joint``, a linear rotational spring at the
    top-RIGHT joint of compliance ``c_r`` [rad/(kN m)] (the welded joint not
    quite rigid; its null, 0, is the rigid weld).

    Constructor
    -----------
    n_elements : elements per member (even: the mid-height sensor sits on a node).
    substeps : time steps per sample (generalized-alpha, ``RHO_INF``).
    table_points : points of the joint's moment-rotation table over
        +- ``ROTATION_RANGE_RAD`` (odd: zero rotation is a point).
    element : ``"ElasticTimoshenkoBeam"`` (default; shear area 5/6 A) or
        ``"elasticBeamColumn"`` (Euler-Bernoulli), both with the ``PDelta``
        transformation and the consistent mass matrix (``-cMass``).
    """

    parameters = [
        Parameter("k_j", 0.1, 3.2, unit="kN m/rad", log=True),
        Parameter("k3", 0.0, 150.0, unit="MN m/rad^3"),
        Parameter("zeta", 0.002, 0.05, log=True),
        Parameter("m_top", 0.5, 2.0, unit="kg"),
    ]
    sensors = (("acc_top", "acceleration"), ("disp_mid", "displacement"))

    def __init__(
        self, n_elements: int = 4, substeps: int = 5, table_points: int = 1001, element: str = "ElasticTimoshenkoBeam"
    ):
        if element not in ELEMENTS:
            raise ValueError(f"element must be one of {ELEMENTS}, got {element!r}")
        if n_elements < 2 or n_elements % 2:
            raise ValueError(f"n_elements must be even and >= 2 (a node at mid-height), got {n_elements}")
        if table_points < 21 or table_points % 2 == 0:
            raise ValueError(f"table_points must be odd (a point at zero rotation) and >= 21, got {table_points}")
        self.n_elements = int(n_elements)
        self.substeps = int(substeps)
        self.table_points = int(table_points)
        self.element = element

    def __repr__(self):
        return (
            f"PortalFrame(n_elements={self.n_elements}, substeps={self.substeps}, "
            f"table_points={self.table_points}, element={self.element!r})"
        )

    def refined(self) -> "PortalFrame":
        """Three times the elements per member and four times the time steps per sample.

        ``sample`` takes the model's error to be its difference to this frame, so
        this frame must be much closer to converged than the model: with twice the
        elements and steps the difference was 0.67-0.69 of the default frame's
        error against a finer one (the rig's frame), and the posterior put k_j and
        m_top 2.0-2.1 sd from the truth; with 3x and 4x it is 1.09-1.13 of it (the
        refined frame 0.17-0.19 from the rig's)."""
        return PortalFrame(3 * self.n_elements, 4 * self.substeps, self.table_points, self.element)

    def candidate_effects(self) -> dict:
        return {
            "k2": [Parameter("k2", -100.0, 100.0, unit="kN m/rad^2", null=0.0)],
            "right_joint": [Parameter("c_r", 0.0, 0.5, unit="rad/(kN m)", null=0.0)],
        }

    # ------------------------------------------------------------------ the joint
    def joint_table(self, theta) -> tuple[np.ndarray, np.ndarray]:
        """(rotation [rad], moment [N m]) points of the top-left joint's law.

        Over +- ``ROTATION_RANGE_RAD``, ``table_points`` points (zero among them),
        cut where the tangent k_j + 2 k2 t + 3 k3 t^2 falls below
        ``TANGENT_FLOOR`` k_j (a joint law that would soften to zero stiffness
        is not a joint the model can run beyond)."""
        kj = K_J_UNIT * theta["k_j"]
        k2 = K2_UNIT * theta.get("k2", 0.0)
        k3 = K3_UNIT * theta["k3"]
        t = np.linspace(-ROTATION_RANGE_RAD, ROTATION_RANGE_RAD, self.table_points)
        tangent = kj + 2 * k2 * t + 3 * k3 * t * t
        ok = tangent > TANGENT_FLOOR * kj
        zero = self.table_points // 2
        hi = zero + (np.argmin(ok[zero:]) if not ok[zero:].all() else self.table_points - zero)
        lo = zero - (np.argmin(ok[zero::-1]) if not ok[zero::-1].all() else zero + 1) + 1
        t = t[lo:hi]
        if t.size < 5:
            raise ModelError(f"the joint law has no stable range around zero rotation at {theta}")
        return t, kj * t + k2 * t * t + k3 * t**3

    # ------------------------------------------------------------------ the model
    def build(self, theta) -> dict:
        """Wipe OpenSees and build the frame at ``theta``; returns the node tags
        of interest: ``tl`` (top-left corner, the column's node), ``joint``
        (the beam end coincident with it), ``tr`` (top-right corner), ``mid``
        (left column at mid-height), the joint's element ``spring`` (its
        deformation is the joint rotation theta_joint - theta_tl) and the
        rotation range of its table ``table`` = (lo, hi) [rad]."""
        n = self.n_elements
        H, L = COLUMN_HEIGHT_M, BEAM_SPAN_M
        ops.wipe()
        ops.logFile(os.devnull, "-noEcho")
        ops.model("basic", "-ndm", 2, "-ndf", 3)
        for i in range(n + 1):
            ops.node(_LEFT + i, 0.0, H * i / n)
            ops.node(_RIGHT + i, L, H * i / n)
        c_r = float(theta.get("c_r", 0.0))
        right_spring = c_r > RIGID_COMPLIANCE
        for i in range(n + 1 if right_spring else n):  # rigid right joint: the beam ends on the column's top
            ops.node(_BEAM + i, L * i / n, H)
        tl, tr, joint = _LEFT + n, _RIGHT + n, _BEAM
        beam_nodes = [_BEAM + i for i in range(n + int(right_spring))] + ([] if right_spring else [tr])
        ops.fix(_LEFT, 1, 1, 1)
        ops.fix(_RIGHT, 1, 1, 1)
        ops.equalDOF(tl, joint, 1, 2)  # the joint: translations tied, rotation through the spring
        if right_spring:
            ops.equalDOF(tr, _BEAM + n, 1, 2)

        ops.geomTransf("PDelta", _TRANSF)
        E = YOUNGS_MODULUS_PA * float(theta.get("e_scale", 1.0))  # a model that updates the modulus
        G = E / (2.0 * (1.0 + POISSON_RATIO))
        tag = 0
        for chain, sec in (
            ([_LEFT + i for i in range(n + 1)], COLUMN_SECTION_M),
            ([_RIGHT + i for i in range(n + 1)], COLUMN_SECTION_M),
            (beam_nodes, BEAM_SECTION_M),
        ):
            A, Iz, mass = _section(sec)
            for a, b in zip(chain[:-1], chain[1:]):
                tag += 1
                if self.element == "elasticBeamColumn":
                    ops.element("elasticBeamColumn", tag, a, b, A, E, Iz, _TRANSF, "-mass", mass, "-cMass")
                else:
                    ops.element(
                        "ElasticTimoshenkoBeam",
                        tag,
                        a,
                        b,
                        E,
                        G,
                        A,
                        Iz,
                        SHEAR_COEFFICIENT * A,
                        _TRANSF,
                        "-mass",
                        mass,
                        "-cMass",
                    )
        t, M = self.joint_table(theta)
        ops.uniaxialMaterial("ElasticMultiLinear", _SPRING_MAT, 0.0, "-strain", *t.tolist(), "-stress", *M.tolist())
        tag += 1
        spring = tag
        ops.element("zeroLength", spring, tl, joint, "-mat", _SPRING_MAT, "-dir", 3, "-doRayleigh", 1)
        if right_spring:  # the right joint's compliance c_r [rad/(kN m)]
            ops.uniaxialMaterial("Elastic", _RIGHT_MAT, 1.0 / (c_r / K_J_UNIT))
            tag += 1
            ops.element("zeroLength", tag, tr, _BEAM + n, "-mat", _RIGHT_MAT, "-dir", 3, "-doRayleigh", 1)
        m = float(theta["m_top"])
        ops.mass(tl, m, m, 0.0)
        ops.mass(tr, m, m, 0.0)
        return {"tl": tl, "joint": joint, "tr": tr, "mid": _LEFT + n // 2, "spring": spring, "table": (t[0], t[-1])}

    def frequencies(self, theta, n_modes: int = 3) -> np.ndarray:
        """Undamped natural frequencies [Hz] of the frame at rest."""
        self.build(theta)
        lam = self._eigen(n_modes)
        ops.wipe()
        return np.sqrt(lam) / (2 * np.pi)

    @staticmethod
    def _eigen(n_modes):
        ops.constraints("Transformation")
        ops.numberer("RCM")
        ops.system("BandGeneral")
        lam = np.asarray(ops.eigen("-fullGenLapack", n_modes), float)
        ops.wipeAnalysis()
        if not np.all(lam > 0):
            raise ModelError(f"the frame has a non-positive eigenvalue {lam}")
        return lam

    def simulate(self, theta, force, fs):
        """(n, 2): the acceleration of the top-left corner [m/s^2] and the
        displacement of the left column at mid-height [m] (horizontal, +x to
        the right) at the force's samples, from rest; ``force`` [N] at the
        top-right corner, +x, sampled at ``fs`` [Hz], interpolated
        band-limited (:func:`upsample`) to ``substeps`` steps per sample."""
        force = np.asarray(force, float)
        return self.respond(theta, upsample(force, self.substeps), fs * self.substeps, self.substeps)

    def respond(self, theta, fine_force, fs_fine, stride: int, with_rotation: bool = False) -> np.ndarray:
        """The response to a force given at every time step (``fs_fine`` [Hz],
        linear between steps), read every ``stride`` steps: (m, 2) with
        m = (len(fine_force) - 1) // stride + 1; with ``with_rotation`` a third
        column, the rotation of the top-left joint's spring [rad]."""
        fine_force = np.asarray(fine_force, float)
        nodes = self.build(theta)
        lam = self._eigen(2)
        w1, w2 = np.sqrt(lam[:2])
        zeta = float(theta["zeta"])
        alpha_m = 2 * zeta * w1 * w2 / (w1 + w2)  # C = alpha_m M + beta_k K0: zeta at w1 and w2
        beta_k = 2 * zeta / (w1 + w2)
        ops.rayleigh(alpha_m, 0.0, beta_k, 0.0)
        h = 1.0 / fs_fine
        ops.timeSeries("Path", _FORCE_SERIES, "-dt", h, "-values", *fine_force.tolist())
        ops.pattern("Plain", _FORCE_PATTERN, _FORCE_SERIES)
        ops.load(nodes["tr"], 1.0, 0.0, 0.0)
        ops.constraints("Transformation")
        ops.numberer("RCM")
        ops.system("BandGeneral")
        # the unbalance after one Newton iteration is tiny (the members are linear, only the joint is
        # not): 1e-6 N (N m) converges in about one iteration a step, 7e-7 of the response from a
        # tolerance of 1e-12 m on the displacement increments, which takes two
        ops.test("NormUnbalance", NEWTON_TOLERANCE, 25, 0)
        ops.algorithm("Newton")
        ops.integrator("HHTGeneralized", RHO_INF)
        ops.analysis("Transient")
        m = (fine_force.size - 1) // stride + 1
        out = np.zeros((m, 3 if with_rotation else 2))
        lo, hi = nodes["table"]
        limit_lo, limit_hi = 0.9 * lo, 0.9 * hi
        tl, joint, mid = nodes["tl"], nodes["joint"], nodes["mid"]
        try:
            for k in range(1, m):
                if ops.analyze(stride, h) != 0:
                    self._retry(k * stride * h, h)
                rot = ops.nodeDisp(joint, 3) - ops.nodeDisp(tl, 3)
                if not limit_lo < rot < limit_hi:
                    raise ModelError(
                        f"the joint rotates {rot:.4g} rad at t = {k * stride * h:.4f} s, beyond 90 % "
                        f"of its law's table [{lo:.4g}, {hi:.4g}] rad"
                    )
                out[k, 0] = ops.nodeAccel(tl, 1)
                out[k, 1] = ops.nodeDisp(mid, 1)
                if with_rotation:
                    out[k, 2] = rot
        finally:
            ops.wipe()
        if not np.all(np.isfinite(out)):
            raise ModelError("the transient gave non-finite values")
        return out

    @staticmethod
    def _retry(t_end, h):
        """The sample's remaining steps again, each in 10 then 100 smaller steps;
        ModelError if that fails too."""
        while ops.getTime() < t_end - 1e-6 * h:
            step = min(h, t_end - ops.getTime())
            for parts in (10, 100):
                if ops.analyze(parts, step / parts) == 0:
                    break
            else:
                raise ModelError(
                    f"OpenSees did not converge at t = {ops.getTime():.5f} s, not even in steps of {step / 100:.3g} s"
                )


# ====================================================================== the virtual rig
RIG_FS_HZ = 1024.0  # acquisition rate [Hz]
RIG_PERIOD = 1024  # samples per period of the multisine (1 s: lines 1 Hz apart)
RIG_PERIODS = 2  # periods per test: the first holds the start transient
RIG_BAND_HZ = (2.0, 110.0)  # multisine lines in this band [Hz]: mode 1 (11 Hz) and modes 2-3 (83, 91 Hz)
RIG_FADE_IN_S = 0.05  # the generator's raised-cosine fade-in [s]; the frame starts at rest
RIG_LEVELS_N = {"low": 0.25, "medium": 3.0, "high": 6.0}  # force rms of each test [N]
RIG_ROLES = {"low": "linear", "medium": "validation", "high": "nonlinear"}
#: white measurement noise, sd per sample, per channel: force [N], acc_top [m/s^2], disp_mid [m]
RIG_NOISE_SD = {"force": 2e-3, "acc_top": 5e-3, "disp_mid": 3e-7}
#: typical sensor offsets (each test draws its own, normal with this sd), same units
RIG_OFFSET_SD = {"force": 0.02, "acc_top": 0.03, "disp_mid": 2e-5}
#: the truth of the rig's frame, each parameter in its unit (PortalFrame.parameters)
RIG_TRUTH = {"k_j": 0.5, "k3": 50.0, "zeta": 0.03, "m_top": 1.0}
#: the rig's finer frame: 1.5x the elements, 3x the time steps, 4x the table points of the default
RIG_MODEL = dict(n_elements=6, substeps=12, table_points=4001)


def multisine(period: int, n_periods: int, fs: float, band_hz, rng, oversampling: int = 1) -> np.ndarray:
    """``n_periods`` periods of ``period`` samples of a random-phase multisine with
    flat amplitudes on the lines k fs / period inside ``band_hz``, unit rms,
    evaluated exactly at ``oversampling`` points per sample
    ((n - 1) * oversampling + 1 points, n = period * n_periods), with the
    generator's fade-in (``RIG_FADE_IN_S``) at the start."""
    lines = np.arange(int(np.ceil(band_hz[0] * period / fs)), int(np.floor(band_hz[1] * period / fs)) + 1)
    X = np.zeros(period * oversampling // 2 + 1, complex)
    X[lines] = np.exp(2j * np.pi * rng.random(lines.size))
    x = np.fft.irfft(X, period * oversampling)
    x = np.tile(x / np.sqrt(np.mean(x**2)), n_periods + 1)[: (period * n_periods - 1) * oversampling + 1]
    t = np.arange(x.size) / (fs * oversampling)
    ramp = np.clip(t / RIG_FADE_IN_S, 0.0, 1.0)
    return x * (0.5 - 0.5 * np.cos(np.pi * ramp))


def make_dataset(
    folder,
    seed: int,
    hidden=None,
    truth=None,
    levels=None,
    period: int = RIG_PERIOD,
    n_periods: int = RIG_PERIODS,
    fs: float = RIG_FS_HZ,
    band_hz=RIG_BAND_HZ,
    rig=None,
    measure_share: bool = True,
    log=print,
) -> dict:
    """The virtual rig: three tests of the frame written as a data folder
    (``dataset.json`` and one CSV per test, docs/models.md "The data").

    The data come from a finer frame (``RIG_MODEL``: more elements, more time
    steps, a denser joint table) driven by the generator's force itself (the
    exact multisine at every time step, not an interpolation of its samples),
    at ``truth`` (default ``RIG_TRUTH``) plus ``hidden`` (e.g. ``{"k2": 40.0}``,
    an effect of ``candidate_effects()`` the baseline model lacks).  Each test
    is ``n_periods`` periods of ``period`` samples (at ``fs`` [Hz]) of a
    random-phase multisine over ``band_hz`` (declared as ``period_samples``) at the
    level of ``levels`` (force rms [N], default ``RIG_LEVELS_N``), starting
    from rest with the generator's fade-in (the first period holds the start
    transient); the recorded channels get white noise
    (``RIG_NOISE_SD``, each channel its own) and an offset per test and
    channel (normal, ``RIG_OFFSET_SD``).  Every random draw comes from ``seed``.

    ``measure_share``: also run the high test's force at the low level and
    report the nonlinear share of the high-level response,
    ||y_high - (high / low) y_low|| / ||y_high|| per sensor (noise-free).

    ``rig``: the frame that makes the data (default ``PortalFrame(**RIG_MODEL)``).

    Returns a summary: the truth, the run times [s], the nonlinear share,
    the noise sd added and the files."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    truth = dict(RIG_TRUTH if truth is None else truth)
    full_truth = {**truth, **(hidden or {})}
    levels = dict(RIG_LEVELS_N if levels is None else levels)
    rig = rig or PortalFrame(**RIG_MODEL)
    q = rig.substeps
    rng = np.random.default_rng(seed)
    n_samples = period * n_periods
    names = [n for n, _ in PortalFrame.sensors]
    tests, times, clean = [], {}, {}
    for level in ("low", "high", "medium"):
        shape = multisine(period, n_periods, fs, band_hz, rng, oversampling=q)
        fine = levels[level] * shape
        t0 = time.perf_counter()
        y = rig.respond(full_truth, fine, fs * q, q)
        times[level] = time.perf_counter() - t0
        clean[level] = (shape, y)
        force = fine[::q]
        noise = {c: sd * rng.standard_normal(n_samples) for c, sd in RIG_NOISE_SD.items()}
        offset = {c: sd * rng.standard_normal() for c, sd in RIG_OFFSET_SD.items()}
        channels = {"force": force + noise["force"] + offset["force"]}
        for j, name in enumerate(names):
            channels[name] = y[:, j] + noise[name] + offset[name]
        file = f"multisine_{level}.csv"
        table = np.column_stack([np.arange(n_samples) / fs] + [channels[c] for c in ("force", *names)])
        np.savetxt(
            folder / file, table, delimiter=",", header=",".join(["time", "force", *names]), comments="", fmt="%.10g"
        )
        tests.append(
            {
                "file": file,
                "role": RIG_ROLES[level],
                "signal": "multisine",
                "level": level,
                "period_samples": period,
                "force_rms_n": levels[level],
            }
        )
    share = None
    if measure_share:
        shape, y_high = clean["high"]
        t0 = time.perf_counter()
        y_low = rig.respond(full_truth, levels["low"] * shape, fs * q, q)
        times["share_check"] = time.perf_counter() - t0
        scaled = levels["high"] / levels["low"] * y_low
        share = {
            name: float(np.linalg.norm(y_high[:, j] - scaled[:, j]) / np.linalg.norm(y_high[:, j]))
            for j, name in enumerate(names)
        }
    units = {p.name: p.unit for p in type(rig).parameters}
    units.update({p.name: p.unit for ps in rig.candidate_effects().values() for p in ps})
    doc = {
        "name": "portal-frame-virtual-rig",
        "sampling_rate_hz": fs,
        "sensors": [{"name": n, "response": k} for n, k in PortalFrame.sensors],
        "tests": tests,
        "truth": {**full_truth, "units": {k: units[k] for k in full_truth}},
        "virtual_rig": {
            "model": repr(rig),
            "seed": seed,
            "band_hz": list(band_hz),
            "noise_sd_added": RIG_NOISE_SD,
            "nonlinear_share": share,
            "note": "notebooks/portal_frame.py make_dataset",
        },
    }
    (folder / "dataset.json").write_text(json.dumps(doc, indent=2))
    if log:
        log(f"virtual rig {rig!r} at {full_truth}: " + ", ".join(f"{k} {v:.1f} s" for k, v in times.items()))
        if share:
            log(
                "nonlinear share of the high-level response: "
                + ", ".join(f"{k} {100 * v:.1f} %" for k, v in share.items())
            )
    return {
        "truth": full_truth,
        "times_s": times,
        "nonlinear_share": share,
        "noise_sd": dict(RIG_NOISE_SD),
        "folder": str(folder),
        "files": [t["file"] for t in tests],
    }
