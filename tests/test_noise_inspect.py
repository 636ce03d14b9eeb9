"""The inspection report's data side (bayes_update.data.inspect) and its figures
(bayes_update.reports.inspection), on lab records with known truth and on the
embedded default data set."""

import json

import lab_records as lab
import numpy as np
import pytest

from bayes_update.data import checks
from bayes_update.data.inspect import find_modes, inspect_dataset
from bayes_update.data.noise import dataset_noise
from bayes_update.reports.inspection import write_inspection

CHANNELS = ("force", "acc1", "acc2", "acc3")


@pytest.fixture(scope="module")
def lab_set():
    records = [lab.periodic_test(seed=12, drift=100.0), *lab.random_tests()]
    records[0].role = "validation"
    ds = lab.lab_dataset(records)
    noise = dataset_noise(ds, strict=False)
    return records, ds, noise, inspect_dataset(ds, noise)


@pytest.fixture(scope="module")
def default_set():
    from bayes_update.models.beam.virtual_rig import load_default_dataset

    ds = load_default_dataset()
    noise = dataset_noise(ds, strict=False)
    return ds, noise, inspect_dataset(ds, noise)


def test_the_inspection_of_lab_records_holds_the_truth(lab_set):
    records, ds, noise, out = lab_set
    json.dumps(out, allow_nan=False)  # JSON-ready
    for rec in records:
        entry = out["tests"][rec.file]
        assert set(entry["noise"]) == set(CHANNELS)
        for ch in CHANNELS:
            assert entry["noise"][ch] == noise[rec.file[:-4]][ch].to_dict()
            assert set(entry["noise"][ch]) == {"sd", "method", "detail"}
        lo, hi = entry["excited_band_hz"]
        assert abs(lo - lab.LAB_BAND_HZ[0]) < 0.5 and abs(hi - lab.LAB_BAND_HZ[1]) < 0.5
        clean = np.column_stack([rec.clean_force, rec.clean_response])
        noise_added = np.column_stack([rec.force_noise, rec.sensor_noise])
        for j, ch in enumerate(CHANNELS):
            # the offset added, plus the means of the drift, the structure's response and the noise
            parts = (rec.offsets[j], rec.drift[:, j].mean(), clean[:, j].mean(), noise_added[:, j].mean())
            assert entry["offset"][ch] == pytest.approx(sum(parts), rel=1e-9)
            assert entry["clipping"][ch] == {"clipped": False, "longest_run": 1, "at_limits": 2}
    # the drift added, as a share of the rms, where it is well above the floor of the measure
    strong = records[0]
    for j, ch in enumerate(CHANNELS):
        truth = np.ptp(strong.drift[:, j]) / np.std(np.column_stack([strong.force, strong.response])[:, j])
        assert out["tests"][strong.file]["drift"][ch] == pytest.approx(truth, rel=0.2), ch
    assert out["tests"][strong.file]["period_samples"] == lab.LAB_PERIOD_SAMPLES
    assert any("acc3" in w and "drifts by" in w for w in out["warnings"])
    assert any("random_high.csv, channel 'force': the noise cannot be estimated" in w for w in out["warnings"])


def test_modes_and_their_level_dependence_on_lab_records(lab_set):
    records, ds, _, out = lab_set
    freqs = lab.lab_modes()[0]
    # every mode of the chain, from the several-modes finder (volterra.estimate_modes)
    assert out["modes_from"] == "random_low.csv" and len(out["modes"]) == len(freqs)
    # measured: frequencies within 6.1e-5, damping ratios within 0.04 % (tolerances 3x and 25x:
    # the damping's at 1 %, what a finder of another record reaches, test_find_modes_is_one_small_function)
    got = np.array([m["freq_hz"] for m in out["modes"]])
    assert np.allclose(got, np.sort(freqs), rtol=2e-4), got
    for m in out["modes"]:
        assert m["damping_ratio"] == pytest.approx(lab.LAB_DAMPING_RATIO, rel=0.01)
    assert len(out["level_dependence"]) == len(freqs)
    dep = out["level_dependence"][0]
    assert "random_low.csv" in dep["freq_hz"]
    assert dep["freq_hz"]["random_low.csv"] == out["modes"][0]["freq_hz"]


