"""The virtual rig and the embedded default data set.

One regeneration of the six tests (about 3 s); the other tests reuse its
cached noise-free runs (same rig settings) or run a single test.
"""

import dataclasses
import json

import numpy as np
import pytest
from reference import clamped_clamped_frequencies

import fe
from bayes_update.cli import main
from bayes_update.data import signals, spectral
from bayes_update.data.folder import read_dataset
from bayes_update.models.beam.levels import linear_departure, nonlinear_shares
from bayes_update.models.beam.rig import rig_of
from bayes_update.models.beam.virtual_rig import (
    CHIRP_LEVELS_N,
    PAPER_TESTS,
    SINE_LEVELS_N,
    TestSpec,
    VirtualRig,
    default_dataset_path,
    load_default_dataset,
    make_dataset,
)
from fe.model import DEFAULT_ELEMENTS, DEFAULT_SUBSTEPS

SHIPPED = default_dataset_path()


def spec(name):
    return next(s for s in PAPER_TESTS if s.name == name)


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory):
    out = tmp_path_factory.mktemp("regen") / "default"
    assert main(["make-dataset", "--out", str(out)]) == 0
    return out


def test_regeneration_is_bit_identical_to_the_shipped_data_set(regenerated):
    shipped = sorted(p.name for p in SHIPPED.iterdir() if p.is_file())
    assert shipped == sorted(p.name for p in regenerated.iterdir())
    assert shipped == [
        "chirp_high.csv",
        "chirp_low.csv",
        "chirp_medium.csv",
        "dataset.json",
        "sine_high.csv",
        "sine_low.csv",
        "sine_medium.csv",
    ]
    for name in shipped:
        assert (regenerated / name).read_bytes() == (SHIPPED / name).read_bytes(), name


def test_another_seed_gives_other_noise_and_nothing_else(regenerated, tmp_path):
    other = make_dataset(tmp_path / "other", seed=2018)  # cached noise-free runs
    base = read_dataset(regenerated)
    for a, b in zip(base.tests, other.tests):
        assert (tmp_path / "other" / a.file).read_bytes() != (regenerated / a.file).read_bytes()
        np.testing.assert_array_equal(a.time, b.time)
        # the difference is noise: about 40 dB below the signal
        d = np.linalg.norm(a.velocity - b.velocity) / np.linalg.norm(a.velocity)
        assert 0.005 < d < 0.03
    meta_a = json.loads((regenerated / "dataset.json").read_text())
    meta_b = json.loads((tmp_path / "other" / "dataset.json").read_text())
    assert meta_a["truth"]["noise"].pop("seed") == 2017
    assert meta_b["truth"]["noise"].pop("seed") == 2018
    assert meta_a == meta_b


def test_default_data_set_structure():
    ds = load_default_dataset()
    assert ds.sampling_rate_hz == 1024.0
    assert rig_of(ds) == fe.Rig(bending_stiffness_factor=1.24)
    meta = json.loads((SHIPPED / "dataset.json").read_text())
    assert meta["rig"]["bending_stiffness_factor"] == 1.24
    assert [(t.name, t.role) for t in ds.tests] == [
        ("chirp_low", "linear"),
        ("chirp_medium", "validation"),
        ("chirp_high", "nonlinear"),
        ("sine_low", "validation"),
        ("sine_medium", "validation"),
        ("sine_high", "validation"),
    ]
    for t in ds.tests:
        assert t.n_samples == 4096 and t.duration_s == 4.0
        amp = (CHIRP_LEVELS_N if t.signal == "chirp" else SINE_LEVELS_N)[t.level]
        assert t.meta["force_amplitude_n"] == amp
    truth = ds.extra["truth"]
    assert truth["parameters_si"] == fe.Parameters().to_dict()  # the paper's Table 3
    assert truth["effects"] == []
    assert truth["rig_model"]["n_elements"] == 2 * DEFAULT_ELEMENTS
    assert truth["rig_model"]["steps_per_output_sample"] == 4 * DEFAULT_SUBSTEPS
    assert truth["noise"] == dict(truth["noise"], seed=2017, snr_force_db=40.0, snr_velocity_db=40.0)
    # the paper-equivalent rig: f1 near the paper's 37 Hz, 35 Hz just below it.
    # Independent reference: the continuous beam with EI x 1.24 under P_eff
    # (tests/reference.py): 37.1272 Hz; the stated 37.1293 Hz (the rig's
    # 20-element model, 4 decimals) is 5.7e-5 above it: 2e-4 allowed (3.5x)
    kb = rig_of(ds).axial_stiffness
    p_eff = truth["parameters_si"]["F"] * kb / (kb + truth["parameters_si"]["k_s"])
    f1 = clamped_clamped_frequencies(
        rig_of(ds).EI, rig_of(ds).mass_per_length, rig_of(ds).length_m, P=p_eff, n_modes=1
    )[0]
    assert truth["linearised"]["f1_hz"] == pytest.approx(f1, rel=2e-4)
    assert truth["linearised"]["p_eff_n"] == pytest.approx(p_eff, rel=1e-5)
    assert truth["linearised"]["euler_load_n"] == pytest.approx(
        4 * np.pi**2 * rig_of(ds).EI / rig_of(ds).length_m ** 2, rel=1e-5
    )
    assert truth["linearised"]["sine_frequency_over_f1"] == pytest.approx(35.0 / f1, rel=2e-4)
    size = sum(p.stat().st_size for p in SHIPPED.iterdir())
    assert size < 2e6


