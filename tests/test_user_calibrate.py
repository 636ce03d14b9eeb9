"""``calibrate`` on a model it has never seen, with the physics partly wrong.

The test structure: a Duffing oscillator whose sensor has an unknown gain and
whose damping grows with amplitude (a quadratic damper, c2 v|v|); the model
being calibrated has the gain and the cubic spring but not the quadratic
damper.  Data from a finer version (16 RK4 steps per sample against 4), 1 %
RMS noise on both channels, a low-level filtered-noise test (linear), a
high-level multisine (nonlinear) and a medium-level multisine held out
(validation), at a sampling rate that is not a round number.

The independent reference is a direct output-error fit of the same model
(scipy ``least_squares`` on the time histories of both estimation tests,
each weighted by its noise), computed here: ``calibrate`` with the ``full``
metric set must predict the held-out test within 1.1x of its error.
"""

import numpy as np
import pytest
from numba import njit
from scipy.optimize import least_squares
from scipy.signal import butter, sosfiltfilt

from bayes_update import Parameter


@njit(cache=False)
def _velocity(f, fs, wn, zeta, k3, c2, substeps):
    """m = 1 kg: x'' + 2 zeta wn x' + c2 x'|x'| + wn^2 x + k3 x^3 = f (RK4, force linear between samples)."""
    h, x, v = 1.0 / (fs * substeps), 0.0, 0.0
    out = np.zeros(f.size)
    for i in range(f.size - 1):
        for s in range(substeps):
            u0, u1 = f[i] + (f[i + 1] - f[i]) * s / substeps, f[i] + (f[i + 1] - f[i]) * (s + 1) / substeps
            um = 0.5 * (u0 + u1)
            k1x, k1v = v, u0 - 2 * zeta * wn * v - c2 * v * abs(v) - wn * wn * x - k3 * x**3
            xa, va = x + 0.5 * h * k1x, v + 0.5 * h * k1v
            k2x, k2v = va, um - 2 * zeta * wn * va - c2 * va * abs(va) - wn * wn * xa - k3 * xa**3
            xb, vb = x + 0.5 * h * k2x, v + 0.5 * h * k2v
            k3x, k3v = vb, um - 2 * zeta * wn * vb - c2 * vb * abs(vb) - wn * wn * xb - k3 * xb**3
            xc, vc = x + h * k3x, v + h * k3v
            k4x, k4v = vc, u1 - 2 * zeta * wn * vc - c2 * vc * abs(vc) - wn * wn * xc - k3 * xc**3
            x, v = x + h * (k1x + 2 * k2x + 2 * k3x + k4x) / 6, v + h * (k1v + 2 * k2v + 2 * k3v + k4v) / 6
        out[i + 1] = v
    return out


class GainDuffing:
    """Sensor reading = gain x velocity; the quadratic damper ``c2`` [kg/m] is not a parameter."""

    parameters = [
        Parameter("fn", 30.0, 50.0, unit="Hz"),
        Parameter("zeta", 0.005, 0.08, log=True),
        Parameter("gain", 0.5, 2.0, unit="V/(m/s)"),
        Parameter("k3", 0.0, 40.0, unit="1e6 N/m^3"),
    ]

    def __init__(self, substeps=4, c2=0.0):
        self.substeps, self.c2 = substeps, c2

    def simulate(self, theta, force, fs):
        v = _velocity(
            np.asarray(force, float),
            fs,
            2 * np.pi * theta["fn"],
            theta["zeta"],
            1e6 * theta["k3"],
            self.c2,
            self.substeps,
        )
        return theta["gain"] * v


TRUTH = {"fn": 41.3, "zeta": 0.02, "gain": 1.3, "k3": 12.0}
C2 = 0.6  # quadratic damper of the truth [kg/m]: the model has none
FS = 1187.5  # [Hz]


def _multisine(n, level, seed):
    t = np.arange(n) / FS
    freqs = np.arange(20.0, 70.0, 0.5)
    phases = np.random.default_rng(seed).uniform(0, 2 * np.pi, freqs.size)
    f = np.sin(2 * np.pi * freqs[:, None] * t + phases[:, None]).sum(axis=0)
    return level * f / np.sqrt(np.mean(f**2))


