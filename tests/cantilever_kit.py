"""A continuous cantilever with a compliant clamp (a joint), recorded as a lab records
it, and a user's two-mode model of it with candidate effects (a test helper: no tests
here).

The structure: a steel strip 520 x 30 x 3 mm clamped through a rotational spring of
380 N m/rad (the joint), a 14 g tip mass (the accelerometer and its base): modes at
7.56 and 48.8 Hz where an ideal clamp without the mass gives 9.16 and 57.4; Rayleigh
damping (0.63 % and 0.40 % in the first two modes, 0.9-2.9 % above), discretised by
40 Hermite beam elements and reduced to its first five modes (to 465 Hz); optionally a cubic spring between
the tip and the ground (``tip_cubic``, a catalogue effect of the user's model).  A
shaker drives it at 30 % of the length with a continuous random-phase multisine or
a sweep; accelerometers at 60 % and at the tip; scipy's DOP853, anti-alias
filtering and decimation, noise on every channel.

The user's model (:class:`TwoModes`): the first two modes of an ideal uniform
cantilever (analytic shapes, the strip's mass), their frequencies and damping
ratios as parameters, RK4 at 4 steps per sample; candidate effects ``tip_cubic``
(k3) and ``tip_damper`` (a quadratic damper at the tip, c2).  What it lacks in
form: the higher modes (their quasi-static share of the acceleration), the clamp's
and the tip mass's change of the mode shapes, the modes' own damping law.

Every constant here is this module's own.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import integrate, interpolate, linalg, signal

from bayes_update import Parameter
from bayes_update.data.dataset import Dataset, Record

LENGTH, WIDTH, THICK = 0.52, 0.030, 0.003  # [m]
E, RHO = 2.05e11, 7850.0  # [Pa], [kg/m^3]
EI = E * WIDTH * THICK**3 / 12.0  # [N m^2]
RHO_A = RHO * WIDTH * THICK  # [kg/m]
K_CLAMP = 380.0  # [N m/rad]
TIP_MASS = 0.014  # [kg]
RAYLEIGH = (0.55, 2.0e-5)  # C = a M + b K
N_ELEMENTS, N_MODES = 40, 5
X_FORCE, X_SENSORS = 0.30, (0.60, 1.0)  # fractions of the length
SENSORS = (("mid", "acceleration"), ("tip", "acceleration"))
FS_HZ = 480.0
BAND_HZ = (3.0, 85.0)
K3_TRUTH = 4.0e6  # [N/m^3] of the tip spring, when present
NOISE = {"force": 2.0e-3, "mid": 0.02, "tip": 0.03}  # sd [N], [m/s^2]
N_SAMPLES = 6000
OVERSAMPLING = 8


def _fe_matrices():
    """Mass and stiffness of the strip (w, w' per node; the clamp's node keeps w = 0 and
    its rotation on the rotational spring), the tip mass at the last node."""
    n = N_ELEMENTS
    h = LENGTH / n
    k = (
        EI
        / h**3
        * np.array(
            [
                [12, 6 * h, -12, 6 * h],
                [6 * h, 4 * h * h, -6 * h, 2 * h * h],
                [-12, -6 * h, 12, -6 * h],
                [6 * h, 2 * h * h, -6 * h, 4 * h * h],
            ]
        )
    )
    m = (
        RHO_A
        * h
        / 420
        * np.array(
            [
                [156, 22 * h, 54, -13 * h],
                [22 * h, 4 * h * h, 13 * h, -3 * h * h],
                [54, 13 * h, 156, -22 * h],
                [-13 * h, -3 * h * h, -22 * h, 4 * h * h],
            ]
        )
    )
    N = 2 * (n + 1)
    K, M = np.zeros((N, N)), np.zeros((N, N))
    for e in range(n):
        s = slice(2 * e, 2 * e + 4)
        K[s, s] += k
        M[s, s] += m
    K[1, 1] += K_CLAMP
    M[-2, -2] += TIP_MASS
    keep = np.arange(1, N)  # w = 0 at the clamp
    return M[np.ix_(keep, keep)], K[np.ix_(keep, keep)]


def _shape_rows(x_frac):
    """The row picking w at a fraction of the length (a node; the clamp's w is removed)."""
    node = int(round(x_frac * N_ELEMENTS))
    row = np.zeros(2 * N_ELEMENTS + 1)
    row[2 * node - 1] = 1.0
    return row


def structure_modes():
    """(frequencies [Hz], modal damping ratios, mass-normalised shapes (dof, N_MODES))."""
    M, K = _fe_matrices()
    w2, V = linalg.eigh(K, M)
    w = np.sqrt(w2[:N_MODES])
    zeta = 0.5 * (RAYLEIGH[0] / w + RAYLEIGH[1] * w)
    return w / (2 * np.pi), zeta, V[:, :N_MODES]


def _excitation(kind: str, level: float, n: int, seed: int):
    rng = np.random.default_rng(seed)
    fine = 32
    fs = FS_HZ * fine
    pre = int(0.5 * fs)
    total = n * fine + 2 * pre
    t = np.arange(total) / fs
    if kind == "sweep":
        T = t[-1] - pre / fs
        f = BAND_HZ[0] * (BAND_HZ[1] / BAND_HZ[0]) ** (np.clip(t - pre / fs, 0, None) / T)
        u = np.sin(2 * np.pi * np.cumsum(f) / fs)
    else:
        period = 2 * total
        X = np.zeros(period // 2 + 1, complex)
        lines = np.arange(int(BAND_HZ[0] * period / fs), int(BAND_HZ[1] * period / fs))
        X[lines] = np.exp(2j * np.pi * rng.random(lines.size))
        u = np.fft.irfft(X, period)[:total]
    u *= 0.5 - 0.5 * np.cos(np.pi * np.clip((t - pre / fs) / 0.3, 0.0, 1.0))
    u *= level / np.sqrt(np.mean(u[pre:] ** 2))
    return interpolate.CubicSpline(t, u), pre / fs


def record(kind: str, level: float, seed: int, k3: float = 0.0, n: int = N_SAMPLES):
    """(force [N], accelerations (n, 2) [m/s^2]) without noise."""
    f_hz, zeta, V = structure_modes()
    w = 2 * np.pi * f_hz
    b = V.T @ _shape_rows(X_FORCE)
    out_rows = np.array([V.T @ _shape_rows(x) for x in X_SENSORS])
    tip = V.T @ _shape_rows(1.0)
    spline, pre = _excitation(kind, level, n, seed)

    def acc(q, dq, f):
        wt = tip @ q
        return b * f - tip * (k3 * wt**3) - 2 * zeta * w * dq - w * w * q

    def rhs(t, s):
        return np.concatenate([s[N_MODES:], acc(s[:N_MODES], s[N_MODES:], float(spline(t)))])

    h = 1.0 / (FS_HZ * OVERSAMPLING)
    t = np.arange(0.0, pre + (n + 40) / FS_HZ, h)
    sol = integrate.solve_ivp(
        rhs, (0.0, t[-1]), np.zeros(2 * N_MODES), method="DOP853", t_eval=t, rtol=1e-8, atol=1e-12
    )
    if not sol.success:
        raise RuntimeError(f"the cantilever's integration failed: {sol.message}")
    fv = spline(t)
    q, dq = sol.y[:N_MODES], sol.y[N_MODES:]
    ddq = b[:, None] * fv - tip[:, None] * (k3 * (tip @ q) ** 3) - (2 * zeta * w)[:, None] * dq - (w * w)[:, None] * q
    a = (out_rows @ ddq).T
    both = signal.resample_poly(np.column_stack([fv, a]), 1, OVERSAMPLING, axis=0)
    start = int(round(pre * FS_HZ))
    both = both[start : start + n]
    return both[:, 0], both[:, 1:]


#: (name, role, kind, force rms [N], seed)
TESTS = (
    ("random_low", "linear", "random", 0.03, 811),
    ("random_high", "nonlinear", "random", 0.45, 812),
    ("random_mid", "validation", "random", 0.25, 813),
    ("sweep_mid", "validation", "sweep", 0.3, 814),
)


def make_dataset(k3: float = 0.0, seed: int = 23, tests=TESTS) -> Dataset:
    """The cantilever's records, its tip spring ``k3`` [N/m^3] (0: none)."""
    rng = np.random.default_rng(seed)
    out = []
    for name, role, kind, level, s in tests:
        f, a = record(kind, level, s, k3)
        f = f + NOISE["force"] * rng.standard_normal(f.size)
        a = a + np.column_stack([NOISE[c] * rng.standard_normal(f.size) for c, _ in SENSORS])
        out.append(Record(f"{name}.csv", kind, name, role, np.arange(f.size) / FS_HZ, f, a, sensors=SENSORS))
    return Dataset("cantilever", FS_HZ, None, out, {"truth": {"tip_cubic_k3_N_m3": k3}})


# --------------------------------------------------------------------------- the user's model
_BETA = (1.875104, 4.694091)


def _cantilever_shape(x, i):
    """The ideal cantilever's mode i at x/L, normalised so that its mean square over the length is 1."""
    bl = _BETA[i]
    sigma = (np.sinh(bl) - np.sin(bl)) / (np.cosh(bl) + np.cos(bl))
    z = bl * x
    return np.cosh(z) - np.cos(z) - sigma * (np.sinh(z) - np.sin(z))


@numba.njit(cache=False)
def _modal_acc(q0, q1, d0, d1, f, w, zeta, b, tip, k3, c2, mass):
    wt = tip[0] * q0 + tip[1] * q1
    vt = tip[0] * d0 + tip[1] * d1
    fnl = k3 * wt**3 + c2 * abs(vt) * vt
    a0 = (b[0] * f - tip[0] * fnl) / mass - 2 * zeta[0] * w[0] * d0 - w[0] * w[0] * q0
    a1 = (b[1] * f - tip[1] * fnl) / mass - 2 * zeta[1] * w[1] * d1 - w[1] * w[1] * q1
    return a0, a1


@numba.njit(cache=False)
def _modal_rk4(F, substeps, fs, w, zeta, b, tip, rows, k3, c2, mass):
    """RK4 of the two modal coordinates from rest, the force on the half-step grid."""
    h = 1.0 / (fs * substeps)
    n_steps = (F.size - 1) // 2
    out = np.zeros((n_steps // substeps + 1, rows.shape[0]))
    q0 = q1 = d0 = d1 = 0.0
    a0, a1 = _modal_acc(q0, q1, d0, d1, F[0], w, zeta, b, tip, k3, c2, mass)
    for r in range(rows.shape[0]):
        out[0, r] = rows[r, 0] * a0 + rows[r, 1] * a1
    for j in range(n_steps):
        k10, k11 = _modal_acc(q0, q1, d0, d1, F[2 * j], w, zeta, b, tip, k3, c2, mass)
        k20, k21 = _modal_acc(
            q0 + 0.5 * h * d0,
            q1 + 0.5 * h * d1,
            d0 + 0.5 * h * k10,
            d1 + 0.5 * h * k11,
            F[2 * j + 1],
            w,
            zeta,
            b,
            tip,
            k3,
            c2,
            mass,
        )
        k30, k31 = _modal_acc(
            q0 + 0.5 * h * (d0 + 0.5 * h * k10),
            q1 + 0.5 * h * (d1 + 0.5 * h * k11),
            d0 + 0.5 * h * k20,
            d1 + 0.5 * h * k21,
            F[2 * j + 1],
            w,
            zeta,
            b,
            tip,
            k3,
            c2,
            mass,
        )
        k40, k41 = _modal_acc(
            q0 + h * (d0 + 0.5 * h * k20),
            q1 + h * (d1 + 0.5 * h * k21),
            d0 + h * k30,
            d1 + h * k31,
            F[2 * j + 2],
            w,
            zeta,
            b,
            tip,
            k3,
            c2,
            mass,
        )
        q0 += h * d0 + h * h / 6.0 * (k10 + k20 + k30)
        q1 += h * d1 + h * h / 6.0 * (k11 + k21 + k31)
        d0 += h / 6.0 * (k10 + 2 * k20 + 2 * k30 + k40)
        d1 += h / 6.0 * (k11 + 2 * k21 + 2 * k31 + k41)
        if (j + 1) % substeps == 0:
            a0, a1 = _modal_acc(q0, q1, d0, d1, F[2 * j + 2], w, zeta, b, tip, k3, c2, mass)
            for r in range(rows.shape[0]):
                out[(j + 1) // substeps, r] = rows[r, 0] * a0 + rows[r, 1] * a1
    return out


class TwoModes:
    """The user's two-mode model of the ideal cantilever; accelerations at 60 % and at the tip."""

    parameters = [
        Parameter("f1", 6.0, 12.0, unit="Hz"),
        Parameter("f2", 40.0, 75.0, unit="Hz"),
        Parameter("zeta1", 0.001, 0.05, log=True),
        Parameter("zeta2", 0.001, 0.05, log=True),
    ]

    def __init__(self, substeps: int = 4):
        self.substeps = int(substeps)

    def candidate_effects(self):
        return {
            "tip_cubic": [Parameter("k3", 0.0, 20.0, unit="MN/m^3", null=0.0)],
            "tip_damper": [Parameter("c2", 0.0, 40.0, unit="N s^2/m^2", null=0.0)],
        }

    def simulate(self, theta, force, fs):
        force = np.asarray(force, float)
        q = 2 * self.substeps
        F = signal.resample_poly(force, q, 1)[: q * (force.size - 1) + 1]
        shapes = lambda x: np.array([_cantilever_shape(x, i) for i in range(2)])  # noqa: E731
        return _modal_rk4(
            F,
            self.substeps,
            float(fs),
            2 * np.pi * np.array([theta["f1"], theta["f2"]]),
            np.array([theta["zeta1"], theta["zeta2"]]),
            shapes(X_FORCE),
            shapes(1.0),
            np.array([shapes(x) for x in X_SENSORS]),
            1e6 * theta.get("k3", 0.0),
            theta.get("c2", 0.0),
            RHO_A * LENGTH,
        )

    def refined(self):
        return TwoModes(4 * self.substeps)
