"""The discrepancy workflow on a model the framework has never seen (bayes_update.core.discrepancy).

The Duffing oscillator of tests/test_user_model.py offers two candidate effects through
``candidate_effects()``: a quadratic spring (k2, a broken symmetry: y2) and quadratic damping (c2,
odd: y3), so naming one is a real choice.  Data come from a finer version of the model (16 RK4 steps
per sample against 4) with 1 % noise on force and response: a linear, a nonlinear and a validation
test (band-limited noise, a signal the updating never sees).  Never told what is hidden, the workflow
must name k2 where k2 is hidden, and nothing where nothing is.
"""

import json
import subprocess
import sys

import numpy as np
import pytest
from numba import njit

from bayes_update import Parameter


# ----------------------------------------------------------------------------- the model
@njit(cache=False)
def _acc(x, v, u, m, wn, zeta, k2, k3, c2):
    return (u - k2 * x * x - k3 * x**3 - c2 * v * abs(v)) / m - 2 * zeta * wn * v - wn * wn * x


@njit(cache=False)
def _velocity(f, fs, m, wn, zeta, k2, k3, c2, substeps):
    h, x, v = 1.0 / (fs * substeps), 0.0, 0.0
    out = np.zeros(f.size)
    for i in range(f.size - 1):
        for s in range(substeps):  # RK4, the force linear between samples
            u0, u1 = f[i] + (f[i + 1] - f[i]) * s / substeps, f[i] + (f[i + 1] - f[i]) * (s + 1) / substeps
            um = 0.5 * (u0 + u1)
            a1 = _acc(x, v, u0, m, wn, zeta, k2, k3, c2)
            a2 = _acc(x + 0.5 * h * v, v + 0.5 * h * a1, um, m, wn, zeta, k2, k3, c2)
            a3 = _acc(x + 0.5 * h * (v + 0.5 * h * a1), v + 0.5 * h * a2, um, m, wn, zeta, k2, k3, c2)
            a4 = _acc(x + h * (v + 0.5 * h * a2), v + h * a3, u1, m, wn, zeta, k2, k3, c2)
            x, v = x + h * v + h * h * (a1 + a2 + a3) / 6, v + h * (a1 + 2 * a2 + 2 * a3 + a4) / 6
        out[i + 1] = v
    return out


class Duffing:
    """m x'' + 2 zeta wn m x' + m wn^2 x + k3 x^3 [+ k2 x^2 + c2 v|v|] = f (m = 0.1 kg); velocity out."""

    parameters = [
        Parameter("fn", 30.0, 50.0, unit="Hz"),
        Parameter("zeta", 0.005, 0.08, log=True),
        Parameter("k3", 0.0, 10.0, unit="1e8 N/m^3"),
    ]

    def __init__(self, substeps=4):
        self.substeps = substeps

    def candidate_effects(self):
        return {
            "k2": [Parameter("k2", -20.0, 20.0, unit="1e5 N/m^2", null=0.0)],
            "c2": [Parameter("c2", 0.0, 5.0, unit="N s^2/m^2", null=0.0)],
        }

    def simulate(self, theta, force, fs):
        return _velocity(
            np.asarray(force, float),
            fs,
            0.1,
            2 * np.pi * theta["fn"],
            theta["zeta"],
            1e5 * theta.get("k2", 0.0),
            1e8 * theta["k3"],
            theta.get("c2", 0.0),
            self.substeps,
        )

    def refined(self):
        return Duffing(4 * self.substeps)


# ---------------------------------------------------------------------------------------------------


TRUTH = {"fn": 41.3, "zeta": 0.021, "k3": 4.2}
FS = 1187.5  # a sampling rate that is not a round number [Hz]