def _filtered_noise(n, level, seed):
    sos = butter(4, [15.0, 80.0], btype="band", fs=FS, output="sos")
    f = sosfiltfilt(sos, np.random.default_rng(seed).standard_normal(n))
    return level * f / np.sqrt(np.mean(f**2))


def make_dataset(n=8192, seed=0):
    """Returns (dataset, noise sd of each test's response)."""
    import fe
    from bayes_update.data.dataset import Dataset, Record

    truth = GainDuffing(substeps=16, c2=C2)
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    tests, noise = [], {}
    for name, role, force in (
        ("noise_low", "linear", _filtered_noise(n, 0.5, seed + 1)),
        ("multisine_high", "nonlinear", _multisine(n, 30.0, seed + 2)),
        ("multisine_mid", "validation", _multisine(n, 18.0, seed + 3)),
    ):
        y = truth.simulate(TRUTH, force, FS)
        sf, sy = 0.01 * np.sqrt(np.mean(force**2)), 0.01 * np.sqrt(np.mean(y**2))
        noise[name] = sy
        tests.append(
            Record(
                f"{name}.csv",
                "multisine",
                name,
                role,
                t,
                force + sf * rng.standard_normal(n),
                y + sy * rng.standard_normal(n),
            )
        )
    return Dataset("gain-duffing", FS, fe.Rig(), tests), noise


def output_error_fit(dataset, noise, model, x0):
    """Direct output-error fit of ``model`` on the linear and nonlinear tests."""
    names = [p.name for p in model.parameters]
    est = [t for t in dataset.tests if t.role in ("linear", "nonlinear")]

    def residual(x):
        theta = dict(zip(names, x))
        return np.concatenate([(t.velocity - model.simulate(theta, t.force, FS)) / noise[t.name] for t in est])

    lo = [p.low for p in model.parameters]
    hi = [p.high for p in model.parameters]
    x0 = [x0[n] for n in names]
    return dict(zip(names, least_squares(residual, x0, bounds=(lo, hi), x_scale=np.subtract(hi, lo)).x))


def validation_error(dataset, model, theta):
    t = dataset.by_role("validation")[0]
    y = model.simulate(theta, t.force, FS)
    return float(np.linalg.norm(t.velocity - y) / np.linalg.norm(t.velocity))


@pytest.fixture(scope="module")
def gain_data():
    return make_dataset()


@pytest.fixture(scope="module")
def calibrations(gain_data):
    from bayes_update.core.calibrate import calibrate_model

    ds, _ = gain_data
    return {
        m: calibrate_model(ds, GainDuffing(), metrics=m, workers=2, progress=False, log=lambda *a: None)
        for m in ("full", "paper")
    }


def test_full_metrics_predict_held_out_data_like_an_output_error_fit(gain_data, calibrations):
    ds, noise = gain_data
    model = GainDuffing()
    oe = output_error_fit(ds, noise, model, TRUTH)
    e_oe = validation_error(ds, model, oe)
    # the model's physics is wrong: at the truth's parameters it predicts the held-out test
    # worse than its best fit, so the comparison is about fitting a wrong model well
    assert validation_error(ds, model, TRUTH) > 1.5 * e_oe
    full = calibrations["full"]
    assert full.prediction_errors["multisine_mid"] <= 1.1 * e_oe, (full.prediction_errors, e_oe)
    # ... which the paper's metrics do not: e_nlin drops the high-level test's y1, and J1 = 2
    # leaves the gain and the damping to the high-level test's y2 + y3 (measured 1.69x)
    assert calibrations["paper"].prediction_errors["multisine_mid"] > 1.3 * e_oe


def test_the_screen_finds_the_linear_parameters_and_sizes_j1(calibrations):
    full = calibrations["full"]
    assert full.linear_parameters == ["fn", "zeta", "gain"]
    assert full.n_functions[0] == 4
    assert full.unidentified == {"linear": [], "nonlinear": []}
    # with J1 = 2 the linear test has two coefficients for three parameters: calibrate says so
    # and names the direction (damping against gain: both set the resonance amplitude)
    paper = calibrations["paper"]
    assert paper.n_functions[0] == 2
    (direction,) = paper.unidentified["linear"]
    loadings = direction["direction"]
    assert abs(loadings["zeta"]) > 0.3 and abs(loadings["gain"]) > 0.3 and abs(loadings["fn"]) < 0.1


