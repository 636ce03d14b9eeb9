"""The discrepancy workflow on records of a structure of another form than the model
fitted: a continuous cantilever with a compliant clamp and a tip mass (five modes,
Rayleigh damping, DOP853), fitted by a user's two-mode model (tests/cantilever_kit.py).

The model is wrong everywhere (no higher modes, ideal-clamp shapes), so the test is
whether the naming rule separates a catalogue effect from model-form error: with a
cubic tip spring in the structure `tip_cubic` is the decisive candidate, of the
structure's order of magnitude, but the two-mode model carries it into the held-out
sweep wrongly (measured: the random test's error 16.2 -> 10.0 %, the sweep's 39.6 ->
47.6 %), so it is not named: naming asks for better held-out predictions, not only
evidence; without the spring nothing is decisive; either way a gap is reported as
numbers, never hidden.  (With a front end that read one of the two modes the
baseline predicted the held-out tests worse, 36.8 %, and the spring was named.)
The full-size run is benchmarks/discrepancy_cases.py (FORM_CASES)."""

from __future__ import annotations

import math

import cantilever_kit
import pytest

from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy
from bayes_update.core.effects import DECISIVE, evidence_table


def _run(k3):
    data = cantilever_kit.make_dataset(k3=k3, seed=41)
    return find_discrepancy(
        data,
        cantilever_kit.TwoModes(),
        settings=DiscrepancySettings.quick(),
        workers=1,
        progress=False,
        log=lambda *a: None,
    )


@pytest.fixture(scope="module")
def with_spring():
    return _run(cantilever_kit.K3_TRUTH)


@pytest.fixture(scope="module")
def without_spring():
    return _run(0.0)


def test_a_tip_spring_is_decisive_and_named_only_if_it_predicts_the_held_out_tests_better(with_spring):
    res = with_spring
    row = res.rounds[0]["candidates"][0]
    assert row["name"] == "tip_cubic" and row["two_ln_B"] > DECISIVE, res.rounds[0]["candidates"]
    # the two-mode model's ideal-clamp shapes move the tip's modal participation, so its k3
    # is an effective value: the structure's sign and order of magnitude, not its number
    k3 = row["parameters"]["k3"]
    assert 0.25 < k3["mode"] / (cantilever_kit.K3_TRUTH / 1e6) < 4.0, k3
    tests = row["held_out"]["tests"]
    assert tests["random_mid"]["after"] < tests["random_mid"]["before"], tests
    assert tests["sweep_mid"]["after"] > tests["sweep_mid"]["before"], tests
    # the evidence table shows the user both tests, not only the summed gain that hides the sweep's rise
    sweep = tests["sweep_mid"]
    assert f"sweep_mid {100 * sweep['before']:.3g} % -> {100 * sweep['after']:.3g} %" in evidence_table(res)
    assert list(res.named) == [], res.gap_sentence()
    # whatever the summed gain (with the front end's whole-record lines it was +559 sd), the
    # sweep predicted worse keeps it unnamed, and the table says why
    assert tests["sweep_mid"]["z"] < -3 and "decisive, but it predicts sweep_mid worse" in evidence_table(res)
    gap = res.gap_remaining()
    assert gap["held_out_times_noise"] > 3, gap
    assert f"{100 * gap['held_out_relative_error']:.3g} %" in res.gap_sentence(), res.gap_sentence()


def test_without_a_catalogue_effect_nothing_is_named_and_the_gap_is_reported(without_spring):
    res = without_spring
    assert list(res.named) == [], res.gap_sentence()
    gap = res.gap_remaining()
    # a two-mode model of a continuous beam leaves a held-out error many times the
    # records' noise (no higher modes, ideal-clamp shapes), and the result says so in numbers
    assert math.isfinite(gap["held_out_relative_error"]) and gap["held_out_times_noise"] > 3, gap
    assert f"{100 * gap['held_out_relative_error']:.3g} %" in res.gap_sentence(), res.gap_sentence()
