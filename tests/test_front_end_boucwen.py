"""The hysteretic oscillator of issue 40, made as a new user would make it, through ``bu.calibrate``.

On the previous release the right model calibrated to 0.2 %; the release
after stopped ``calibrate`` and ``sample`` for the right model and the wrong
one alike ("the frequency of the mode near 61.52 Hz ran to the edge of its
search range"), and ``inspect`` warned that the sensor's noise differed 735x
between tests (the high-level test's quiet band holding its harmonics).

The records (this file's own generator and constants): a Bouc-Wen
single-degree-of-freedom oscillator (m x'' + c x' + alpha k x + (1 - alpha) k z
= f, z' = v - beta |v| z - beta v |z|, beta = 1 / (2 x_y): z saturates at the
yield displacement x_y), fn = 25 Hz, zeta = 2 %, alpha = 0.35, x_y = 1.2 mm,
the acceleration measured; a random-phase multisine 5-60 Hz (lines of a
32.768 s period: it does not repeat inside the 16.384 s record) sampled at
1 kHz; integrated by scipy's solve_ivp (DOP853, rtol 1e-9) on the cubic
spline through the input at 8 kHz, anti-alias filtered and decimated;
white noise of 1 % of the low-level test's rms on the force and the
accelerometer (the same sd in every test: a sensor's noise floor).  Three
tests: low level (displacement rms 0.3 % of x_y: linear), high level (150 %:
strongly hysteretic), a validation test (80 %).

The user's model (``BoucWen``, a model of the contract, docs/models.md)
integrates the same physics by classic RK4 at 4 steps per sample on the
recorded force interpolated band-limited (``scipy.signal.resample_poly``, 4x;
linear between those samples): another scheme, step and interpolation than
the generator's.  (With the force linear between the recorded samples, the
model's response at the truth is 0.6 % of the high-level test's rms off the
record, 34x the noise: docs/models.md, "What the samples of the force mean".)
"""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from scipy import signal
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

import bayes_update as bu
import volterra
from bayes_update.data.inspect import inspect_dataset
from bayes_update.data.noise import dataset_noise

FS = 1000.0  # [Hz]
N = 16384  # samples per test
BAND = (5.0, 60.0)  # [Hz]
FINE = 8  # the generator's grid: FINE x fs
MASS = 1.7  # [kg], known to the user
TRUTH = {"fn": 25.0, "zeta": 0.02, "alpha": 0.35, "xy": 1.2}  # Hz, -, -, mm
LEVELS = {"low": ("linear", 0.003, 401), "high": ("nonlinear", 1.5, 402), "check": ("validation", 0.8, 403)}
NOISE = 0.01  # sd / the low-level test's rms, force and acceleration
PARAMETER_TOL = 0.01  # the bar: every parameter within 1 %


def _physics(theta):
    k = MASS * (2 * np.pi * theta["fn"]) ** 2
    return k, 2 * theta["zeta"] * np.sqrt(k * MASS), theta["alpha"], 0.5 / (1e-3 * theta["xy"])


