"""Several modes in the excited band, through ``bu.calibrate`` and the CLI.

The issue: a two-mass chain with an accelerometer on the second mass and both
modes (near 18 and 47 Hz) inside a 5-80 Hz multisine stopped calibrate with
"the refined linear fit leaves 51 % of ||y|| unexplained" (one mode's linear
fit cannot hold the other's response).  Here: ground -k1 (+ cubic k3 x1^3)-
m1 -k2- m2, dampers c on both springs, the force and the accelerometer on m2
(the accelerometer sees the force directly: a feed-through), modes at 17.9 and
46.9 Hz, a periodic 5-80 Hz multisine (4 periods, the first a transient) at
three levels.  The data come from the same model at 16 RK4 steps per sample,
the model calibrated takes 4; 1 % white noise on the response, 0.5 % on the
force, the noise found by the framework from the periods.  Every constant
below is this file's own.
"""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from numba import njit

import bayes_update as bu

FS = 400.0  # [Hz]: 5x the band's top
PERIOD = 2048  # [samples]
BAND = (5.0, 80.0)  # [Hz]
N_PERIODS = 4
M1, M2 = 0.9, 0.45  # [kg], known
TRUTH = {"k1": 19.0, "k2": 23.5, "c": 4.0, "k3": 0.2}  # kN/m, kN/m, N s/m, GN/m^3
LEVELS = {"low": ("linear", 0.15, 11), "high": ("nonlinear", 3.0, 12), "mid": ("validation", 1.8, 13)}
NOISE = (0.005, 0.01)  # force, response: sd / rms
# at about twice the accuracy measured (the same data both ways: calibrate and the CLI's --quick):
PARAMETER_TOL = 0.003  # relative, every parameter (measured at most 0.15 %, k3)
FLOOR_FACTOR = 1.01  # held-out error / the truth's (measured 1.0036)


@njit(cache=False)
def _rhs(x1, v1, x2, v2, u, k1, k2, c, k3):
    a1 = (-k1 * x1 - k3 * x1**3 - c * v1 + k2 * (x2 - x1) + c * (v2 - v1)) / 0.9
    a2 = (u - k2 * (x2 - x1) - c * (v2 - v1)) / 0.45
    return a1, a2


@njit(cache=False)
def _acceleration(f, fs, k1, k2, c, k3, substeps):
    """RK4 from rest, ``substeps`` steps per sample, the force linear between samples; m2's acceleration."""
    h = 1.0 / (fs * substeps)
    x1 = v1 = x2 = v2 = 0.0
    out = np.zeros(f.size)
    out[0] = _rhs(x1, v1, x2, v2, f[0], k1, k2, c, k3)[1]
    for i in range(f.size - 1):
        for s in range(substeps):
            u0 = f[i] + (f[i + 1] - f[i]) * s / substeps
            u1 = f[i] + (f[i + 1] - f[i]) * (s + 1) / substeps
            um = 0.5 * (u0 + u1)
            p1, p2 = _rhs(x1, v1, x2, v2, u0, k1, k2, c, k3)
            q1, q2 = _rhs(x1 + 0.5 * h * v1, v1 + 0.5 * h * p1, x2 + 0.5 * h * v2, v2 + 0.5 * h * p2, um, k1, k2, c, k3)
            r1, r2 = _rhs(
                x1 + 0.5 * h * (v1 + 0.5 * h * p1),
                v1 + 0.5 * h * q1,
                x2 + 0.5 * h * (v2 + 0.5 * h * p2),
                v2 + 0.5 * h * q2,
                um,
                k1,
                k2,
                c,
                k3,
            )
            s1, s2 = _rhs(
                x1 + h * (v1 + 0.5 * h * q1), v1 + h * r1, x2 + h * (v2 + 0.5 * h * q2), v2 + h * r2, u1, k1, k2, c, k3
            )
            x1, v1 = x1 + h * v1 + h * h * (p1 + q1 + r1) / 6, v1 + h * (p1 + 2 * q1 + 2 * r1 + s1) / 6
            x2, v2 = x2 + h * v2 + h * h * (p2 + q2 + r2) / 6, v2 + h * (p2 + 2 * q2 + 2 * r2 + s2) / 6
        out[i + 1] = _rhs(x1, v1, x2, v2, f[i + 1], k1, k2, c, k3)[1]
    return out