def test_the_first_look_and_the_problem_share_one_estimate_of_the_modes(monkeypatch):
    """A command's first look and its problem read the linear test's modes once: every record
    is estimated once (the high-level test for its level dependence), and the basis's order-1
    poles are the first look's modes polished on the record's linear fit (within 5e-4 in
    frequency: the polish moves them up to 1.5e-4 here)."""
    from collections import OrderedDict

    import volterra
    from bayes_update.core.problem import Problem
    from bayes_update.data import modes as modes_module

    monkeypatch.setattr(modes_module, "_ESTIMATES", OrderedDict())
    real, calls = volterra.estimate_modes, []

    def counted(u, y, *args, **kwargs):
        calls.append(hash(np.asarray(u).tobytes()))
        return real(u, y, *args, **kwargs)

    monkeypatch.setattr(volterra, "estimate_modes", counted)
    ds = lab.lab_dataset(lab.random_tests(seed=41))

    class Stub:  # the problem's basis needs no model run
        def simulate(self, theta, force, fs):
            raise AssertionError("not run")

    look = inspect_dataset(ds, dataset_noise(ds, strict=False))
    n_look = len(calls)
    problem = Problem(ds, Stub())
    assert n_look == len(ds.tests) and len(calls) == n_look, (n_look, len(calls))
    first_look = np.array([m["freq_hz"] for m in look["modes"]])
    basis = np.sort([p.freq_hz for p in problem.basis.modes(1)])
    assert first_look.size == 3 and np.allclose(basis, first_look, rtol=5e-4), (basis, first_look)
    # the linear test's level-dependence entries are its modes, not a second estimate
    assert [d["freq_hz"]["random_low.csv"] for d in look["level_dependence"]] == list(first_look)


def test_clipping_and_coherence_loss_are_reported():
    rec = lab.random_tests()[0]
    clipped = rec.record()
    r = clipped.response.copy()
    top = 0.6 * r[:, 1].max()
    r[:, 1] = np.minimum(r[:, 1], top)
    clipped.response = r
    assert checks.clipping(r[:, 1])["clipped"] and not checks.clipping(r[:, 0])["clipped"]
    noisy = rec.record()
    noisy.file = "noisy.csv"
    rng = np.random.default_rng(5)
    r = noisy.response.copy()
    r[:, 2] += 5.0 * rng.standard_normal(r.shape[0])  # 2x the response's rms
    noisy.response = r
    ds = lab.lab_dataset([rec])
    ds.tests = [clipped, noisy]
    out = inspect_dataset(ds)
    assert out["tests"]["random_low.csv"]["clipping"]["acc2"]["clipped"]
    assert any("random_low.csv, channel 'acc2': clipped" in w for w in out["warnings"])
    assert out["tests"]["noisy.csv"]["coherence"]["acc3"]["median_in_band"] < 0.9
    assert any("noisy.csv, sensor 'acc3': coherence below" in w for w in out["warnings"])
    assert not any("sensor 'acc1': coherence below" in w for w in out["warnings"])


def test_the_default_data_set(default_set):
    ds, noise, out = default_set
    truth = ds.extra["truth"]
    assert truth["noise"]["snr_force_db"] == truth["noise"]["snr_velocity_db"] == 40.0
    methods = {}
    for t in ds.tests:
        for ch, x in (("force", t.force), ("velocity", t.response)):
            est = noise[t.name][ch]
            # noise added at 40 dB below each channel's rms: sd = rms / 100 (of the clean channel)
            expected = np.sqrt(np.mean(x**2) / (1 + 1e-4)) / 100
            assert abs(est.sd / expected - 1) < 0.15, (t.name, ch, est.method, est.sd / expected)
            methods[(t.name, ch)] = est.method
    print(methods)
    assert {methods[(t, "velocity")] for t in ("sine_low", "sine_medium", "sine_high")} == {"periods"}
    assert methods[("chirp_low", "force")] == "zero_input"
    assert out["tests"]["sine_low.csv"]["period_samples"] == 1024  # 35 Hz repeats every 1024 samples
    lin = truth["linearised"]
    assert out["modes"][0]["freq_hz"] == pytest.approx(lin["f1_hz"], rel=0.01)
    assert out["modes"][0]["damping_ratio"] == pytest.approx(lin["zeta1"], rel=0.15)
    dep = out["level_dependence"][0]["freq_hz"]
    assert set(dep) == {"chirp_low.csv", "chirp_medium.csv", "chirp_high.csv"}  # the sines miss the mode
    assert dep["chirp_low.csv"] < dep["chirp_high.csv"]
    # this virtual data set's noise is proportional to each test's level: the report says so
    assert any("sensor 'velocity': its noise differs" in w for w in out["warnings"])


