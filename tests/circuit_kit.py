"""An electronic oscillator recorded as a benchmark rig records it, and a user's model of
another form (a test helper: no tests here).

The rig (the "structure"): a second-order circuit whose restoring force is cubic
and a little asymmetric, whose damping grows with the velocity, behind an input
filter and read through a first-order output filter (the amplifier's bandwidth):

    x'' + 2 z w x' (1 + nu x'^2) + w^2 (x + k2 x^2 + k3 x^3) = w^2 g v(t),
    v' = (u - v) / tau_in,   y' = (x - y) / tau_out,

integrated by scipy's adaptive DOP853 on a continuous excitation (random-phase
odd multisines and a filtered noise whose amplitude grows along the record), the
output read on a 6x grid and decimated through an anti-alias filter, noise added
to both channels.  Every test is a fresh realisation of its excitation.

The user's model (:class:`Oscillator`): f0 [Hz], zeta, a gain and k3, nothing
else: no quadratic stiffness, no nonlinear damping, no filters.  That is what a
user who reads "Duffing oscillator" writes, and what the rig is not: the model
misses every test by more than its noise, in a way no parameter value removes.
:class:`OscillatorWithCandidates` is the same model offering the discrepancy
workflow two candidate effects, a quadratic stiffness (k2) and a damping growing
with the velocity squared (nu); the filters stay outside the catalogue.

Every constant here is this module's own.
"""

from __future__ import annotations

import numba
import numpy as np
from scipy import integrate, interpolate, signal

from bayes_update import Parameter
from bayes_update.data.dataset import Dataset, Record

FS_HZ = 420.0
F0_HZ = 41.3
ZETA = 0.031
GAIN = 1.7  # static gain [V/V]
K3 = 0.9  # [1/V^2]: hardening
K2 = -0.1  # [1/V]: the asymmetry the model lacks
NU = 2.0e-5  # [s^2/V^2]: damping growing with the velocity, which the model lacks
TAU_IN = 1.0 / (2 * np.pi * 3500.0)
TAU_OUT = 1.0 / (2 * np.pi * 2400.0)
NOISE = {"force": 2.0e-5, "response": 2.0e-4}  # sd [V]
OVERSAMPLING = 6
N_SAMPLES = 8192


