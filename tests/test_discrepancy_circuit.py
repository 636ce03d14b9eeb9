"""The discrepancy workflow on an electronic oscillator whose model is of another form:
the rig (tests/circuit_kit.py: scipy's DOP853 on a continuous excitation, input and
output filters, a velocity-growing damping and a quadratic stiffness when asked,
anti-alias decimation, noise on both channels) against a user's Duffing model
without the filters, which offers the quadratic stiffness and the damping as
candidates.  The filters are outside the catalogue: the model misses every test by
more than its noise whatever its parameters, as on a real record.

Checked against the rig's own constants: with neither effect nothing is named; with
both, both (the rig with one of them: benchmarks/discrepancy_cases.py); every named parameter
within 2 sd of the rig's, each held-out test predicted better with each named
effect, and the filters' gap reported in numbers.  The full-size runs are
benchmarks/discrepancy_cases.py (CIRCUIT_CASES)."""

from __future__ import annotations

import circuit_kit
import pytest

from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy

EFFECTS = {"k2": "quadratic_stiffness", "nu": "velocity_damping"}


# each case makes four records through the rig's DOP853 (about 30 s each): the case without
# an effect, which the cantilever's and the beam's null cases check too, runs with -m slow
@pytest.mark.parametrize(
    "rig",
    [
        pytest.param({"k2": 0.0, "nu": 0.0}, marks=pytest.mark.slow, id="neither"),
        pytest.param({"k2": -0.1, "nu": 2.0e-5}, id="both"),
    ],
)
def test_the_rigs_effects_are_named_and_the_filters_gap_reported(rig):
    data = circuit_kit.make_dataset(circuit_kit.SET_A + circuit_kit.HELD_OUT, **rig)
    res = find_discrepancy(
        data,
        circuit_kit.OscillatorWithCandidates(),
        settings=DiscrepancySettings.quick(),
        workers=2,
        progress=False,
        log=lambda *a: None,
    )
    hidden = sorted(EFFECTS[k] for k, v in rig.items() if v)
    assert sorted(res.named) == hidden, res.gap_sentence()
    effects = res.to_json()["final_mode"]["effects"]
    for k, v in rig.items():
        if v:
            fitted = effects[EFFECTS[k]][k]
            assert abs(fitted["mode"] - v) <= 2 * fitted["sd"], (k, v, fitted)
    for rnd in res.rounds:
        for row in rnd["candidates"]:
            if row["name"] in res.named:
                for test, err in row["held_out"]["tests"].items():
                    assert err["after"] < err["before"], (row["name"], test, err)
    # the filters leave a held-out error several times the noise, and the result says so
    gap = res.gap_remaining()
    assert gap["held_out_times_noise"] > 3, gap
    assert f"{100 * gap['held_out_relative_error']:.3g} %" in res.gap_sentence(), res.gap_sentence()