class TwoMassChain:
    """The two-mass chain of the module docstring; m2's acceleration [m/s^2]."""

    parameters = [
        bu.Parameter("k1", 12.0, 30.0, unit="kN/m"),
        bu.Parameter("k2", 15.0, 35.0, unit="kN/m"),
        bu.Parameter("c", 1.0, 15.0, unit="N s/m"),
        bu.Parameter("k3", 0.0, 1.0, unit="GN/m^3"),
    ]

    def __init__(self, substeps=4):
        self.substeps = substeps

    def simulate(self, theta, force, fs):
        return _acceleration(
            np.asarray(force, float),
            float(fs),
            1e3 * theta["k1"],
            1e3 * theta["k2"],
            float(theta["c"]),
            1e9 * theta["k3"],
            self.substeps,
        )


def natural_frequencies(theta) -> np.ndarray:
    k1, k2 = 1e3 * theta["k1"], 1e3 * theta["k2"]
    w2 = np.linalg.eigvals(np.linalg.solve(np.diag([M1, M2]), [[k1 + k2, -k2], [-k2, k2]]))
    return np.sort(np.sqrt(w2.real)) / (2 * np.pi)


def multisine(level, seed):
    rng = np.random.default_rng(seed)
    k = np.arange(int(np.ceil(BAND[0] * PERIOD / FS)), int(BAND[1] * PERIOD / FS) + 1)
    X = np.zeros(PERIOD // 2 + 1, complex)
    X[k] = np.exp(2j * np.pi * rng.random(k.size))
    x = np.fft.irfft(X, PERIOD)
    return level * np.tile(x / x.std(), N_PERIODS)


def make_dataset():
    """(data set, {test: noise-free response})."""
    truth_model = TwoMassChain(substeps=16)
    rng = np.random.default_rng(2)
    tests, clean = [], {}
    for name, (role, level, seed) in LEVELS.items():
        f = multisine(level, seed)
        y = truth_model.simulate(TRUTH, f, FS)
        clean[name] = y
        tests.append(
            bu.Record(
                f"{name}.csv",
                "multisine",
                name,
                role,
                np.arange(f.size) / FS,
                f + NOISE[0] * f.std() * rng.standard_normal(f.size),
                y + NOISE[1] * y.std() * rng.standard_normal(f.size),
                sensors=(("acc2", "acceleration"),),
                period_samples=PERIOD,
            )
        )
    return bu.Dataset("two-mass-chain", FS, None, tests), clean


def held_out_error(data, theta) -> float:
    t = data.test("mid")
    y = t.response - t.response.mean()
    m = TwoMassChain().simulate(theta, t.force - t.force.mean(), FS)
    return float(np.linalg.norm(y - (m - m.mean())) / np.linalg.norm(y))


@pytest.fixture(scope="module")
def data():
    return make_dataset()


def test_both_modes_are_in_the_band_and_in_the_basis(data):
    ds, _ = data
    f = natural_frequencies(TRUTH)
    assert BAND[0] < f[0] < 20.0 and 45.0 < f[1] < BAND[1], f
    p = bu.Problem(ds, TwoMassChain())
    found = sorted(m.freq_hz for m in p.basis.modes(1))
    assert np.allclose(found, f, rtol=0.01), (found, f)


def _check(theta, pred, ds, where):
    floor = held_out_error(ds, TRUTH)
    print(f"\n[{where}] {theta}; held-out error {pred:.5f}, at the truth {floor:.5f} (ratio {pred / floor:.4f})")
    for name, value in TRUTH.items():
        assert theta[name] == pytest.approx(value, rel=PARAMETER_TOL), (where, name, theta[name])
    assert pred <= FLOOR_FACTOR * floor, (where, pred, floor)


def test_calibrate_with_both_modes(data):
    ds, _ = data
    t0 = time.perf_counter()
    cal = bu.calibrate(ds, TwoMassChain(), workers=1, progress=False, log=lambda *a: None)
    print(f"\n[calibrate] {cal.n_model_runs} model runs, {time.perf_counter() - t0:.1f} s; warnings {cal.fit_warnings}")
    # the record does not end at rest, so the model's acceleration has a mean: calibrate's number is
    # the one Problem.prediction_errors gives (both without the means), and this file's
    assert cal.prediction_errors["mid"] == pytest.approx(cal.problem.prediction_errors(cal.theta)["mid"], rel=1e-9)
    assert cal.prediction_errors["mid"] == pytest.approx(held_out_error(ds, cal.theta), rel=1e-6)
    _check(cal.theta, cal.prediction_errors["mid"], ds, "calibrate")
    assert cal.disagreement == []
    # orders 2-3 on the mode the ground spring acts through (17.9 Hz), not on the accelerometer's
    # most energetic one (46.9 Hz), where the high-level projection left 18 % of its rms unexplained
    assert cal.problem.basis.modes(2)[0].freq_hz == pytest.approx(natural_frequencies(TRUTH)[0], rel=0.005)
    assert cal.problem.representation_floor("nonlinear") < 0.05
    assert cal.fit_warnings == []


def test_the_cli_calibrates_with_both_modes(data, tmp_path, capsys):
    from bayes_update.cli import main

    ds, _ = data
    bu.write_dataset(ds, tmp_path / "data")
    out = tmp_path / "out"
    t0 = time.perf_counter()
    code = main(
        [
            "calibrate",
            "--model",
            f"{__file__}:TwoMassChain",
            "--data",
            str(tmp_path / "data"),
            "--out",
            str(out),
            "--quick",
            "--workers",
            "1",
        ]
    )
    assert code == 0, capsys.readouterr().err[-3000:]
    cal = json.loads((out / "calibration.json").read_text())
    print(f"\n[cli] {cal['n_model_runs']} model runs, {time.perf_counter() - t0:.1f} s")
    assert len(cal["setup"]["basis"]["orders"]["1"]["modes"]) == 2
    _check({n: cal[n] for n in TRUTH}, cal["prediction_errors"]["mid"], ds, "cli")


def test_calibrates_sd_covers_the_error_of_a_model_whose_force_is_linear_between_samples():
    """A lab's force is band-limited between samples; the user's model takes it linear there
    (a model error of 2.7 % of the response, which calibrate's sd measures against the model
    run at twice the rate on a band-limited force).  Records made by the chain at 16x the rate
    on the polyphase-interpolated force: the damping comes out 4.7-5.2 % low (three noise
    seeds), 1.4 of calibrate's (Laplace) sd and 321 of the fit's white-noise Gauss-Newton sd
    (k2 45, k3 58 of them); every parameter measured within 1.44 Laplace sd (bar 3)."""
    from scipy.signal import resample_poly

    rng = np.random.default_rng(100)
    tests = []
    for name, (role, level, seed) in LEVELS.items():
        f = multisine(level, seed)
        fine = resample_poly(f, 16, 1)[: 16 * f.size - 15]
        y = TwoMassChain(substeps=1).simulate(TRUTH, fine, 16 * FS)[::16]
        noisy_f = f + NOISE[0] * f.std() * rng.standard_normal(f.size)
        noisy_y = y + NOISE[1] * y.std() * rng.standard_normal(f.size)
        tests.append(
            bu.Record(
                f"{name}.csv",
                "multisine",
                name,
                role,
                np.arange(f.size) / FS,
                noisy_f,
                noisy_y,
                sensors=(("acc2", "acceleration"),),
                period_samples=PERIOD,
            )
        )
    ds = bu.Dataset("band-limited force", FS, None, tests)
    cal = bu.calibrate(ds, TwoMassChain(), workers=1, progress=False, log=lambda *a: None)
    fit_only = bu.calibrate(ds, TwoMassChain(), workers=1, progress=False, log=lambda *a: None, uncertainty=False)
    z = {n: (cal.theta[n] - v) / cal.sd[n] for n, v in TRUTH.items()}
    z_gn = {n: (cal.theta[n] - v) / fit_only.sd[n] for n, v in TRUTH.items()}
    print(f"\n[band-limited force] error in Laplace sd {z}; in GN sd {z_gn}")
    assert all(abs(v) < 3.0 for v in z.values()), z
    assert abs(z_gn["c"]) > 30, z_gn  # the white-noise sd would have put the truth far outside
