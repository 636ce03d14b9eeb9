"""The discrepancy workflow (bayes_update.core.discrepancy) on the beam, on virtual-rig data
with a hidden effect: each of the four hidden in turn, none (over three noise
seeds), an effect outside the candidate catalogue, and a bow plus
amplitude-dependent damping.  Magnitudes are drawn from
HIDDEN_EFFECT_RANGES with a seed; the workflow is never told what is hidden.

Reduced settings (CI): three tests per data set (the two updating chirps and
the medium chirp for validation), fewer noise replicates and iterations; the
full run with the sine tests is benchmarks/discrepancy_cases.py.  Most cases
start the baseline at the paper's Table 3 with no band starts (the saving that
keeps the file in budget); one runs the real baseline search (start=None: the
deterministic start on coarse grids, then band starts), as the CLI does."""

import json
import math

import numpy as np
import pytest

import fe
from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy
from bayes_update.core.effects import DECISIVE, EXPLAINED_FACTOR
from bayes_update.core.mode import ModeResult, laplace_log_evidence
from bayes_update.models.beam.model import EFFECT_PARAMETERS, Beam, effect_values, hidden_effects
from bayes_update.models.beam.rig import rig_of
from bayes_update.models.beam.virtual_rig import PAPER_TESTS, VirtualRig, make_dataset
from bayes_update.reports.discrepancy import write_discrepancy

TESTS = [t for t in PAPER_TESTS if t.name in ("chirp_low", "chirp_high", "chirp_medium")]
# the paper's Table 3 as the baseline's start (prior knowledge; it saves the coarse grids)
START = {"eta": 3.0, "c": 15.0, "F": 77.0, "k_s": 180.0}
CANDIDATES = tuple(EFFECT_PARAMETERS)
SINGLE = ("initial_imperfection", "amplitude_dependent_damping", "shaker_attachment", "clamp_compliance")
# name -> hidden effects and how the workflow runs; magnitudes from hidden_effects(seed=1), noise seed 7
CASES = {
    **{name: dict(hidden=[name]) for name in SINGLE},
    "none": dict(hidden=[]),
    "none_seed8": dict(hidden=[], data_seed=8),
    "none_seed9": dict(hidden=[], data_seed=9),
    # the real baseline search: deterministic start on coarse grids, then band starts (two
    # candidates: the naming among all four is the bow case's above; this saves 40 s)
    "bow_from_no_start": dict(
        hidden=["initial_imperfection"],
        start=None,
        band_starts=True,
        candidates=["initial_imperfection", "amplitude_dependent_damping"],
    ),
    # an effect the catalogue does not hold
    "clamp_outside_catalogue": dict(
        hidden=["clamp_compliance"], candidates=[n for n in CANDIDATES if n != "clamp_compliance"]
    ),
    "combined": dict(hidden=["initial_imperfection", "amplitude_dependent_damping"], max_effects=2),
}

_cache = {}


def run_case(name):
    if name not in _cache:
        spec = CASES[name]
        effects = hidden_effects(spec["hidden"], seed=1)
        data = make_dataset(rig=VirtualRig(effects=effects), tests=TESTS, seed=spec.get("data_seed", 7))
        # one effect at most where at most one is hidden (the second round is the combined case's)
        settings = DiscrepancySettings.quick(
            max_effects=spec.get("max_effects", 1), extra_starts=spec.get("band_starts", False)
        )
        res = find_discrepancy(
            data,
            Beam(fe.BeamModel(rig=rig_of(data))),
            start=spec.get("start", START),
            candidates=spec.get("candidates"),
            settings=settings,
            workers=2,
            progress=False,
            log=lambda *a: None,
        )
        _cache[name] = (effects, data, res)
    return _cache[name]