@pytest.mark.parametrize("n_linear, j1", [(0, 2), (1, 2), (2, 4), (3, 4), (4, 6), (5, 6)])
def test_j1_outnumbers_the_linear_parameters(n_linear, j1):
    from bayes_update.core.basis import linear_n_functions

    assert linear_n_functions(n_linear) == (j1, 2, 6)


def test_weights_are_the_measured_noise_and_the_representation_floor_is_apart():
    """The tests are weighted by their measured noise (bayes_update.core.weights), which
    the noise estimator finds in each record (here its quiet band), never by the
    residual of the record's own Volterra fit: that residual also holds what orders
    1-3 cannot represent, which is reported apart as the representation floor.  The
    reference for the floor: the noise-free record's own residual in the same basis."""
    import fe
    from bayes_update.core import Problem
    from bayes_update.data.dataset import Dataset, Record

    n = 8192
    t = np.arange(n) / FS
    model = GainDuffing()
    theta = {**TRUTH, "k3": 0.0}
    rng = np.random.default_rng(5)
    clean, noisy, sd = {}, [], {}
    for i, (name, role, level) in enumerate((("low", "linear", 0.5), ("high", "nonlinear", 5.0))):
        f = _filtered_noise(n, level, seed=i)
        y = model.simulate(theta, f, FS)
        sd[role] = 0.02 * np.sqrt(np.mean(y**2))
        clean[role] = y - y.mean()
        noisy.append(Record(f"{name}.csv", "noise", name, role, t, f, y + sd[role] * rng.standard_normal(n)))
    p = Problem(Dataset("noisy", FS, fe.Rig(), noisy), model)
    for role in ("linear", "nonlinear"):
        assert p.noise_sd(role) == pytest.approx(sd[role], rel=0.15)  # the sensor noise, not the residual
        y = clean[role]
        comps = p.projector(role).components(y)
        clean_floor = np.linalg.norm(y - sum(comps.values())) / np.linalg.norm(y)
        assert p.representation_floor(role) == pytest.approx(clean_floor, abs=0.01)


def test_a_record_of_1e5_samples_runs_through_calibrate():
    from bayes_update.core.calibrate import calibrate_model

    ds, _ = make_dataset(n=100_000, seed=3)
    cal = calibrate_model(ds, GainDuffing(), n_start=16, workers=2, progress=False, log=lambda *a: None)
    assert cal.problem.tests["nonlinear"].force.size == 100_000
    # the quadratic damper is still missing: the linear parameters land close, k3 absorbs some of it
    assert cal.theta["fn"] == pytest.approx(TRUTH["fn"], rel=1e-3)
    assert cal.theta["gain"] == pytest.approx(TRUTH["gain"], rel=0.01)
    assert cal.theta["zeta"] == pytest.approx(TRUTH["zeta"], rel=0.1)
    assert cal.prediction_errors["multisine_mid"] < 0.02


def test_cli_calibrate_with_a_model_from_a_file(tmp_path, gain_data):
    import json
    import subprocess
    import sys

    from bayes_update.data.folder import write_dataset

    ds, _ = gain_data
    write_dataset(ds, tmp_path / "data")
    out = tmp_path / "out"
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "bayes_update",
            "calibrate",
            "--model",
            f"{__file__}:GainDuffing",
            "--data",
            str(tmp_path / "data"),
            "--out",
            str(out),
            "--quick",
            "--workers",
            "2",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert res.returncode == 0, res.stderr[-3000:]
    cal = json.loads((out / "calibration.json").read_text())
    assert {"fn", "zeta", "gain", "k3", "e_lin", "e_nlin"} <= set(cal)
    assert cal["metric_set"] == "full"
    assert cal["fn"] == pytest.approx(TRUTH["fn"], rel=1e-3)
    assert set(cal["prediction_errors"]) == {"multisine_mid"}
    assert (out / "calibration_fit.png").stat().st_size > 20_000
    assert "prediction error on validation test multisine_mid" in res.stdout
    # the data set's first look comes with the calibration: the mode the data show, near the truth's
    look = json.loads((out / "inspection" / "inspection.json").read_text())
    assert [m["freq_hz"] for m in look["modes"]] == [pytest.approx(TRUTH["fn"], rel=0.01)], look["modes"]
    assert (out / "inspection" / "modes.png").exists()
