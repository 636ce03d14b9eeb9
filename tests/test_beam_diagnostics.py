"""Discrepancy diagnostics (bayes_update.models.beam.diagnostics) on data with a hidden bow."""

import numpy as np
import pytest

import fe
from bayes_update.models.beam.diagnostics import decay_curve, diagnose, diagnostics_figure, harmonic_amplitudes
from bayes_update.models.beam.model import Beam
from bayes_update.models.beam.rig import rig_of
from bayes_update.models.beam.virtual_rig import PAPER_TESTS, load_default_dataset, make_dataset

TRUTH = fe.Parameters.from_paper_units(3, 15, 77, 180)
TESTS = [t for t in PAPER_TESTS if t.name in ("chirp_low", "chirp_high", "sine_high")]


@pytest.fixture(scope="module")
def diagnoses():
    straight = load_default_dataset()
    bowed = make_dataset(imperfection=0.5e-3, tests=TESTS)
    model = Beam(fe.BeamModel(rig=rig_of(straight)))
    theta = model.theta_of(TRUTH)
    return diagnose(straight, model, theta), diagnose(bowed, model, theta)


def test_harmonic_fit_and_decay_curve_against_closed_forms():
    fs, f0 = 1024.0, 35.0
    t = np.arange(4096) / fs
    x = 2.0 * np.sin(2 * np.pi * f0 * t + 0.3) + 0.5 * np.cos(2 * np.pi * 3 * f0 * t)
    h = harmonic_amplitudes(x, fs, f0)
    assert h[1] == pytest.approx(2.0, rel=1e-9) and h[2] < 1e-9 and h[3] == pytest.approx(0.5, rel=1e-9)
    zeta, f1 = 0.013, 37.0
    wd = 2 * np.pi * f1 * np.sqrt(1 - zeta**2)
    v = np.where(t > 1.0, np.exp(-zeta * 2 * np.pi * f1 * (t - 1.0)) * np.sin(wd * (t - 1.0)), 0.0)
    d = decay_curve(v, fs, f1, 1.0)
    assert np.allclose(d["zeta"], zeta, rtol=0.03)
    assert np.allclose(d["freq_hz"], f1 * np.sqrt(1 - zeta**2), rtol=2e-3)


def test_a_hidden_bow_shows_in_y2_and_the_even_harmonic(diagnoses):
    straight, bowed = diagnoses
    y2_straight = straight["by_order"]["chirp_high"]["y2"]
    y2_bowed = bowed["by_order"]["chirp_high"]["y2"]
    assert y2_bowed > 3 * y2_straight
    h2 = bowed["by_frequency"]["sine_high"]["2x"]
    assert h2["data_above_noise"] and h2["difference_db"] < -10.0
    assert not straight["by_frequency"]["sine_high"]["2x"]["data_above_noise"]


def test_model_decay_matches_its_modal_damping(diagnoses):
    straight, _ = diagnoses
    zeta1 = fe.BeamModel(rig=rig_of(load_default_dataset())).modal_analysis(TRUTH, 1).damping_ratios[0]
    model_decay = straight["by_amplitude"]["chirp_low"]["model"]
    assert np.allclose(model_decay["zeta"], zeta1, rtol=0.1)
    fig = diagnostics_figure(straight)
    assert len(fig.axes) == 4