def multisine(seed):
    """Unit-rms samples on the FINE grid of a random-phase multisine 5-60 Hz with lines
    of a period twice the record (it does not repeat inside it)."""
    rng = np.random.default_rng(seed)
    n = 2 * N * FINE
    k = np.arange(int(np.ceil(BAND[0] * 2 * N / FS)), int(BAND[1] * 2 * N / FS) + 1)
    X = np.zeros(n // 2 + 1, complex)
    X[k] = np.exp(2j * np.pi * rng.random(k.size))
    x = np.fft.irfft(X, n)[: N * FINE]
    return x / x.std()


def generate(force_fine, theta):
    """(force, acceleration) at FS from the fine-grid force: solve_ivp on its cubic spline."""
    k, c, alpha, beta = _physics(theta)
    h = 1.0 / (FS * FINE)
    t = np.arange(force_fine.size) * h
    c3, c2, c1, c0 = (row.tolist() for row in CubicSpline(t, force_fine).c)
    last = force_fine.size - 2

    def rhs(tt, s):
        x, v, z = s
        i = min(int(tt / h), last)
        d = tt - i * h
        f = ((c3[i] * d + c2[i]) * d + c1[i]) * d + c0[i]
        return (v, (f - c * v - alpha * k * x - (1 - alpha) * k * z) / MASS, v - beta * abs(v) * z - beta * v * abs(z))

    sol = solve_ivp(
        rhs, (0.0, t[-1]), [0.0, 0.0, 0.0], method="DOP853", t_eval=t, rtol=1e-9, atol=[1e-12, 1e-10, 1e-12]
    )
    assert sol.success, sol.message
    x, v, z = sol.y
    acc = (force_fine - c * v - alpha * k * x - (1 - alpha) * k * z) / MASS
    both = signal.resample_poly(np.column_stack([force_fine, acc]), 1, FINE, axis=0)
    return both[:, 0], both[:, 1], x


@njit(cache=False)
def _rk4(f, fs, k, c, alpha, beta, m, substeps):
    """RK4 from rest, one step per sample of ``f`` (sampled at ``fs``), the force linear
    between them; the acceleration at every ``substeps``-th sample."""
    h = 1.0 / fs
    x = v = z = 0.0
    out = np.empty(f.size // substeps)
    out[0] = f[0] / m
    for i in range(f.size - 1):
        f0, f1 = f[i], f[i + 1]
        fm = 0.5 * (f0 + f1)
        kx, kv, kz = (
            v,
            (f0 - c * v - alpha * k * x - (1 - alpha) * k * z) / m,
            v - beta * abs(v) * z - beta * v * abs(z),
        )
        x2, v2, z2 = x + 0.5 * h * kx, v + 0.5 * h * kv, z + 0.5 * h * kz
        lx, lv, lz = (
            v2,
            (fm - c * v2 - alpha * k * x2 - (1 - alpha) * k * z2) / m,
            v2 - beta * abs(v2) * z2 - beta * v2 * abs(z2),
        )
        x3, v3, z3 = x + 0.5 * h * lx, v + 0.5 * h * lv, z + 0.5 * h * lz
        mx, mv, mz = (
            v3,
            (fm - c * v3 - alpha * k * x3 - (1 - alpha) * k * z3) / m,
            v3 - beta * abs(v3) * z3 - beta * v3 * abs(z3),
        )
        x4, v4, z4 = x + h * mx, v + h * mv, z + h * mz
        nx, nv, nz = (
            v4,
            (f1 - c * v4 - alpha * k * x4 - (1 - alpha) * k * z4) / m,
            v4 - beta * abs(v4) * z4 - beta * v4 * abs(z4),
        )
        x += h * (kx + 2 * lx + 2 * mx + nx) / 6
        v += h * (kv + 2 * lv + 2 * mv + nv) / 6
        z += h * (kz + 2 * lz + 2 * mz + nz) / 6
        if (i + 1) % substeps == 0:
            out[(i + 1) // substeps] = (f[i + 1] - c * v - alpha * k * x - (1 - alpha) * k * z) / m
    return out


class BoucWen:
    """The user's model: a Bouc-Wen oscillator of known mass, its acceleration [m/s^2]."""

    parameters = [
        bu.Parameter("fn", 20.0, 30.0, unit="Hz"),
        bu.Parameter("zeta", 0.005, 0.08, log=True),
        bu.Parameter("alpha", 0.1, 0.7),
        bu.Parameter("xy", 0.3, 4.0, unit="mm", log=True),
    ]

    def simulate(self, theta, force, fs):
        k, c, alpha, beta = _physics(theta)
        fine = signal.resample_poly(np.asarray(force, float), 4, 1)
        return _rk4(fine, 4.0 * fs, k, c, alpha, beta, MASS, 4)


def make_dataset():
    """The three tests (module docstring) and the noise added {test: (force sd, acc sd)}."""
    rng = np.random.default_rng(404)
    k = _physics(TRUTH)[0]
    records, sd = [], None
    for name, (role, share, seed) in LEVELS.items():
        u = multisine(seed)
        # the force that puts the linear displacement's rms at ``share`` of the yield displacement
        w = 2 * np.pi * TRUTH["fn"]
        b, a = signal.bilinear([1.0], [MASS, 2 * TRUTH["zeta"] * MASS * w, k], FS * FINE)
        scale = share * 1e-3 * TRUTH["xy"] / np.std(signal.lfilter(b, a, u))
        f, acc, _ = generate(scale * u, TRUTH)
        if sd is None:
            sd = NOISE * np.array([np.std(f), np.std(acc)])
        records.append(
            bu.Record(
                f"{name}.csv",
                "multisine",
                name,
                role,
                np.arange(N) / FS,
                f + sd[0] * rng.standard_normal(N),
                acc + sd[1] * rng.standard_normal(N),
                sensors=(("acc", "acceleration"),),
            )
        )
    return bu.Dataset("bouc-wen", FS, None, records), sd


@pytest.fixture(scope="module")
def data():
    return make_dataset()


def test_the_user_model_and_the_generator_agree_at_the_truth(data):
    """The two integrations of the same physics (independent schemes) agree on the
    high-level test to well under the noise (measured below), so a calibration
    within 1 % is the framework's to reach, not the model's."""
    ds, sd = data
    t = ds.test("high")
    model = BoucWen().simulate(TRUTH, t.force, FS)
    err = np.std(model - t.response)
    print(
        f"\nmodel - record at the truth: {err:.4g} m/s^2 rms (noise {sd[1]:.4g}, force noise through the "
        "structure included)"
    )
    assert err < 0.05 * np.std(t.response)


def test_the_front_end_finds_one_mode_and_noise_that_is_noise(data):
    ds, sd = data
    noise = dataset_noise(ds, strict=False)
    for name in LEVELS:
        est = noise[name]["acc"]
        print(f"\n{name}: acc noise {est.sd:.4g} ({est.method}) against {sd[1]:.4g}; {est.detail[:160]}")
        assert est.sd == pytest.approx(sd[1], rel=0.25)
    # the spurious mode at the band's edge: none, whether the band is given or found
    low = ds.test("low")
    for f_range in (None, BAND):
        est = volterra.estimate_modes(
            low.force - low.force.mean(), low.response - low.response.mean(), FS, f_range=f_range
        )
        assert [round(p.freq_hz) for p in est.poles] == [25], (f_range, est.poles)
    inspection = inspect_dataset(ds, noise)
    modes = inspection["modes"]
    assert len(modes) == 1, modes
    assert modes[0]["freq_hz"] == pytest.approx(TRUTH["fn"], rel=0.005)
    assert not [w for w in inspection["warnings"] if "noise differs" in w], inspection["warnings"]


def test_calibrate_finds_the_truth_within_one_percent(data):
    ds, _ = data
    cal = bu.calibrate(ds, BoucWen(), workers=1, progress=False, log=lambda *a: None)
    modes = cal.problem.basis.modes(1)
    print(
        f"\ncalibrate: {cal.theta}; {cal.n_model_runs} runs; basis modes "
        f"{[(round(p.freq_hz, 3), round(p.damping_ratio, 5)) for p in modes]}; warnings {cal.fit_warnings}"
    )
    assert len(modes) == 1 and modes[0].freq_hz == pytest.approx(TRUTH["fn"], rel=0.005)
    for name, value in TRUTH.items():
        assert cal.theta[name] == pytest.approx(value, rel=PARAMETER_TOL), (name, cal.theta[name])