def test_rig_is_finer_than_the_updating_model():
    vrig = VirtualRig()
    assert vrig.model.n_elements >= 2 * DEFAULT_ELEMENTS
    assert vrig.model.substeps * vrig.oversampling >= 4 * DEFAULT_SUBSTEPS
    assert vrig.fs_fine == 4096.0


def test_decimation_is_zero_phase_and_noise_has_the_stated_snr():
    vrig = VirtualRig()
    s = spec("chirp_low")
    t, f, v = vrig.clean(s)
    # the decimated true force is the chirp sampled at 1024 Hz (no delay, flat passband),
    # except within the filter's half length of the kinks at 0 s and 2 s (sweep on/off)
    away = (np.abs(t - 0.0) > 0.03) & (np.abs(t - 2.0) > 0.03)
    np.testing.assert_allclose(f[away], signals.chirp(s.amplitude_n)[away], rtol=0, atol=1e-5 * s.amplitude_n)
    ds = load_default_dataset()
    rec = ds.test("chirp_low")
    for clean, noisy in ((f, rec.force), (v, rec.velocity)):
        snr = 20 * np.log10(signals.rms(clean) / signals.rms(noisy - clean))
        assert snr == pytest.approx(40.0, abs=0.3)


def test_h1_of_the_linear_test_matches_the_fe_linear_frf():
    """The low chirp of the default data set (noisy) against the rig model's linear FRF."""
    ds = load_default_dataset()
    rec = ds.test("chirp_low")
    est = spectral.transient_frf(rec.force, rec.velocity, ds.sampling_rate_hz)
    vrig = VirtualRig()
    f1 = vrig.modes(1).frequencies_hz[0]
    band = est.band(f1 - 4.0, f1 + 4.0)  # about +-8 half-power half-widths
    h_model = vrig.model.linear_frf(vrig.truth, est.f[band])
    err = np.abs(est.h1[band] - h_model) / np.abs(h_model)
    assert err.max() < 0.02
    assert est.coherence[band].min() > 0.95
    # the peak sits at f1 (within one 0.25 Hz bin)
    assert est.f[band][np.argmax(np.abs(est.h1[band]))] == pytest.approx(f1, abs=0.25)


def test_levels_low_linear_high_strongly_nonlinear():
    vrig = VirtualRig()
    modes = vrig.modes(1)
    f1, z1 = modes.frequencies_hz[0], modes.damping_ratios[0]
    shares = {}
    for s in PAPER_TESTS:
        _, f, v = vrig.clean(s)
        shares[s.name] = nonlinear_shares(f, v, f1, z1, vrig.fs)
    assert shares["chirp_high"]["share"] >= 0.30
    assert shares["sine_high"]["share"] >= 0.30
    assert shares["sine_low"]["share"] < 0.01
    assert shares["chirp_low"]["share"] < shares["chirp_medium"]["share"] < shares["chirp_high"]["share"]
    # the chirp's Volterra share has a ~2 % floor from the basis; the physics is linear:
    assert linear_departure(vrig, spec("chirp_low")) < 0.01
    # a straight beam has no even kernels
    assert shares["chirp_high"]["y2_over_y1"] < 1e-3


def test_imperfection_is_hidden_in_the_truth_and_shows_as_y2(tmp_path):
    s = TestSpec("chirp", "high", CHIRP_LEVELS_N["high"])
    ds = make_dataset(tmp_path / "bow", imperfection=3e-4, tests=[s])
    assert ds.extra["truth"]["effects"] == [{"name": "initial_imperfection", "amplitude": 3e-4}]
    read = read_dataset(tmp_path / "bow")
    assert rig_of(read) == fe.Rig(bending_stiffness_factor=1.24)  # nothing in the rig block
    vrig = VirtualRig()
    modes = vrig.modes(1)
    rec = read.tests[0]
    bowed = nonlinear_shares(rec.force, rec.velocity, modes.frequencies_hz[0], modes.damping_ratios[0], vrig.fs)
    assert bowed["y2_over_y1"] > 1e-3  # straight beam: ~6e-6


def test_rig_validates_its_settings():
    with pytest.raises(ValueError, match="oversampling"):
        VirtualRig(oversampling=0)
    with pytest.raises(ValueError, match="snr_force_db"):
        VirtualRig(snr_force_db=float("nan"))
    with pytest.raises(ValueError, match="n_elements"):
        VirtualRig(n_elements=2)
    vrig = dataclasses.replace(VirtualRig(), snr_force_db=None, snr_velocity_db=None)
    t, f, v = vrig.measure(spec("sine_low"), np.random.default_rng(0))
    np.testing.assert_array_equal(v, vrig.clean(spec("sine_low"))[2])


def test_plot_data_writes_the_figures(tmp_path, capsys):
    out = tmp_path / "figs"
    assert main(["plot-data", "--out", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    for t in ("chirp_low", "chirp_medium", "chirp_high", "sine_low", "sine_medium", "sine_high"):
        assert f"{t}.png" in names
    assert {"chirp_low_frf.png", "chirp_high_frf.png", "chirp_frf.png", "sine_high_psd.png", "sine_psd.png"} <= names
    assert "wrote 14 figure(s)" in capsys.readouterr().out


def test_cli_reports_bad_data(tmp_path, capsys):
    assert main(["plot-data", "--data", str(tmp_path / "nope"), "--out", str(tmp_path / "o")]) == 2
    assert "not a folder" in capsys.readouterr().err
