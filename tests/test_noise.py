"""The noise estimators of bayes_update.data.noise against the noise really added
to laboratory-like records (tests/lab_records.py): every estimate within 15 % of
the sd of the added noise sequence, over the whole record."""

import lab_records as lab
import numpy as np
import pytest

from bayes_update.data.lpm import lpm_noise
from bayes_update.data.noise import NoiseEstimationError, dataset_noise, from_fit_residual, record_noise
from bayes_update.data.periodic import find_periods, period_noise

TOL = 0.15
CHANNELS = ("force", "acc1", "acc2", "acc3")
SENSORS = CHANNELS[1:]


def errors(estimates, rec, channels=CHANNELS) -> dict:
    """Relative error of each channel's estimate against the sd of the noise added."""
    return {ch: estimates[ch].sd / rec.noise_sd[ch] - 1.0 for ch in channels}


def channel(rec, name):
    return rec.force if name == "force" else rec.response[:, SENSORS.index(name)]


def added(rec, name):
    return rec.force_noise if name == "force" else rec.sensor_noise[:, SENSORS.index(name)]


@pytest.fixture(scope="module")
def periodic():
    return lab.periodic_test()


@pytest.fixture(scope="module")
def random_pair():
    return lab.random_tests()


# ------------------------------------------------------------------ the generator
def test_the_generator_adds_exactly_the_noise_it_returns_and_integrates_accurately():
    rec = lab.lab_record("lin.csv", "linear", 0.5, lab.MULTISINE_LAYOUT, seed=3, cubic=0.0)
    measured = np.column_stack([rec.force, rec.response])
    clean = np.column_stack([rec.clean_force, rec.clean_response])
    noise = np.column_stack([rec.force_noise, rec.sensor_noise])
    assert np.allclose(measured - clean - rec.offsets - rec.drift, noise, rtol=0, atol=1e-12)
    # a middle period of the steady state against the chain's analytic FRF (acceleration / force)
    N, (a, _) = rec.period_samples, rec.section("multisine")[0]
    Y = np.fft.rfft(rec.clean_response[a + 3 * N : a + 4 * N], axis=0)
    U = np.fft.rfft(rec.clean_force[a + 3 * N : a + 4 * N])
    f = np.fft.rfftfreq(N, 1 / rec.fs)
    k = np.flatnonzero(np.abs(U) > 0.1 * np.abs(U).max())
    M, K, C, b = np.diag(lab.LAB_MASSES_KG), lab._stiffness(), lab._damping(), np.array([0.0, 0.0, 1.0])
    exact = np.array([-(w**2) * np.linalg.solve(K - w**2 * M + 1j * w * C, b) for w in 2 * np.pi * f[k]])
    assert np.max(np.abs(Y[k] / U[k, None] - exact) / np.abs(exact)) < 1e-3
    assert f[k].min() < 2.5 and f[k].max() > 79.0 and rec.fs == 2.5 * lab.LAB_BAND_HZ[1]
    # the steady state repeats exactly (what the periods estimator relies on)
    P = rec.clean_response[a + 2 * N : a + 5 * N].reshape(3, N, 3)
    assert np.max(np.abs(np.diff(P, axis=0))) < 1e-9 * np.max(np.abs(P))


# ------------------------------------------------------------------ periods
def test_periods_give_every_channel_within_15_percent(periodic):
    est = record_noise(periodic.record())
    err = errors(est, periodic)
    print("periods:", {k: f"{v:+.3f}" for k, v in err.items()})
    assert all(est[ch].method == "periods" for ch in CHANNELS)
    assert all(abs(e) < TOL for e in err.values()), err
    assert est["acc1"].detail.startswith("periods 2-")  # the first period is dropped
    ((a, b),) = est["acc1"].spans
    assert a >= periodic.section("multisine")[0][0] + periodic.period_samples


def test_a_period_not_declared_is_found_in_the_force(periodic):
    layout = find_periods(periodic.force)
    assert layout.period == periodic.period_samples and not layout.declared
    est = record_noise(periodic.record(declare_period=False))
    assert all(est[ch].method == "periods" for ch in CHANNELS)
    assert "period detected in the force" in est["acc2"].detail
    assert all(abs(e) < TOL for e in errors(est, periodic).values())


def test_three_sensors_whose_noise_differs_tenfold_are_each_within_15_percent(periodic):
    truth = periodic.noise_sd
    assert 9.0 < truth["acc3"] / truth["acc1"] < 11.0
    est = record_noise(periodic.record())
    for ch in SENSORS:
        assert abs(est[ch].sd / truth[ch] - 1) < TOL, ch
    assert abs(est["acc3"].sd / est["acc1"].sd / (truth["acc3"] / truth["acc1"]) - 1) < TOL