def test_find_modes_is_one_small_function():
    """One call per sensor finds the chain's three modes: measured within 7.3e-5 in frequency
    and 1 % in damping on every sensor (tolerances 2.7x and 3x that)."""
    rec = lab.random_tests()[0]
    freqs = np.sort(lab.lab_modes()[0])
    for j in range(rec.response.shape[1]):
        modes = find_modes(rec.force, rec.response[:, j], rec.fs)
        assert len(modes) == 3, (j, modes)
        f, z = np.array(modes).T
        assert np.allclose(f, freqs, rtol=2e-4), (j, modes)
        assert np.allclose(z, lab.LAB_DAMPING_RATIO, rtol=0.03), (j, modes)
    quiet = np.random.default_rng(1).standard_normal(rec.force.size)
    with pytest.raises(ValueError):
        find_modes(quiet, np.random.default_rng(2).standard_normal(rec.force.size), rec.fs)


@pytest.mark.parametrize("which", ["lab", "default"])
def test_the_figures_are_written(which, lab_set, default_set, tmp_path):
    ds, noise, out = lab_set[1:] if which == "lab" else default_set
    paths = write_inspection(ds, tmp_path, out, noise)
    names = (
        {"inspection.json", "modes.png", "noise_force.png"}
        | {f"frf_{n}.png" for n, _ in ds.sensors}
        | {f"noise_{n}.png" for n, _ in ds.sensors}
        # where a test repeats (the lab set's multisines, the default set's sines): its lines
        | {f"distortion_{n}.png" for n, _ in ds.sensors}
    )
    assert any(entry["period_samples"] for entry in out["tests"].values())  # declared or found
    assert set(paths) == names
    assert all(p.stat().st_size > 10_000 for n, p in paths.items() if n.endswith(".png"))
    assert json.loads(paths["inspection.json"].read_text())["tests"].keys() == out["tests"].keys()


def _multisine(fs, n, band, seed):
    """A random-phase multisine with flat lines in ``band`` [Hz], one period of n samples, unit rms."""
    f = np.fft.rfftfreq(n, 1 / fs)
    lines = np.zeros(f.size, complex)
    sel = (f >= band[0]) & (f <= band[1])
    lines[sel] = np.exp(2j * np.pi * np.random.default_rng(seed).random(sel.sum()))
    x = np.fft.irfft(lines, n)
    return x / x.std()


@pytest.mark.parametrize(
    "fs, seconds, band", [(512.0, 2.0, (2.0, 40.0)), (1024.0, 2.0, (2.0, 110.0)), (200.0, 8.0, (0.5, 60.0))]
)
def test_low_multisine_lines_are_not_a_drift(fs, seconds, band):
    """Records of a few seconds whose lowest excited line has a few cycles in them (a
    portal frame's 2-s multisines from 2 Hz): windows of 1/8 of the record read
    40-65 % of the rms as a drift there; windows over two cycles of the lowest line
    do not, and a drift added is still measured."""
    n = int(fs * seconds)
    x = np.tile(_multisine(fs, n // 2, band, seed=31), 2)  # two periods
    assert checks.drift(x) > 0.1  # what the fixed windows said
    assert checks.drift(x, fs, band[0]) < 0.02
    ramp = 0.3 * np.linspace(-0.5, 0.5, n)  # a drift of 30 % of the rms
    got = checks.drift(x + ramp, fs, band[0])
    truth_span = np.ptp(checks.trend(ramp, int(np.ceil(2 * fs / band[0])))) / np.std(x + ramp)
    assert got == pytest.approx(truth_span, rel=0.1) and got > 0.1
    # a record with fewer than two windows of two cycles: the drift cannot be told from the lines
    assert np.isnan(checks.drift(x[: int(3.9 * fs / band[0])], fs, band[0]))
    with pytest.raises(ValueError, match="fs > 0 and lowest_hz > 0"):
        checks.drift(x, None, band[0])
