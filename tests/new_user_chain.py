"""A two-mass chain of a first-time user, its displacement measured, for the discrepancy tests
(tests/test_new_user_discrepancy.py): ground -k1,c- m1 -k2,c- m2, the force on m2, the sensor on m2.
The ground spring may be quadratic (``kq``: a broken symmetry, which also shifts the mean
displacement) or cubic (``kc``), the two candidate effects.  The constants are used nowhere else.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy import signal

from bayes_update import ModelError, Parameter

FS = 731.0  # [Hz]
M1, M2 = 1.3, 0.55  # [kg]
TRUTH = {"k1": 31.0, "k2": 17.5, "c": 9.0}  # kN/m, kN/m, N s/m


@njit(cache=False)
def _rhs(x1, v1, x2, v2, u, k1, k2, c, kq, kc):
    spring = k1 * x1 + kq * x1 * x1 + kc * x1 * x1 * x1
    a1 = (-spring - c * v1 + k2 * (x2 - x1) + c * (v2 - v1)) / 1.3
    a2 = (u - k2 * (x2 - x1) - c * (v2 - v1)) / 0.55
    return a1, a2


@njit(cache=False)
def chain_displacement(f, fs, k1, k2, c, kq, kc, substeps):
    """RK4 with ``substeps`` steps per sample, the force linear between samples; x2 [m] out."""
    h = 1.0 / (fs * substeps)
    x1 = v1 = x2 = v2 = 0.0
    out = np.zeros(f.size)
    for i in range(f.size - 1):
        for s in range(substeps):
            u0 = f[i] + (f[i + 1] - f[i]) * s / substeps
            u1 = f[i] + (f[i + 1] - f[i]) * (s + 1) / substeps
            um = 0.5 * (u0 + u1)
            a1, a2 = _rhs(x1, v1, x2, v2, u0, k1, k2, c, kq, kc)
            b1, b2 = _rhs(
                x1 + 0.5 * h * v1, v1 + 0.5 * h * a1, x2 + 0.5 * h * v2, v2 + 0.5 * h * a2, um, k1, k2, c, kq, kc
            )
            c1, c2 = _rhs(
                x1 + 0.5 * h * (v1 + 0.5 * h * a1),
                v1 + 0.5 * h * b1,
                x2 + 0.5 * h * (v2 + 0.5 * h * a2),
                v2 + 0.5 * h * b2,
                um,
                k1,
                k2,
                c,
                kq,
                kc,
            )
            d1, d2 = _rhs(
                x1 + h * (v1 + 0.5 * h * b1),
                v1 + h * c1,
                x2 + h * (v2 + 0.5 * h * b2),
                v2 + h * c2,
                u1,
                k1,
                k2,
                c,
                kq,
                kc,
            )
            x1, v1 = x1 + h * v1 + h * h * (a1 + b1 + c1) / 6, v1 + h * (a1 + 2 * b1 + 2 * c1 + d1) / 6
            x2, v2 = x2 + h * v2 + h * h * (a2 + b2 + c2) / 6, v2 + h * (a2 + 2 * b2 + 2 * c2 + d2) / 6
        out[i + 1] = x2
    return out


class Chain:
    """The linear chain; ``candidate_effects()``: a quadratic or a cubic ground spring."""

    parameters = [
        Parameter("k1", 20.0, 45.0, unit="kN/m"),
        Parameter("k2", 10.0, 25.0, unit="kN/m"),
        Parameter("c", 2.0, 30.0, unit="N s/m"),
    ]

    def __init__(self, substeps=2):
        self.substeps = substeps

    def candidate_effects(self):
        return {
            "quadratic_ground": [Parameter("kq", -6.0, 6.0, unit="MN/m^2", null=0.0)],
            "cubic_ground": [Parameter("kc", -8.0, 8.0, unit="GN/m^3", null=0.0)],
        }

    def simulate(self, theta, force, fs):
        x2 = chain_displacement(
            np.asarray(force, float),
            fs,
            1e3 * theta["k1"],
            1e3 * theta["k2"],
            theta["c"],
            1e6 * theta.get("kq", 0.0),
            1e9 * theta.get("kc", 0.0),
            self.substeps,
        )
        if not np.all(np.isfinite(x2)):
            raise ModelError("the softening ground spring let the chain run away")
        return x2

    def refined(self):
        return Chain(4 * self.substeps)


def make_dataset(hidden=None, n=4096, seed=5, levels=(0.5, 6.0, 4.0), offsets=(0.0, 0.0)):
    """Band-limited noise (8-70 Hz) on m2 at three levels: linear, nonlinear, validation; the data from
    the refined chain with ``hidden`` effect values, 1 % noise on force and response, and
    ``offsets`` = (force, response) sensor offsets in units of each channel's RMS."""
    from bayes_update.data.dataset import Dataset, Record

    truth = {**TRUTH, **(hidden or {})}
    model = Chain().refined()
    rng = np.random.default_rng(seed)
    sos = signal.butter(4, [8.0, 70.0], btype="band", fs=FS, output="sos")
    t = np.arange(n) / FS
    tests = []
    for i, (name, role) in enumerate(
        (("noise_low", "linear"), ("noise_high", "nonlinear"), ("noise_mid", "validation"))
    ):
        f = signal.sosfiltfilt(sos, rng.standard_normal(n))
        f *= levels[i] / np.std(f)
        y = model.simulate(truth, f, FS)
        f_meas = f + 0.01 * np.std(f) * rng.standard_normal(n) + offsets[0] * np.std(f)
        y_meas = y + 0.01 * np.std(y) * rng.standard_normal(n) + offsets[1] * np.std(y)
        tests.append(
            Record(
                f"{name}.csv", "noise", name.split("_")[1], role, t, f_meas, y_meas, sensors=(("tip", "displacement"),)
            )
        )
    return Dataset("chain", FS, None, tests, extra={"truth": truth})
