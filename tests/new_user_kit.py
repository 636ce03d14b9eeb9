"""Small models and data sets of a first-time user, for the tests/test_new_user_*.py files.

A linear single-degree-of-freedom oscillator driven through a bilinear (Tustin)
filter, so that a run costs well under a millisecond: displacement, velocity or
acceleration out, its stiffness in kN/m.  The constants here are used nowhere
else in the repository.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from bayes_update import Parameter

FS = 913.0  # [Hz]
TRUTH = {"fn": 23.7, "zeta": 0.031, "k": 4.6}  # Hz, -, kN/m
N_SAMPLES = 2048


def sdof_response(force, fs, fn, zeta, k_n_per_m, kind="displacement"):
    """Response of m x'' + c x' + k x = f (k in N/m, wn = 2 pi fn) to ``force``."""
    wn = 2 * np.pi * fn
    m = k_n_per_m / wn**2
    num = {"displacement": [1.0], "velocity": [1.0, 0.0], "acceleration": [1.0, 0.0, 0.0]}[kind]
    b, a = signal.bilinear(num, [m, 2 * zeta * wn * m, k_n_per_m], fs)
    return signal.lfilter(b, a, np.asarray(force, float))


class Spring:
    """A mass on a spring and a dashpot; the sensor measures ``kind``."""

    parameters = [
        Parameter("fn", 15.0, 35.0, unit="Hz"),
        Parameter("zeta", 0.005, 0.1, log=True),
        Parameter("k", 2.0, 8.0, unit="kN/m"),
    ]
    kind = "displacement"

    def simulate(self, theta, force, fs):
        return sdof_response(force, fs, theta["fn"], theta["zeta"], 1e3 * theta["k"], self.kind)


class VelocitySpring(Spring):
    kind = "velocity"


class AccelerationSpring(Spring):
    kind = "acceleration"


def band_noise(n, level, seed, band=(6.0, 70.0)):
    sos = signal.butter(4, band, btype="band", fs=FS, output="sos")
    f = signal.sosfiltfilt(sos, np.random.default_rng(seed).standard_normal(n))
    return level * f / np.std(f)


def make_dataset(
    kind="displacement", n=N_SAMPLES, seed=11, forces=None, truth=None, extra=None, sensor_name=None, validation=True
):
    """Linear (low), nonlinear (high) and validation (medium) band-limited noise tests of the spring,
    1 % noise on force and response.  ``forces``: {test name: force array} replacing a test's force."""
    from bayes_update.data.dataset import Dataset, Record

    truth = {**TRUTH, **(truth or {})}
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    sensors = ((sensor_name or kind, kind),)
    tests = []
    plan = [("quiet_low", "linear", 0.4), ("loud_high", "nonlinear", 3.0)]
    if validation:
        plan.append(("medium_check", "validation", 1.3))
    for i, (name, role, level) in enumerate(plan):
        f = band_noise(n, level, seed + i) if forces is None or name not in forces else forces[name]
        y = sdof_response(f, FS, truth["fn"], truth["zeta"], 1e3 * truth["k"], kind)
        f_meas = f + 0.01 * np.std(f) * rng.standard_normal(n) if np.std(f) > 0 else f
        y_meas = y + 0.01 * max(np.std(y), 1e-12) * rng.standard_normal(n)
        tests.append(Record(f"{name}.csv", "noise", name.split("_")[1], role, t, f_meas, y_meas, sensors=sensors))
    return Dataset("spring", FS, None, tests, extra=dict(extra or {}))