def make_dataset(hidden=None, seed=0, snr_db=40.0, n=4096, high=0.4, medium=0.5):
    """Low (linear) and high (nonlinear) chirps 15 -> 75 Hz in 2.2 s then free decay, and band-limited
    noise (15-75 Hz) for validation, from the refined model with ``hidden`` = {effect parameter: value};
    white noise of 1 % RMS on the force and on the response."""
    from scipy import signal

    import fe
    from bayes_update.data.dataset import Dataset, Record

    t = np.arange(n) / FS
    T = 2.2
    sweep = np.sin(2 * np.pi * (15 * t + (75 - 15) / (2 * T) * t**2)) * (t < T)
    rng = np.random.default_rng(seed)
    band = signal.sosfiltfilt(signal.butter(4, [15, 75], "bandpass", fs=FS, output="sos"), rng.standard_normal(n))
    truth = {**TRUTH, **(hidden or {})}
    truth_model = Duffing().refined()
    tests = []
    for name, level, f, role in (
        ("chirp_low", "low", 0.05 * sweep, "linear"),
        ("chirp_high", "high", high * sweep, "nonlinear"),
        ("noise_medium", "medium", medium * band / np.std(band), "validation"),
    ):
        y = truth_model.simulate(truth, f, FS)
        noisy = [z + 10 ** (-snr_db / 20) * np.sqrt(np.mean(z**2)) * rng.standard_normal(n) for z in (f, y)]
        tests.append(Record(f"{name}.csv", name.split("_")[0], level, role, t, *noisy))
    return Dataset("duffing", FS, fe.Rig(), tests, extra={"truth": truth})


HIDDEN_K2 = 8.0  # [1e5 N/m^2]: k2 x^2 is about a tenth of the linear spring's force at the high level


def _run(hidden):
    from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy

    return find_discrepancy(
        make_dataset(hidden), Duffing(), settings=DiscrepancySettings.quick(), workers=2, log=lambda *a: None
    )


@pytest.fixture(scope="module")
def hidden_k2():
    return _run({"k2": HIDDEN_K2})


@pytest.fixture(scope="module")
def no_effect():
    return _run({})


def test_hidden_quadratic_spring_is_named_and_closes_the_gap(hidden_k2):
    from bayes_update.core.effects import DECISIVE, EXPLAINED_FACTOR, misfit_ratios

    res = hidden_k2
    b, a = res.gap_before, res.gap_after
    # the gap is real: the baseline leaves e_nlin far beyond what noise and model error allow, and the
    # validation error well above its noise floor (about 1.1 % with 1 % noise on both channels)
    assert misfit_ratios(res.baseline, res.likelihood)["e_nlin"] > 2 * EXPLAINED_FACTOR
    assert b["held_out_error_beyond_noise"] > 0.025, b
    # k2, and only k2, is named; the other candidate fails the rule in both rounds
    assert res.named == ["k2"] and res.verdict == "named" and res.explains_gap
    rows = {r["name"]: r for r in res.rounds[0]["candidates"]}
    assert rows["k2"]["two_ln_B"] > DECISIVE and rows["k2"]["excludes_null"], rows["k2"]
    for rnd in res.rounds:
        c2 = next(r for r in rnd["candidates"] if r["name"] == "c2")
        assert c2["two_ln_B"] <= DECISIVE or not c2["excludes_null"], c2
    # the re-updated k2 covers the truth with its Laplace interval, in its unit
    k2 = res.final.to_json(res.effects)["effects"]["k2"]["k2"]
    assert k2["interval"][0] <= HIDDEN_K2 <= k2["interval"][1] and k2["unit"] == "1e5 N/m^2", k2
    # the gap closes: e_nlin and the validation error at most half of before
    assert (
        a["e_nlin"] <= 0.5 * b["e_nlin"] and a["held_out_error_beyond_noise"] <= 0.5 * b["held_out_error_beyond_noise"]
    ), (b, a)
    assert all(r <= EXPLAINED_FACTOR for r in res.misfit_ratio.values()), res.misfit_ratio
    doc = res.to_json()
    assert doc["named_effect"] == "k2" and doc["named"] == ["k2"]
    assert set(doc["final_mode"]["parameters"]) == {"fn", "zeta", "k3"}