def _check_named_effect(res, effect):
    """What docs/discrepancy.md claims for a named effect: decisive evidence with the
    naming fit's interval excluding "no effect", the model with it explains
    the data within noise and model error, and every hidden parameter inside
    the re-update's 2-sd interval with the mode within 10 % of the truth.

    The 2-sd interval alone does not discriminate: docs/discrepancy.md's re-update sds
    (damper 59 +- 69, shaker mass 14.6 +- 8.3 g) hold zero, so "no effect"
    would pass it; the mode within 10 % of the truth does not (measured here:
    1.1-2.6 % off for the five parameters of the four single cases, 2.3 % for
    the bow from no start, 0.3 % for both in the combined case; the
    full-settings benchmark 0-4.5 %)."""
    row = next(r for rnd in res.rounds for r in rnd["candidates"] if r["name"] == effect.name)
    assert row["two_ln_B"] > DECISIVE and row["excludes_null"], row
    got = res.to_json()["final_mode"]["effects"][effect.name]
    for name, t in effect_values(effect).items():
        m, sd = got[name]["mode"], got[name]["sd"]
        assert abs(m - t) <= 2.0 * sd, (name, t, got)
        assert abs(m - t) <= 0.1 * abs(t - got[name]["null"]), (name, t, got)


def _check_explains(res):
    assert res.explains_gap, res.misfit_ratio
    assert all(r <= EXPLAINED_FACTOR for r in res.misfit_ratio.values()), res.misfit_ratio


# every case -m slow (75-145 s each, the 15-minute budget), all four at full settings in
# benchmarks/discrepancy_cases.py; the default run names the bow in notebooks/05_discrepancy.ipynb
# the clamp's case is also a headline check (CI runs it after the suite)
@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=[pytest.mark.slow] + [pytest.mark.headline] * (n == "clamp_compliance")) for n in SINGLE],
)
def test_a_hidden_effect_is_named_and_the_gap_shrinks(name):
    (effect,), data, res = run_case(name)
    assert res.named == [name] and res.verdict == "named", res.rounds[0]["candidates"]
    b, a = res.gap_before, res.gap_after
    # docs/discrepancy.md's success criterion: e_lin + e_nlin and the validation misfit each shrink by more than 50 %
    assert a["e_lin"] + a["e_nlin"] <= 0.5 * (b["e_lin"] + b["e_nlin"])
    assert a["held_out_error_beyond_noise"] <= 0.5 * b["held_out_error_beyond_noise"]
    _check_named_effect(res, effect)
    _check_explains(res)


@pytest.mark.slow  # the suite's time; test_cli_discrepancy_writes_the_decision_and_the_evidence runs start=None too
def test_the_real_baseline_search_from_no_start_names_the_bow():
    """start=None: the deterministic start on coarse grids, the likelihood
    scales there, then least squares from it and from the band starts."""
    (effect,), data, res = run_case("bow_from_no_start")
    assert len(res.baseline.mode.starts) > 1  # the band starts ran
    assert res.named == ["initial_imperfection"], res.rounds[0]["candidates"]
    b, a = res.gap_before, res.gap_after
    assert a["e_lin"] + a["e_nlin"] <= 0.5 * (b["e_lin"] + b["e_nlin"])
    assert a["held_out_error_beyond_noise"] <= 0.5 * b["held_out_error_beyond_noise"]
    _check_named_effect(res, effect)
    _check_explains(res)


@pytest.mark.slow  # 114 s: the 15-minute budget; benchmarks/discrepancy_cases.py runs the null cases
def test_an_effect_outside_the_catalogue_is_not_given_a_wrong_name(tmp_path):
    """A clamp compliance hidden, the catalogue without clamp_compliance.  Under the
    landed likelihood (noise and model error only) a damper won the evidence decisively
    (2 ln B = 35) while leaving e_nlin at 45x what noise and model error allow; the
    honest likelihood counts the baseline's model-form error (the clamp's signature) for
    every model alike, and the held-out tests must be predicted better: nothing is named,
    and the gap is stated as a number."""
    _, data, res = run_case("clamp_outside_catalogue")
    assert res.named == [] and res.named_effect is None
    assert res.verdict == "no candidate explains the gap" and not res.explains_gap
    assert res.misfit_ratio["e_nlin"] > EXPLAINED_FACTOR
    best = res.rounds[0]["candidates"][0]
    print("\n[outside the catalogue] best", best["name"], best["two_ln_B"], best["held_out"])
    assert res.gap_after == res.gap_before
    doc = write_discrepancy(res, tmp_path)
    saved = json.loads((tmp_path / "discrepancy.json").read_text())
    assert (
        saved["named_effect"] is None and saved["named"] == [] and saved["verdict"] == "no candidate explains the gap"
    )
    assert saved["explains_gap"] is False and saved["gap_remaining"]["closed"] is False
    assert doc["verdict"] == saved["verdict"]
    assert "A gap remains" in (tmp_path / "evidence.md").read_text()