def _excitation(kind: str, level: float, n: int, seed: int):
    """(cubic spline of u on a 24x grid, duration): an odd random-phase multisine on
    1-120 Hz (``"multisine"``), or a band-limited noise whose amplitude grows
    linearly along the record (``"arrow"``), rms ``level`` [V]."""
    rng = np.random.default_rng(seed)
    fine = 24
    total = n * fine
    fs = FS_HZ * fine
    pre = int(0.4 * fs)
    if kind == "multisine":
        period = total + pre
        X = np.zeros(period // 2 + 1, complex)
        lines = np.arange(1, int(120.0 * period / fs))
        lines = lines[lines % 2 == 1]
        X[lines] = np.exp(2j * np.pi * rng.random(lines.size))
        u = np.fft.irfft(X, period)
    else:
        sos = signal.butter(6, 120.0, fs=fs, output="sos")
        u = signal.sosfilt(sos, rng.standard_normal(total + pre))
        u *= np.linspace(0.15, 1.0, u.size)
    u *= level / np.sqrt(np.mean(u[pre:] ** 2))
    t = np.arange(u.size) / fs
    u *= 0.5 - 0.5 * np.cos(np.pi * np.clip(t / 0.2, 0.0, 1.0))  # from rest
    return interpolate.CubicSpline(t, u), pre / fs


def record(kind: str, level: float, seed: int, n: int = N_SAMPLES, k2: float = K2, nu: float = NU):
    """(u, y) as the rig gives them [V], without noise; ``k2`` [1/V] and ``nu`` [s^2/V^2]
    the rig's asymmetry and velocity-growing damping (the module's by default)."""
    spline, pre = _excitation(kind, level, n, seed)
    w = 2 * np.pi * F0_HZ
    knots, coef = spline.x, np.ascontiguousarray(spline.c)

    def rhs(t, s):
        return _rig_rhs(t, s, knots, coef, w, k2, nu)

    h = 1.0 / (FS_HZ * OVERSAMPLING)
    t = pre + np.arange(n * OVERSAMPLING) * h - 0.3
    t = np.concatenate([np.arange(0.0, t[0], h), t])
    sol = integrate.solve_ivp(rhs, (0.0, t[-1]), np.zeros(4), method="DOP853", t_eval=t, rtol=1e-9, atol=1e-12)
    if not sol.success:
        raise RuntimeError(f"the circuit's integration failed: {sol.message}")
    both = signal.resample_poly(np.column_stack([spline(t), sol.y[3]]), 1, OVERSAMPLING, axis=0)
    both = both[-n:]
    return both[:, 0], both[:, 1]


@numba.njit(cache=False)
def _rig_rhs(t, s, knots, coef, w, k2, nu):
    """The rig's state derivative; the input is the cubic spline (``knots``, ``coef``: scipy's
    piecewise-polynomial form on a uniform grid) evaluated here, not through scipy (65 s a
    record through Python calls, a few seconds here)."""
    x, dx, v, y = s[0], s[1], s[2], s[3]
    step = knots[1] - knots[0]
    i = min(max(int((t - knots[0]) / step), 0), coef.shape[1] - 1)
    d = t - knots[i]
    u = ((coef[0, i] * d + coef[1, i]) * d + coef[2, i]) * d + coef[3, i]
    out = np.empty(4)
    out[0] = dx
    out[1] = _accel(x, dx, v, w, ZETA, GAIN, k2, K3, nu)
    out[2] = (u - v) / TAU_IN
    out[3] = (x - y) / TAU_OUT
    return out


def make_dataset(tests, seed: int = 17, k2: float = K2, nu: float = NU) -> Dataset:
    """``tests``: [(name, role, kind, level [V], seed of its excitation)]; noise on both
    channels; ``k2``, ``nu``: the rig's (:func:`record`)."""
    rng = np.random.default_rng(seed)
    out = []
    for name, role, kind, level, s in tests:
        u, y = record(kind, level, s, k2=k2, nu=nu)
        out.append(
            Record(
                f"{name}.csv",
                kind,
                name,
                role,
                np.arange(u.size) / FS_HZ,
                u + NOISE["force"] * rng.standard_normal(u.size),
                y + NOISE["response"] * rng.standard_normal(y.size),
                sensors=(("out", "displacement"),),
            )
        )
    return Dataset("circuit", FS_HZ, None, out)


#: two independent estimation sets (each: a low-level noise test and a high-level multisine)
#: and the held-out tests both are judged on
SET_A = [("noise_low_a", "linear", "noise", 0.006, 501), ("ms_high_a", "nonlinear", "multisine", 0.03, 502)]
SET_B = [("noise_low_b", "linear", "noise", 0.006, 503), ("ms_high_b", "nonlinear", "multisine", 0.03, 504)]
HELD_OUT = [("arrow", "validation", "arrow", 0.025, 505), ("ms_mid", "validation", "multisine", 0.018, 506)]


@numba.njit(cache=False)
def _accel(x, dx, u, w, zeta, gain, k2, k3, nu):
    return w * w * (gain * u - x - k2 * x * x - k3 * x**3) - 2 * zeta * w * dx * (1.0 + nu * dx * dx)


@numba.njit(cache=False)
def _rk4(u, fs, f0, zeta, gain, k3, substeps, k2=0.0, nu=0.0):
    n = u.size
    h = 1.0 / (fs * substeps)
    w = 2 * np.pi * f0
    x = 0.0
    dx = 0.0
    out = np.zeros(n)
    for i in range(n - 1):
        for s in range(substeps):
            u0 = u[i] + (u[i + 1] - u[i]) * s / substeps
            u1 = u[i] + (u[i + 1] - u[i]) * (s + 1) / substeps
            um = 0.5 * (u0 + u1)
            a1 = _accel(x, dx, u0, w, zeta, gain, k2, k3, nu)
            x2, v2 = x + 0.5 * h * dx, dx + 0.5 * h * a1
            a2 = _accel(x2, v2, um, w, zeta, gain, k2, k3, nu)
            x3, v3 = x + 0.5 * h * v2, dx + 0.5 * h * a2
            a3 = _accel(x3, v3, um, w, zeta, gain, k2, k3, nu)
            x4, v4 = x + h * v3, dx + h * a3
            a4 = _accel(x4, v4, u1, w, zeta, gain, k2, k3, nu)
            x += h / 6.0 * (dx + 2 * v2 + 2 * v3 + v4)
            dx += h / 6.0 * (a1 + 2 * a2 + 2 * a3 + a4)
        out[i + 1] = x
    return out


class Oscillator:
    """The user's Duffing oscillator: x'' + 2 zeta w x' + w^2 (x + k3 x^3) = w^2 gain u."""

    parameters = [
        Parameter("f0", 30.0, 55.0, unit="Hz"),
        Parameter("zeta", 0.005, 0.12, log=True),
        Parameter("gain", 0.5, 5.0),
        Parameter("k3", 0.0, 10.0, unit="1/V^2"),
    ]

    def __init__(self, substeps: int = 4):
        self.substeps = int(substeps)

    def simulate(self, theta, force, fs):
        return _rk4(
            np.asarray(force, float), float(fs), theta["f0"], theta["zeta"], theta["gain"], theta["k3"], self.substeps
        )

    def refined(self):
        return Oscillator(4 * self.substeps)


class OscillatorWithCandidates(Oscillator):
    """:class:`Oscillator` with two candidate effects for the discrepancy workflow: a
    quadratic stiffness ``w^2 k2 x^2`` and a damping ``2 zeta w x' nu x'^2``."""

    def candidate_effects(self):
        return {
            "quadratic_stiffness": [Parameter("k2", -1.0, 1.0, unit="1/V", null=0.0)],
            "velocity_damping": [Parameter("nu", 0.0, 2.0e-3, unit="s^2/V^2", null=0.0)],
        }

    def simulate(self, theta, force, fs):
        return _rk4(
            np.asarray(force, float),
            float(fs),
            theta["f0"],
            theta["zeta"],
            theta["gain"],
            theta["k3"],
            self.substeps,
            theta.get("k2", 0.0),
            theta.get("nu", 0.0),
        )

    def refined(self):
        return OscillatorWithCandidates(4 * self.substeps)