def test_hidden_quadratic_damping_is_named_not_the_spring():
    """The other candidate hidden: the choice goes the other way."""
    res = _run({"c2": 1.0})
    rows = [(r["name"], r["two_ln_B"]) for r in res.rounds[0]["candidates"]]
    assert res.named == ["c2"] and res.verdict == "named", rows
    c2 = res.final.to_json(res.effects)["effects"]["c2"]["c2"]
    assert c2["interval"][0] <= 1.0 <= c2["interval"][1], c2
    assert res.gap_after["e_nlin"] <= 0.5 * res.gap_before["e_nlin"], (res.gap_before, res.gap_after)


def test_no_hidden_effect_names_nothing(no_effect):
    from bayes_update.core.effects import DECISIVE, EXPLAINED_FACTOR

    res = no_effect
    assert res.named == [] and res.verdict == "no missing effect", res.verdict
    assert all(c["two_ln_B"] <= DECISIVE or not c["excludes_null"] for c in res.rounds[0]["candidates"])
    assert {c["name"] for c in res.rounds[0]["candidates"]} == {"k2", "c2"}
    assert all(r <= EXPLAINED_FACTOR for r in res.misfit_ratio.values()), res.misfit_ratio
    assert res.gap_after == res.gap_before and res.gap_before["held_out_error_beyond_noise"] < 0.02, res.gap_before


class _NoCandidates:
    """The Duffing without candidate_effects()."""

    parameters = Duffing.parameters
    simulate = Duffing.simulate

    def __init__(self, substeps=4):
        self.substeps = substeps


class _NoneCandidates(Duffing):
    candidate_effects = None


class _NoNull(Duffing):
    def candidate_effects(self):
        return {"k2": [Parameter("k2", -20.0, 20.0, unit="1e5 N/m^2")]}


def test_a_model_without_candidates_or_nulls_is_told_what_to_add():
    from bayes_update.core import ModelSpecError
    from bayes_update.core.discrepancy import find_discrepancy

    data = make_dataset(n=1024)
    with pytest.raises(ModelSpecError, match=r"has no candidate_effects\(\).*add a method"):
        find_discrepancy(data, _NoCandidates(), workers=1)
    # a hook set to None is a member of the wrong type (told by the contract's check, for every command)
    with pytest.raises(ModelSpecError, match=r"candidate_effects is None .*not a method.*candidate_effects\(\) ->"):
        find_discrepancy(data, _NoneCandidates(), workers=1)
    with pytest.raises(ModelSpecError, match="parameter 'k2' has no null value"):
        find_discrepancy(data, _NoNull(), workers=1)


def test_cli_discrepancy_with_a_model_from_a_file(tmp_path):
    from bayes_update.cli import main
    from bayes_update.data.folder import write_dataset

    write_dataset(make_dataset({"k2": HIDDEN_K2}), tmp_path / "data")
    out = tmp_path / "out"
    assert (
        main(
            [
                "discrepancy",
                "--model",
                f"{__file__}:Duffing",
                "--data",
                str(tmp_path / "data"),
                "--out",
                str(out),
                "--quick",
                "--workers",
                "2",
            ]
        )
        == 0
    )
    doc = json.loads((out / "discrepancy.json").read_text())
    assert doc["named"] == ["k2"] and doc["named_effect"] == "k2" and doc["verdict"] == "named"
    assert {"candidates", "gap_before", "gap_after", "misfit_ratio", "gap_remaining", "gap_sentence"} <= set(doc)
    assert doc["gap_after"]["e_nlin"] <= 0.5 * doc["gap_before"]["e_nlin"]
    assert "Named: **k2**" in (out / "evidence.md").read_text()
    assert (out / "gap_before_after.png").stat().st_size > 20_000
    # a model without candidate_effects(): one line saying what to add, nothing written
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "bayes_update",
            "discrepancy",
            "--model",
            f"{__file__}:_NoCandidates",
            "--data",
            str(tmp_path / "data"),
            "--out",
            str(tmp_path / "none"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert "has no candidate_effects()" in res.stderr and not (tmp_path / "none" / "discrepancy.json").exists()
