"""A model of the wrong form: a linear oscillator calibrated on the records of a
hysteretic (Bouc-Wen) one.  `calibrate` must say that the model misses the
high-level test (fit_warnings, in the result and the JSON), and `sample` must
end with a message and exit status 2 once its start is found, never run on
to a traceback.

The records: m x'' + c x' + a k x + (1 - a) k z = f with the Bouc-Wen
hysteresis z' = x' - b |x'| z - g x' |z| (n = 1), integrated by RK4 at 16
steps per sample with the force linear between samples; band-limited noise
forces at three levels, displacement recorded, 1 % noise on the response and
0.5 % on the force.  At the low level z stays far below its ceiling
1 / (b + g) and the oscillator is nearly linear; at the high level it yields.
Every constant is this file's own.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from new_user_kit import FS, Spring, band_noise
from numba import njit

import bayes_update as bu
from bayes_update.core.checks import ModelFitError

MASS = 0.224  # [kg]: 24 Hz on the elastic stiffness
K = 5.1e3  # [N/m]
C = 6.0  # [N s/m]
ALPHA = 0.08  # post-yield stiffness ratio
BETA, GAMMA = 2.2e3, 1.4e3  # [1/m]: z's ceiling 1 / (b + g) = 0.28 mm
SUBSTEPS = 16
N = 4096
LEVELS = (("weak", "linear", 0.08), ("strong", "nonlinear", 6.0), ("middle", "validation", 3.0))


@njit(cache=False)
def _rhs(x, v, z, f):
    a = (f - C * v - ALPHA * K * x - (1.0 - ALPHA) * K * z) / MASS
    dz = v - BETA * abs(v) * z - GAMMA * v * abs(z)
    return v, a, dz


@njit(cache=False)
def bouc_wen(force, fs):
    h = 1.0 / (fs * SUBSTEPS)
    x = v = z = 0.0
    out = np.zeros(force.size)
    for i in range(force.size - 1):
        for s in range(SUBSTEPS):
            f0 = force[i] + (force[i + 1] - force[i]) * s / SUBSTEPS
            f1 = force[i] + (force[i + 1] - force[i]) * (s + 1) / SUBSTEPS
            fm = 0.5 * (f0 + f1)
            k1 = _rhs(x, v, z, f0)
            k2 = _rhs(x + 0.5 * h * k1[0], v + 0.5 * h * k1[1], z + 0.5 * h * k1[2], fm)
            k3 = _rhs(x + 0.5 * h * k2[0], v + 0.5 * h * k2[1], z + 0.5 * h * k2[2], fm)
            k4 = _rhs(x + h * k3[0], v + h * k3[1], z + h * k3[2], f1)
            x += h / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            v += h / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
            z += h / 6.0 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
        out[i + 1] = x
    return out


@pytest.fixture(scope="module")
def hysteretic_data():
    from bayes_update.data.dataset import Dataset, Record

    rng = np.random.default_rng(29)
    t = np.arange(N) / FS
    tests = []
    for i, (name, role, level) in enumerate(LEVELS):
        f = band_noise(N, level, 31 + i)
        y = bouc_wen(f, FS)
        tests.append(
            Record(
                f"{name}.csv",
                "noise",
                name,
                role,
                t,
                f + 0.005 * np.std(f) * rng.standard_normal(N),
                y + 0.01 * np.std(y) * rng.standard_normal(N),
                sensors=(("displacement", "displacement"),),
            )
        )
    return Dataset("bouc_wen", FS, None, tests)


def test_calibrate_says_the_linear_model_misses_the_hysteretic_test(hysteretic_data):
    """Measured: the linear model misses the weak test by 28 %, the strong one by 109 % and the
    held-out one by 111 % of their rms (the noise allows 1 %); the strong test's Volterra
    projection leaves 92 % unexplained; the tests put k 6.9 sd apart."""
    cal = bu.calibrate(hysteretic_data, Spring(), workers=1, progress=False, log=lambda *a: None)
    errors = {k: round(v["rel"], 4) for k, v in cal.output_errors.items()}
    print(f"\n[wrong form] output errors {errors}; warnings {cal.fit_warnings}")
    assert errors["strong"] > 0.5 and errors["middle"] > 0.5, errors
    missed = next(w for w in cal.fit_warnings if w.startswith("the model misses"))
    assert "test strong by" in missed and "test middle by" in missed and "discrepancy" in missed, missed
    assert any("Volterra projection" in w and "test strong" in w for w in cal.fit_warnings), cal.fit_warnings
    assert cal.calibration_json()["fit_warnings"] == cal.fit_warnings


def test_sample_stops_after_its_start_with_a_message(hysteretic_data):
    # the full start (every parameter fitted, coarse_start off): the check runs right after it,
    # before any MAP; the message gives each test's miss against what noise allows, and the remedy
    with pytest.raises(ModelFitError, match="strong") as info:
        bu.sample(
            hysteretic_data,
            Spring(),
            bu.PosteriorSettings.quick(coarse_start=False),
            workers=1,
            progress=False,
            log=lambda *a: None,
        )
    msg = str(info.value)
    print(f"\n[wrong form] sample: {msg}")
    for test in ("weak", "strong"):
        assert re.search(rf"test {test} by \d+ % of its rms \(noise allows [\d.]+ %\)", msg), msg
    assert "bayes-update discrepancy" in msg and "MAP" not in msg, msg


def test_with_a_coarse_start_sample_stops_after_its_map(hysteretic_data):
    # the default start is coarse (it fits part of the parameters): the check waits for the MAP
    with pytest.raises(ModelFitError, match="MAP") as info:
        bu.sample(hysteretic_data, Spring(), bu.PosteriorSettings(), workers=1, progress=False, log=lambda *a: None)
    assert "strong" in str(info.value), info.value


def test_the_command_line_ends_in_one_line_with_status_2(hysteretic_data, tmp_path, capsys):
    from bayes_update.cli import main
    from bayes_update.data.folder import write_dataset

    write_dataset(hysteretic_data, tmp_path / "data")
    rc = main(
        [
            "sample",
            "--quick",
            "--workers",
            "1",
            "--model",
            "new_user_kit:Spring",
            "--data",
            str(tmp_path / "data"),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2, err[-3000:]
    assert "Traceback" not in err
    (line,) = [ln for ln in err.splitlines() if "error:" in ln]
    assert "strong" in line, line
    assert not (tmp_path / "out").exists()