def test_drift_and_offsets_do_not_spoil_the_periods():
    rec = lab.periodic_test(seed=12, drift=100.0, offsets=(5.0, 3.0, -4.0, 2.0))
    # a drift that matters: over the record, 20 % of the response's rms and more, 30x the noise
    assert np.min(np.ptp(rec.drift[:, 1:], axis=0) / rec.clean_response.std(axis=0)) > 0.2
    assert np.min(np.ptp(rec.drift, axis=0) / np.array([rec.noise_sd[ch] for ch in CHANNELS])) > 30
    est = record_noise(rec.record())
    err = errors(est, rec)
    print("periods with drift:", {k: f"{v:+.3f}" for k, v in err.items()})
    assert all(est[ch].method == "periods" for ch in CHANNELS)
    assert all(abs(e) < TOL for e in err.values()), err
    # the per-period trend is what saves it: without it the drift counts as noise
    layout = find_periods(rec.force, rec.period_samples)
    raw = [period_noise(channel(rec, ch), layout, detrend=-1)[0] / rec.noise_sd[ch] - 1 for ch in CHANNELS]
    assert min(raw) > 1.0, raw


# ------------------------------------------------------------------ zero-input sections
@pytest.fixture(scope="module")
def with_pauses():
    return lab.lab_record("pauses.csv", "validation", 2.0, [("quiet", 3.0), ("random", 20.0), ("quiet", 8.0)], seed=31)


def test_zero_input_sections_skip_the_free_decay(with_pauses):
    rec = with_pauses
    est = record_noise(rec.record())
    err = errors(est, rec)
    print("zero input:", {k: f"{v:+.3f}" for k, v in err.items()})
    assert all(est[ch].method == "zero_input" for ch in CHANNELS)
    assert all(abs(e) < TOL for e in err.values()), err
    stop = rec.section("random")[0][1]
    for ch in SENSORS:
        tail = [a for a, _ in est[ch].spans if a >= stop]
        assert tail and tail[0] - stop > 1.0 * rec.fs  # the decay (tau 0.44 s) is skipped
        # a free decay is not noise: the whole quiet tail would be many times the noise
        assert np.std(channel(rec, ch)[stop:]) > 5 * rec.noise_sd[ch]


# ------------------------------------------------------------------ quiet band
def test_quiet_band_on_a_record_sampled_well_above_its_band():
    rec = lab.lab_record("fast.csv", "validation", 2.0, lab.RANDOM_LAYOUT, seed=41, fs=1000.0, white=True)
    est = record_noise(rec.record())
    err = errors(est, rec)
    print("quiet band:", {k: f"{v:+.3f}" for k, v in err.items()})
    assert all(est[ch].method == "quiet_band" for ch in CHANNELS)
    assert all(abs(e) < TOL for e in err.values()), err
    assert "white noise assumed" in est["acc1"].detail
    # what "white noise assumed" means: coloured noise (AR(1), pole 0.75 on acc3) is under-read
    coloured = lab.lab_record("fast.csv", "validation", 2.0, lab.RANDOM_LAYOUT, seed=41, fs=1000.0)
    low = record_noise(coloured.record())["acc3"]
    print("quiet band on coloured noise, acc3:", f"{low.sd / coloured.noise_sd['acc3'] - 1:+.3f}")
    assert low.method == "quiet_band" and low.sd < 0.6 * coloured.noise_sd["acc3"]


def test_no_quiet_band_at_two_and_a_half_times_the_band(random_pair):
    est = record_noise(random_pair[1].record())
    assert all(est[ch].method == "unknown" and est[ch].sd is None for ch in CHANNELS)
    assert "no band from 3x" in est["force"].detail


# ------------------------------------------------------------------ fit residual, carried
def test_the_low_level_fit_residual_is_carried_to_the_high_level_test(random_pair):
    low, high = random_pair
    noise = dataset_noise(lab.lab_dataset([low, high]))
    err_low = errors(noise["random_low"], low, SENSORS)
    err_high = errors(noise["random_high"], high, SENSORS)
    own = {ch: lpm_noise(high.force, channel(high, ch), high.fs).sd / high.noise_sd[ch] for ch in SENSORS}
    print("fit residual (low):", {k: f"{v:+.3f}" for k, v in err_low.items()})
    print("carried (high):", {k: f"{v:+.3f}" for k, v in err_high.items()})
    print("high test's own fit residual / noise:", {k: f"{v:.1f}" for k, v in own.items()})
    assert all(noise["random_low"][ch].method == "fit_residual" for ch in SENSORS)
    assert all(noise["random_high"][ch].method == "carried" for ch in SENSORS)
    assert noise["random_high"]["acc1"].source_test == "random_low"
    assert all(abs(e) < TOL for e in err_low.values()), err_low
    assert all(abs(e) < TOL for e in err_high.values()), err_high
    # the high-level test's own fit residual holds its nonlinear distortion: several times the noise
    assert min(own.values()) > 3.0, own
    # the force is never carried
    assert noise["random_high"]["force"].method == "unknown"