@pytest.mark.parametrize(
    "name",
    [
        pytest.param("none", marks=pytest.mark.slow),
        pytest.param("none_seed8", marks=pytest.mark.slow),
        pytest.param("none_seed9", marks=pytest.mark.slow),
    ],
)
def test_no_hidden_effect_names_none(name, tmp_path):
    """Three noise realisations of the rig without a hidden effect: nothing
    named, no candidate decisive, and the baseline explains the data."""
    _, data, res = run_case(name)
    assert res.named == [] and res.verdict == "no missing effect"
    assert all(c["two_ln_B"] <= DECISIVE or not c["excludes_null"] for c in res.rounds[0]["candidates"])
    _check_explains(res)
    assert res.gap_after == res.gap_before
    doc = write_discrepancy(res, tmp_path)
    saved = json.loads((tmp_path / "discrepancy.json").read_text())
    assert saved["named_effect"] is None and doc["named_effect"] is None
    assert {c["name"] for c in saved["candidates"]} == set(CANDIDATES)
    for key in ("gap_before", "gap_after"):
        assert {"e_lin", "e_nlin", "validation"} <= set(saved[key])
    assert (tmp_path / "gap_before_after.png").stat().st_size > 10_000


@pytest.mark.slow  # 63-95 s, outside the default run (15-minute budget); benchmarks/discrepancy_cases.py: full settings
def test_combined_case_names_both_and_closes_the_gap():
    """docs/discrepancy.md (combined case, full settings): both named, e_lin + e_nlin
    16.13 -> 0.44 %, validation 4.20 -> 0.35 %, bow 0.146 / 0.146 +- 0.036 mm,
    damper 32 / 31 +- 29.  Measured here (reduced settings): the damper then
    the bow named (2 ln B 921, then 1965), e_lin + e_nlin 10.7 -> 0.38 %,
    validation 2.58 -> 0.32 %, bow 0.127 / 0.127 +- 0.036 mm, damper 37.2 /
    37.1 +- 38, misfit 0.65x the allowance."""
    effects, data, res = run_case("combined")
    assert set(res.named) == {e.name for e in effects}, res.rounds
    b, a = res.gap_before, res.gap_after
    assert a["e_lin"] + a["e_nlin"] <= 0.5 * (b["e_lin"] + b["e_nlin"])
    assert a["held_out_error_beyond_noise"] <= 0.5 * b["held_out_error_beyond_noise"]
    for effect in effects:
        _check_named_effect(res, effect)
    _check_explains(res)


