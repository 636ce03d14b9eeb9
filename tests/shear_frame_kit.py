"""A three-storey shear frame recorded the way a laboratory records it, and a
user's model of it that may lack an effect (a test helper: no tests here).

The structure (the "truth"): floors of 2.35, 1.95 and 1.45 kg on storeys of
63, 48 and 34 kN/m (modes near 12.5, 29.9 and 42.5 Hz), the same modal
damping ratio in every mode, a cubic spring ``k_nl x1^3`` in the first
storey, a shaker on the top floor and an accelerometer on every floor.
Optionally it holds what the user's model lacks:

* ``damper``: a quadratic damper ``c_q |v1| v1`` in the first storey (damping
  that grows with amplitude, as joints and air give);
* ``stiffness``: a quadratic spring ``k_q (x2 - x1)^2`` in the second storey
  (an asymmetric storey, as a bolted or cracked one gives).

How it is recorded, in another form than the model that is fitted to it:
the force is a continuous-time random-phase multisine (a sum of cosines that
never repeats inside the record) held as a cubic spline on a 32x grid, the
frame is integrated by scipy's adaptive DOP853 (relative tolerance 1e-9),
the accelerations are read on an 8x grid, both channels go through the same
anti-alias filter and 8:1 decimation, and then white plus coloured noise is
added to every channel, the force included, with an offset per channel.  The
sensors' noise does not grow with the level (a few milli-g), so the low-level
test is the noisiest relative to its rms.

The user's model (:class:`ShearFrame`): the same masses (weighed), the
storeys' stiffness, one modal damping ratio and the cubic spring as
parameters, integrated by classic RK4 at a few steps per sample with the
force between samples interpolated band-limited (polyphase FIR); ``refined()``
takes 4x the steps.

Every constant here is this module's own.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import integrate, interpolate, linalg, signal

from bayes_update import Parameter
from bayes_update.data.dataset import Dataset, Record

MASSES_KG = (2.35, 1.95, 1.45)
TRUTH = {"k1": 63.0, "k2": 48.0, "k3": 34.0, "zeta": 0.017, "knl": 1.2}  # kN/m x3, -, GN/m^3
FS_HZ = 250.0
BAND_HZ = (5.0, 60.0)
N_SAMPLES = 6000  # 24 s
SENSORS = (("floor1", "acceleration"), ("floor2", "acceleration"), ("floor3", "acceleration"))
SENSOR_NOISE = (0.021, 0.017, 0.026)  # sd [m/s^2]
FORCE_NOISE = 0.006  # sd [N]
#: (name, role, force rms [N], seed of its multisine)
TESTS = (
    ("low", "linear", 0.9, 301),
    ("high", "nonlinear", 9.0, 302),
    ("middle", "validation", 5.0, 303),
    ("high_b", "validation", 9.0, 304),
)
#: strengths of the effects the user's model lacks
HIDDEN = {
    "damper": 22.0,  # c_q [N s^2/m^2]
    "stiffness": 1.0e6,
}  # k_q [N/m^2]
OVERSAMPLING = 8
PRE_ROLL_S = 0.6
RAMP_S = 0.4


def stiffness_matrix(k) -> np.ndarray:
    k1, k2, k3 = k
    return np.array([[k1 + k2, -k2, 0.0], [-k2, k2 + k3, -k3], [0.0, -k3, k3]])


def modal_damping(k, zeta: float) -> np.ndarray:
    """C = M V diag(2 zeta w) V^T M (V mass-normalised): every mode damped at ``zeta``."""
    M = np.diag(MASSES_KG)
    w2, V = linalg.eigh(stiffness_matrix(k), M)
    return M @ V @ np.diag(2.0 * zeta * np.sqrt(w2)) @ V.T @ M


def modes_hz(theta=None) -> np.ndarray:
    theta = {**TRUTH, **(theta or {})}
    k = 1e3 * np.array([theta["k1"], theta["k2"], theta["k3"]])
    return np.sqrt(linalg.eigh(stiffness_matrix(k), np.diag(MASSES_KG), eigvals_only=True)) / (2 * np.pi)


# ----------------------------------------------------------------- the structure
def _force_spline(level_n: float, n: int, seed: int):
    """A random-phase multisine on BAND_HZ of rms ``level_n`` over the record and its
    pre-roll (its period twice that, so it never repeats), as a cubic spline on a 32x grid."""
    rng = np.random.default_rng(seed)
    fine = 32
    total = int(round((n / FS_HZ + 2 * PRE_ROLL_S) * FS_HZ)) * fine
    period = 2 * total
    fs_fine = FS_HZ * fine
    lines = np.arange(int(np.ceil(BAND_HZ[0] * period / fs_fine)), int(BAND_HZ[1] * period / fs_fine) + 1)
    X = np.zeros(period // 2 + 1, complex)
    X[lines] = np.exp(2j * np.pi * rng.random(lines.size))
    x = np.fft.irfft(X, period)[: total + 1]
    x *= level_n / np.sqrt(np.mean(x**2))
    # at rest until the record starts, then a smooth (raised-cosine) start over RAMP_S: the
    # record begins at rest, as a test whose shaker is switched on after the acquisition is
    t = np.arange(total + 1) / fs_fine
    x *= 0.5 - 0.5 * np.cos(np.pi * np.clip((t - PRE_ROLL_S) / RAMP_S, 0.0, 1.0))
    return interpolate.CubicSpline(t, x), t[-1]


def _structure_rhs(theta: dict, hidden: dict):
    M_inv = 1.0 / np.asarray(MASSES_KG)
    k = 1e3 * np.array([theta["k1"], theta["k2"], theta["k3"]])
    K, C = stiffness_matrix(k), modal_damping(k, theta["zeta"])
    knl = 1e9 * theta["knl"]
    cq, kq = hidden.get("damper", 0.0), hidden.get("stiffness", 0.0)

    def accel(x, v, f):
        r = -C @ v - K @ x
        r[0] -= knl * x[0] ** 3 + cq * abs(v[0]) * v[0]
        d = x[1] - x[0]
        r[0] += kq * d * d
        r[1] -= kq * d * d
        r[2] += f
        return M_inv * r

    return accel


def record(level_n: float, seed: int, theta=None, hidden=None, n: int = N_SAMPLES):
    """(force [N], accelerations (n, 3) [m/s^2]) as the structure gives them, anti-alias
    filtered and decimated, without noise."""
    theta = {**TRUTH, **(theta or {})}
    accel = _structure_rhs(theta, dict(hidden or {}))
    spline, t_end = _force_spline(level_n, n, seed)

    def rhs(t, s):
        with np.errstate(over="ignore", invalid="ignore"):  # DOP853's rejected trial steps
            return np.concatenate([s[3:], accel(s[:3], s[3:], float(spline(t)))])

    h = 1.0 / (FS_HZ * OVERSAMPLING)
    t = np.arange(0.0, t_end - 1e-9, h)
    sol = integrate.solve_ivp(rhs, (0.0, t[-1]), np.zeros(6), method="DOP853", t_eval=t, rtol=1e-9, atol=1e-12)
    if not sol.success:
        raise RuntimeError(f"the shear frame's integration failed: {sol.message}")
    f = spline(t)
    acc = np.array([accel(sol.y[:3, i], sol.y[3:, i], f[i]) for i in range(t.size)])  # 0.2 s of the ~8 s
    both = signal.resample_poly(np.column_stack([f, acc]), 1, OVERSAMPLING, axis=0)
    pre = int(round(PRE_ROLL_S * FS_HZ))
    both = both[pre : pre + n]
    return both[:, 0], both[:, 1:]


def _noise(n: int, sd: float, rng) -> np.ndarray:
    """Half white, half first-order coloured noise of standard deviation ``sd``."""
    white = rng.standard_normal(n)
    col = signal.lfilter([1.0], [1.0, -0.7], rng.standard_normal(n + 300))[300:] * np.sqrt(1 - 0.49)
    return sd * (white + col) / np.sqrt(2.0)


def make_dataset(hidden=(), theta=None, tests=TESTS, seed: int = 7, n: int = N_SAMPLES) -> Dataset:
    """The frame's records: ``hidden`` names the effects of :data:`HIDDEN` the
    structure holds (the user's model lacks them); ``tests`` as :data:`TESTS`."""
    effects = {h: HIDDEN[h] for h in hidden}
    rng = np.random.default_rng(seed)
    out = []
    t = np.arange(n) / FS_HZ
    for name, role, level, s in tests:
        f, a = record(level, s, theta, effects, n)
        f_meas = f + _noise(n, FORCE_NOISE, rng) + 0.01
        a_meas = a + np.column_stack([_noise(n, sd, rng) for sd in SENSOR_NOISE]) + rng.normal(0, 0.05, 3)
        out.append(Record(f"{name}.csv", "random", name, role, t, f_meas, a_meas, sensors=SENSORS))
    truth = {
        "theta": {**TRUTH, **(theta or {})},
        "hidden": effects,
        "noise_sd": {"force": FORCE_NOISE, **{s: sd for (s, _), sd in zip(SENSORS, SENSOR_NOISE)}},
    }
    return Dataset("shear-frame", FS_HZ, None, out, {"truth": truth})


# ----------------------------------------------------------------- the user's model
@numba.njit(cache=False)
def _accel(x, v, f, minv, C, K, knl, cq, out):
    """out = M^-1 (f e3 - C v - K x - (knl x1^3 + cq |v1| v1) e1), written out for 3 degrees of freedom."""
    for i in range(3):
        r = -(C[i, 0] * v[0] + C[i, 1] * v[1] + C[i, 2] * v[2] + K[i, 0] * x[0] + K[i, 1] * x[1] + K[i, 2] * x[2])
        if i == 0:
            r -= knl * x[0] ** 3 + cq * abs(v[0]) * v[0]
        if i == 2:
            r += f
        out[i] = minv[i] * r


@numba.njit(cache=False)
def _frame_rk4(F, substeps, fs, minv, C, K, knl, cq):
    """RK4 from rest with the force ``F`` on the half-step grid (F[2 j] at step j); the
    accelerations at every ``substeps``-th step, (len(F) // (2 substeps) + 1, 3)."""
    h = 1.0 / (fs * substeps)
    n_steps = (F.size - 1) // 2
    out = np.zeros((n_steps // substeps + 1, 3))
    x, v = np.zeros(3), np.zeros(3)
    xs, vs = np.zeros(3), np.zeros(3)
    a1, a2, a3, a4 = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
    _accel(x, v, F[0], minv, C, K, knl, cq, a1)
    out[0] = a1
    for j in range(n_steps):
        _accel(x, v, F[2 * j], minv, C, K, knl, cq, a1)
        for i in range(3):
            xs[i] = x[i] + 0.5 * h * v[i]
            vs[i] = v[i] + 0.5 * h * a1[i]
        _accel(xs, vs, F[2 * j + 1], minv, C, K, knl, cq, a2)
        v2 = vs.copy()
        for i in range(3):
            xs[i] = x[i] + 0.5 * h * v2[i]
            vs[i] = v[i] + 0.5 * h * a2[i]
        _accel(xs, vs, F[2 * j + 1], minv, C, K, knl, cq, a3)
        v3 = vs.copy()
        for i in range(3):
            xs[i] = x[i] + h * v3[i]
            vs[i] = v[i] + h * a3[i]
        _accel(xs, vs, F[2 * j + 2], minv, C, K, knl, cq, a4)
        for i in range(3):
            x[i] += h / 6.0 * (v[i] + 2 * v2[i] + 2 * v3[i] + vs[i])
            v[i] += h / 6.0 * (a1[i] + 2 * a2[i] + 2 * a3[i] + a4[i])
        if (j + 1) % substeps == 0:
            _accel(x, v, F[2 * j + 2], minv, C, K, knl, cq, a1)
            out[(j + 1) // substeps] = a1
    return out


class ShearFrame:
    """The user's model: three storeys (kN/m), one modal damping ratio, a cubic
    first storey (GN/m^3); floors weighed; RK4 at ``substeps`` per sample."""

    parameters = [
        Parameter("k1", 40.0, 90.0, unit="kN/m"),
        Parameter("k2", 30.0, 70.0, unit="kN/m"),
        Parameter("k3", 20.0, 50.0, unit="kN/m"),
        Parameter("zeta", 0.004, 0.08, log=True),
        Parameter("knl", 0.0, 10.0, unit="GN/m^3"),
    ]

    def __init__(self, substeps: int = 3):
        self.substeps = int(substeps)

    def simulate(self, theta, force, fs):
        k = 1e3 * np.array([theta["k1"], theta["k2"], theta["k3"]])
        K, C = stiffness_matrix(k), modal_damping(k, theta["zeta"])
        # the force between samples band-limited (polyphase FIR), as the records' anti-alias
        # filter left it: linear interpolation would cut the gain by 9 % at the third mode
        force = np.asarray(force, float)
        q = 2 * self.substeps
        F = signal.resample_poly(force, q, 1)[: q * (force.size - 1) + 1]
        return _frame_rk4(
            F,
            self.substeps,
            float(fs),
            1.0 / np.asarray(MASSES_KG),
            C,
            K,
            1e9 * theta["knl"],
            float(theta.get("cq", 0.0)),
        )

    def refined(self):
        return type(self)(4 * self.substeps)


class ShearFrameWithDamper(ShearFrame):
    """The same model with the first storey's quadratic damper c_q [N s^2/m^2] as a parameter."""

    parameters = ShearFrame.parameters + [Parameter("cq", 0.0, 60.0, unit="N s^2/m^2")]