def test_a_fit_residual_given_by_the_caller_takes_the_place_of_the_lpm(random_pair):
    low, high = random_pair
    given = {"acc2": from_fit_residual(low.sensor_noise[:, 1], 12, "a Volterra fit of orders 1-3")}
    noise = dataset_noise(lab.lab_dataset([low, high]), fit_residuals={"random_low": given})
    n = low.sensor_noise.shape[0]
    assert noise["random_low"]["acc2"].sd == pytest.approx(np.linalg.norm(low.sensor_noise[:, 1]) / np.sqrt(n - 12))
    assert noise["random_low"]["acc2"].detail == "residual of a Volterra fit of orders 1-3 (12 parameters)"
    assert noise["random_low"]["acc1"].detail.startswith("local polynomial method")
    assert noise["random_high"]["acc2"].sd == noise["random_low"]["acc2"].sd
    with pytest.raises(ValueError, match="cannot carry"):
        from_fit_residual(np.zeros(5), 5)


# ------------------------------------------------------------------ declared noise, force
def test_declared_noise_wins(periodic, random_pair):
    ds = lab.lab_dataset([periodic, random_pair[1]], noise_sd={"acc2": 0.123, "force": 0.01})
    ds.tests[0].noise_sd = {"force": 0.02}  # one test's own, overriding
    noise = dataset_noise(ds)
    first, second = noise["multisine_low"], noise["random_high"]
    assert (first["acc2"].sd, first["acc2"].method) == (0.123, "declared")
    assert (first["force"].sd, first["force"].method) == (0.02, "declared")
    assert (second["force"].sd, second["acc2"].sd) == (0.01, 0.123)
    assert first["acc1"].method == "periods"  # not declared: estimated


def test_force_noise_from_periods_and_from_zero_input(periodic, with_pauses):
    for rec, method in ((periodic, "periods"), (with_pauses, "zero_input")):
        est = record_noise(rec.record())["force"]
        assert est.method == method
        assert abs(est.sd / rec.noise_sd["force"] - 1) < TOL, (method, est.sd, rec.noise_sd["force"])


# ------------------------------------------------------------------ nothing available
def test_a_data_set_with_no_source_of_noise_says_what_to_add(random_pair):
    ds = lab.lab_dataset([random_pair[1]])  # high level only, no linear test
    with pytest.raises(NoiseEstimationError) as info:
        dataset_noise(ds)
    msg = str(info.value)
    for word in ("'acc1'", "'acc2'", "'acc3'", "noise_sd", "period_samples", "quiet", "'linear'", "m/s^2"):
        assert word in msg, word
    # declared for two of the three sensors: the message names only the third
    ds = lab.lab_dataset([random_pair[1]], noise_sd={"acc1": 0.01, "acc3": 0.1})
    with pytest.raises(NoiseEstimationError, match="sensor 'acc2'") as info:
        dataset_noise(ds)
    assert "'acc1'" not in str(info.value)
    lenient = dataset_noise(ds, strict=False)["random_high"]
    assert lenient["acc2"].method == "unknown" and lenient["acc2"].sd is None


# ------------------------------------------------------------------ over seeds (outside the default run)
@pytest.mark.slow
@pytest.mark.parametrize("seed", range(100, 110))
def test_every_estimator_over_seeds(seed):
    cases = [
        (lab.periodic_test(seed=seed), "periods"),
        (
            lab.lab_record("p.csv", "validation", 2.0, [("quiet", 3.0), ("random", 20.0), ("quiet", 8.0)], seed=seed),
            "zero_input",
        ),
        (lab.lab_record("f.csv", "validation", 2.0, lab.RANDOM_LAYOUT, seed=seed, fs=1000.0, white=True), "quiet_band"),
    ]
    for rec, method in cases:
        est = record_noise(rec.record())
        err = errors(est, rec)
        print(seed, method, {k: f"{v:+.3f}" for k, v in err.items()})
        assert all(est[ch].method == method for ch in CHANNELS)
        assert all(abs(e) < TOL for e in err.values()), (method, err)
    low, high = lab.random_tests(seed=seed)
    noise = dataset_noise(lab.lab_dataset([low, high]))
    for name, rec in (("random_low", low), ("random_high", high)):
        err = errors(noise[name], rec, SENSORS)
        print(seed, name, {k: f"{v:+.3f}" for k, v in err.items()})
        assert all(abs(e) < TOL for e in err.values()), (name, err)