def test_laplace_evidence_of_a_linear_gaussian_model_is_exact():
    # r = A x - b with a uniform prior box: for a box much wider than the
    # posterior, Z = exp(-cost) (2 pi)^(d/2) det(A^T A)^(-1/2) / volume
    rng = np.random.default_rng(0)
    A = rng.standard_normal((50, 2)) * 10
    b = rng.standard_normal(50)
    x = np.linalg.lstsq(A, b, rcond=None)[0]
    r = A @ x - b
    widths = np.array([100.0, 100.0])
    mode = ModeResult(x=x, cost=0.5 * float(r @ r), jacobian=A, residual=r, n_evaluations=0, starts=[])
    logz = laplace_log_evidence(mode, -float(np.sum(np.log(widths))), widths)
    exact = (
        -0.5 * float(r @ r)
        + math.log(2 * math.pi)
        - 0.5 * np.linalg.slogdet(A.T @ A)[1]
        - float(np.sum(np.log(widths)))
    )
    assert logz == pytest.approx(exact, abs=1e-3)
    # a parameter the data do not constrain costs nothing (Occam factor 1)
    A0 = np.column_stack([A[:, 0], np.zeros(50)])
    x0 = np.array([np.linalg.lstsq(A0[:, :1], b, rcond=None)[0][0], 0.0])
    r0 = A0 @ x0 - b
    mode0 = ModeResult(x=x0, cost=0.5 * float(r0 @ r0), jacobian=A0, residual=r0, n_evaluations=0, starts=[])
    one = ModeResult(x=x0[:1], cost=mode0.cost, jacobian=A0[:, :1], residual=r0, n_evaluations=0, starts=[])
    z2 = laplace_log_evidence(mode0, -float(np.sum(np.log(widths))), widths)
    z1 = laplace_log_evidence(one, -math.log(widths[0]), widths[:1])
    assert z2 == pytest.approx(z1, abs=1e-6)


def test_candidate_values_round_trip_and_bad_input():
    beam = Beam(fe.BeamModel())
    for name, params in beam.candidate_effects().items():
        theta = {p.name: 0.5 * (p.low + p.high) + 0.1 * (p.high - p.low) for p in params}
        (effect,) = beam.effects_of(theta)
        assert effect.name == name
        got = effect_values(effect)
        assert np.allclose([got[n] for n in theta], list(theta.values()))
    assert beam.effects_of({p.name: 0.0 for ps in beam.candidate_effects().values() for p in ps}) == ()
    data = make_dataset(tests=TESTS[:2])
    with pytest.raises(ValueError, match="unknown candidate"):
        find_discrepancy(data, Beam(fe.BeamModel(rig=rig_of(data))), candidates=["gravity"], progress=False)
    with pytest.raises(ValueError, match="modal ROM"):
        find_discrepancy(data, Beam(fe.ModalROM(rig_of(data))), progress=False)
    with pytest.raises(ValueError, match="unknown effect"):
        hidden_effects(["gravity"], 0)


def test_cli_discrepancy_refuses_the_rom(tmp_path, capsys):
    from bayes_update.cli import main

    assert main(["discrepancy", "--model", "rom", "--out", str(tmp_path)]) == 2
    assert "modal ROM" in capsys.readouterr().err


# ------------------------------------------------------------------ the CLI
@pytest.fixture(scope="module")
def hidden_bow_dataset(tmp_path_factory):
    """`bayes-update make-dataset --hidden initial_imperfection` twice with the same --hidden-seed."""
    from bayes_update.cli import main

    out = tmp_path_factory.mktemp("hidden")
    for name, seed in (("a", "1"), ("b", "1"), ("c", "2")):
        assert (
            main(["make-dataset", "--hidden", "initial_imperfection", "--hidden-seed", seed, "--out", str(out / name)])
            == 0
        )
    return out


