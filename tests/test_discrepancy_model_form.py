"""The discrepancy workflow on records of a structure of another form than the model
fitted: a continuous cantilever with a compliant clamp and a tip mass (five modes,
Rayleigh damping, DOP853), fitted by a user's two-mode model (tests/cantilever_kit.py).

The model is wrong everywhere (no higher modes, ideal-clamp shapes), so the test is
whether the naming rule separates a catalogue effect from model-form error: with a
cubic tip spring in the structure `tip_cubic` is named and the held-out error drops;
without it nothing is named; either way a gap is reported as numbers, never hidden.
The full-size run is benchmarks/discrepancy_cases.py (FORM_CASES)."""
from __future__ import annotations

import math

import pytest

import cantilever_kit
from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy


def _run(k3):
    data = cantilever_kit.make_dataset(k3=k3, seed=41)
    return find_discrepancy(data, cantilever_kit.TwoModes(), settings=DiscrepancySettings.quick(), workers=1,
                            progress=False, log=lambda *a: None)


@pytest.fixture(scope="module")
def with_spring():
    return _run(cantilever_kit.K3_TRUTH)


@pytest.fixture(scope="module")
def without_spring():
    return _run(0.0)


def test_a_tip_spring_is_named_through_the_model_form_error(with_spring):
    res = with_spring
    assert list(res.named) == ["tip_cubic"], res.gap_sentence()
    before, after = res.gap_before, res.gap_after
    assert after["held_out_error_beyond_noise"] < before["held_out_error_beyond_noise"], (before, after)
    k3 = res.to_json()["final_mode"]["effects"]["tip_cubic"]["k3"]
    # the two-mode model's ideal-clamp shapes move the tip's modal participation, so its k3
    # is an effective value: the structure's sign and order of magnitude, not its number
    assert 0.25 < k3["mode"] / (cantilever_kit.K3_TRUTH / 1e6) < 4.0, k3


def test_without_a_catalogue_effect_nothing_is_named_and_the_gap_is_reported(without_spring):
    res = without_spring
    assert list(res.named) == [], res.gap_sentence()
    gap = res.gap_remaining()
    # a two-mode model of a continuous beam leaves a held-out error many times the
    # records' noise (no higher modes, ideal-clamp shapes), and the result says so in numbers
    assert math.isfinite(gap["held_out_relative_error"]) and gap["held_out_times_noise"] > 3, gap
    assert f"{100 * gap['held_out_relative_error']:.3g} %" in res.gap_sentence(), res.gap_sentence()