def _resonant_record(fs, period, n_periods, modes, noise_sd, seed):
    """(force, response, sensor noise added): a multisine over 3 %-45 % of fs (every
    line of the period, no quiet band) through lightly damped digital resonators
    (poles r e^{+-i 2 pi f / fs}), from rest: the first period holds the transient."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(seed)
    f = np.fft.rfftfreq(period, 1 / fs)
    lines = np.where((f >= 0.03 * fs) & (f <= 0.45 * fs), np.exp(2j * np.pi * rng.random(f.size)), 0)
    force = np.tile(np.fft.irfft(lines, period), n_periods)
    force /= force.std()
    y = np.zeros_like(force)
    for fn, zeta in modes:
        r, w = np.exp(-zeta * 2 * np.pi * fn / fs), 2 * np.pi * fn / fs
        y += lfilter([1.0], [1.0, -2 * r * np.cos(w), r * r], force)
    y *= 1.0 / y.std()
    noise = noise_sd * rng.standard_normal(y.size)
    return force, y + noise, noise


def test_the_lpm_on_a_record_short_against_a_mode_bandwidth():
    """Two periods of 2 s at a rate 2.2x the band (no quiet band, no repeated steady
    periods: the LPM's case) and a mode of 0.3 % damping (bandwidth 0.08 Hz, lines
    0.25 Hz apart): the local polynomials cannot follow the FRF around the mode, and
    their residual there (1e3-1e4 times the noise's level) was counted as noise.
    Those lines are now found and given their neighbours' level: the estimate is
    the noise added, within the suite's tolerance; the detail says where."""
    fs = 97.0
    force, y, noise = _resonant_record(fs, 194, 2, [(13.1, 0.003), (31.7, 0.01)], 0.01, seed=404)
    est = lpm_noise(force, y, fs)
    print(est.detail)
    assert abs(est.sd / noise.std() - 1) < TOL, est.sd / noise.std()
    lo, hi = (float(v) for v in est.detail.split(" Hz) unresolved")[0].split("(")[-1].split("-"))
    assert 9.0 < lo < 13.1 and 31.7 < hi < 36.0, (lo, hi)  # around the two modes, not beyond
    # the raw residual without the guard: several times the noise (what the frame's records gave)
    from bayes_update.data import lpm

    old, lpm.UNRESOLVED_P = lpm.UNRESOLVED_P, 0.0
    try:
        assert lpm_noise(force, y, fs).sd > 3 * noise.std()
    finally:
        lpm.UNRESOLVED_P = old


def test_the_lpm_refuses_a_record_whose_lines_are_mostly_unresolved():
    fs = 97.0
    modes = [(fn, 0.002) for fn in np.linspace(4.0, 44.0, 6)]  # a mode every 8 Hz, bandwidth 0.04 Hz
    force, y, _ = _resonant_record(fs, 194, 2, modes, 0.01, seed=404)
    with pytest.raises(ValueError, match="cannot follow the FRF on .* record longer or declare noise_sd"):
        lpm_noise(force, y, fs)


# ------------------------------------------------------------------ one estimate per data set
def test_a_data_set_is_estimated_once_and_again_when_a_sample_changes(random_pair, monkeypatch):
    """The first look and the problem ask for the same data set's noise: the second ask reuses
    the first's estimates (no record estimated again), strict or not; a data set whose samples
    or declared noise differ is estimated anew, and a caller's fit residuals bypass the reuse."""
    import copy

    import bayes_update.data.noise as noise

    ds = lab.lab_dataset(list(random_pair))
    calls = []
    real = noise.record_noise
    monkeypatch.setattr(noise, "record_noise", lambda *a, **k: calls.append(1) or real(*a, **k))
    monkeypatch.setattr(noise, "_ESTIMATES", type(noise._ESTIMATES)())
    first = dataset_noise(ds, strict=False)
    assert len(calls) == 2  # one per test
    again = dataset_noise(ds)
    assert len(calls) == 2 and again == first and again is not first
    again["random_low"]["acc1"] = None  # a caller's edit does not reach the next caller
    assert dataset_noise(ds)["random_low"]["acc1"] == first["random_low"]["acc1"]
    changed = copy.deepcopy(ds)
    changed.tests[1].response[100, 0] += 1e-3  # one sample of one sensor
    dataset_noise(changed)
    assert len(calls) == 4
    declared = lab.lab_dataset(list(random_pair), noise_sd={"acc1": 0.01})
    assert dataset_noise(declared)["random_low"]["acc1"].method == "declared" and len(calls) == 6
    dataset_noise(ds, fit_residuals={"random_low": {}})
    assert len(calls) == 8