def test_cli_make_dataset_hidden_records_the_effect(hidden_bow_dataset):
    from bayes_update.data.folder import read_dataset
    from bayes_update.models.beam.model import HIDDEN_EFFECT_RANGES
    from bayes_update.models.beam.virtual_rig import load_default_dataset

    a, b = (json.loads((hidden_bow_dataset / n / "dataset.json").read_text()) for n in ("a", "b"))
    (effect,) = a["truth"]["effects"]
    assert effect["name"] == "initial_imperfection"
    lo, hi = HIDDEN_EFFECT_RANGES["initial_imperfection"]["amplitude"]
    assert lo <= abs(effect["amplitude"]) <= hi  # drawn from the stated range (either sign)
    assert b["truth"]["effects"] == a["truth"]["effects"]  # the same --hidden-seed, the same magnitude
    for f in (hidden_bow_dataset / "a").glob("*.csv"):  # ... and the same bytes
        assert f.read_bytes() == (hidden_bow_dataset / "b" / f.name).read_bytes(), f.name
    other = json.loads((hidden_bow_dataset / "c" / "dataset.json").read_text())["truth"]["effects"][0]
    assert other["amplitude"] != effect["amplitude"]  # another seed, another magnitude
    # the data differ from the default data set (same noise seed, 1 % of RMS) by more than the noise
    # could: measured 0.22 of the high chirp's velocity (0.35 of the low one's: the bow moves f1) for
    # this 0.127 mm bow; 5x the noise leaves 4x margin
    data, default = read_dataset(hidden_bow_dataset / "a"), load_default_dataset()
    assert [t.name for t in data.tests] == [t.name for t in default.tests]
    high = {t.name: t for t in data.tests}["chirp_high"], {t.name: t for t in default.tests}["chirp_high"]
    assert np.array_equal(high[0].force, high[1].force)
    rel = np.linalg.norm(high[0].velocity - high[1].velocity) / np.linalg.norm(high[1].velocity)
    assert rel > 5 * 0.01, rel


@pytest.mark.slow  # 140 s: the 15-minute budget; notebooks/05 names the bow in the default run
def test_cli_discrepancy_writes_the_decision_and_the_evidence(hidden_bow_dataset, tmp_path):
    """`bayes-update discrepancy --quick` on the make-dataset output (start=None: the
    deterministic start on coarse grids, as a user runs it)."""
    from bayes_update.cli import main

    out = tmp_path / "disc"
    assert (
        main(
            [
                "discrepancy",
                "--data",
                str(hidden_bow_dataset / "a"),
                "--quick",
                "--workers",
                "2",
                "--candidates",
                "initial_imperfection",
                "amplitude_dependent_damping",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    doc = json.loads((out / "discrepancy.json").read_text())
    assert {
        "named_effect",
        "named",
        "verdict",
        "explains_gap",
        "candidates",
        "gap_before",
        "gap_after",
        "signature_check",
        "truth",
    } <= set(doc)
    assert doc["named_effect"] == "initial_imperfection" and doc["verdict"] == "named" and doc["explains_gap"]
    assert {c["name"] for c in doc["candidates"]} == {"initial_imperfection", "amplitude_dependent_damping"}
    for c in doc["candidates"]:
        assert {"two_ln_B", "delta_log_likelihood", "parameters", "excludes_null"} <= set(c)
    for key in ("gap_before", "gap_after"):
        assert {"e_lin", "e_nlin", "validation"} <= set(doc[key])
    b, a = doc["gap_before"], doc["gap_after"]
    assert (
        a["e_lin"] + a["e_nlin"] <= 0.5 * (b["e_lin"] + b["e_nlin"])
        and a["held_out_error_beyond_noise"] <= 0.5 * b["held_out_error_beyond_noise"]
    )
    # the truth block travels to the output; the re-updated bow covers it
    (hidden,) = doc["truth"]["effects"]
    got = doc["final_mode"]["effects"]["initial_imperfection"]["bow_amplitude"]
    assert abs(got["mode"] - 1e3 * hidden["amplitude"]) <= 2 * got["sd"]
    # evidence.md: the table with one row per candidate and the decision
    text = (out / "evidence.md").read_text()
    assert "| candidate | 2 ln B | gain in log L |" in text
    rows = [
        line
        for line in text.splitlines()
        if line.startswith("| initial_imperfection |") or line.startswith("| amplitude_dependent_damping |")
    ]
    assert len(rows) >= 2, text
    row = next(line for line in rows if line.startswith("| initial_imperfection |"))
    assert float(row.split("|")[2]) == pytest.approx(
        next(c["two_ln_B"] for c in doc["candidates"] if c["name"] == "initial_imperfection"), abs=0.06
    )
    assert "Named: **initial_imperfection**" in text
    for name in ("gap_before_after.png", "diagnostics_before.png", "diagnostics_after.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and (out / name).stat().st_size > 10_000
