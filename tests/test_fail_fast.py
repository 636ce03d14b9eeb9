"""Fail fast (issues 40 and 43): every error a user can make in the model's contract, the data
set's structure, the scheduler's address or the settings is told in one line, before any long
step (the first look at the data, the noise estimate, the basis fit, the start search).

No test here times anything (timings never decide a test: benchmarks/fail_fast.py measures
them).  Each asserts the order instead: the model runs at most once (a model that counts its
runs), and the long steps are never reached (each replaced by a stand-in that fails the test
when it is called).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest
from new_user_kit import Spring, make_dataset

import bayes_update as bu
from bayes_update import DatasetError, ModelRunError, ModelSpecError, Parameter
from bayes_update.cli import main
from bayes_update.data.folder import write_dataset

HERE = __file__


class LongStepReached(AssertionError):
    """A long step was reached: the error came too late.  (An AssertionError: the command
    line's one-line reporting does not catch it, so it fails the test.)"""


# ------------------------------------------------------------------ models, one fault each
class Counting(Spring):
    """The new user's spring; counts its runs (every test runs it in this process, workers=1)."""

    runs = 0
    thetas: list = []

    def simulate(self, theta, force, fs):
        Counting.runs += 1
        Counting.thetas.append(dict(theta))
        return super().simulate(theta, force, fs)


class ShortByOne(Counting):
    def simulate(self, theta, force, fs):
        return super().simulate(theta, force, fs)[:-1]


class WithEffects(Counting):
    """A model the discrepancy workflow takes: it offers a quadratic spring."""

    def candidate_effects(self):
        return {"k2": [Parameter("k2", -1.0, 1.0, unit="kN/m^2", null=0.0)]}


class ShortWithEffects(WithEffects):
    def simulate(self, theta, force, fs):
        return super().simulate(theta, force, fs)[:-1]


class NaNAtTheMiddle(Counting):
    def simulate(self, theta, force, fs):
        y = super().simulate(theta, force, fs)
        y[7] = np.nan
        return y


class ComplexOut(Counting):
    def simulate(self, theta, force, fs):
        return super().simulate(theta, force, fs) * (1.0 + 0.1j)


class RefinedNone(Counting):
    refined = None


class RefineMisspelt(Counting):
    def refine(self):  # meant as refined(): the framework would ignore it
        return Counting()


class EffectMisspelt(Counting):
    def candidate_effect(self):  # meant as candidate_effects()
        return {"k2": [Parameter("k2", -1.0, 1.0, null=0.0)]}


class EffectsNotCallable(Counting):
    candidate_effects = {"k2": [Parameter("k2", -1.0, 1.0, null=0.0)]}


class MetricsMisnamed(Counting):
    default_metrics = "ful"


class TupleParameters(Counting):
    parameters = [("fn", 15.0, 35.0), ("zeta", 0.005, 0.1)]


class IgnoresItsParameters(Counting):
    def simulate(self, theta, force, fs):
        return super().simulate({"fn": 23.0, "zeta": 0.03, "k": 4.0}, force, fs)


class RunsOnlyAtTheMiddle(Counting):
    def simulate(self, theta, force, fs):
        if abs(theta["fn"] - 25.0) > 1e-9:
            raise bu.ModelError("outside the one point this model runs at")
        return super().simulate(theta, force, fs)


# -------------------------------------------------------------------------- fixtures
@pytest.fixture(autouse=True)
def fresh_counts():
    Counting.runs, Counting.thetas = 0, []
    from bayes_update.core import preflight

    preflight._PASSED.clear()  # each test checks from scratch
    yield


@pytest.fixture
def no_long_steps(monkeypatch):
    """The long steps, each a stand-in that fails the test: the command line's first look at the
    data (OUT/inspection), the problem (the basis fit and the noise estimate) and Dask's client."""
    import bayes_update.cli.commands as commands
    import bayes_update.core.problem as problem

    def reached(what):
        def stand_in(*args, **kwargs):
            raise LongStepReached(f"the error came after a long step began: {what}")

        return stand_in

    monkeypatch.setattr(commands, "_first_look", reached("the first look at the data"))
    monkeypatch.setattr(problem.Problem, "__init__", reached("the problem (basis fit, noise estimate)"))
    try:
        import distributed
    except ImportError:  # a dev extra: without it --scheduler stops at its own check
        return
    monkeypatch.setattr(distributed, "Client", reached("Dask's client"))


@pytest.fixture(scope="module")
def data():
    return make_dataset()


@pytest.fixture(scope="module")
def folder(data, tmp_path_factory):
    return write_dataset(data, tmp_path_factory.mktemp("spring") / "data")


def _roles(data, **roles):
    """``data`` with the given tests' roles changed ({test name: role})."""
    import dataclasses

    return dataclasses.replace(data, tests=[dataclasses.replace(t, role=roles.get(t.name, t.role)) for t in data.tests])


def _cli(capsys, *argv):
    """(exit status, the one error line) of ``bayes-update argv``; fails on a traceback or on
    an error of more than one line."""
    status = main(list(argv) + ["--workers", "1"])
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ": error: " in ln]
    assert status == 2 and len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _one_line(exc) -> str:
    text = str(exc)
    assert "\n" not in text, text
    return text


API = {
    "calibrate": lambda d, m: bu.calibrate(d, m, workers=1, progress=False, n_start=8),
    "sample": lambda d, m: bu.sample(d, m, bu.PosteriorSettings.quick(), workers=1, progress=False),
    "discrepancy": lambda d, m: bu.find_discrepancy(d, m, workers=1),
}


# ------------------------------------------------------------- the model's one check run
@pytest.mark.parametrize("verb", ["calibrate", "sample"])
def test_cli_a_response_one_sample_short_is_told_after_one_run(verb, folder, tmp_path, capsys, no_long_steps):
    line = _cli(capsys, verb, "--model", f"{HERE}:ShortByOne", "--data", str(folder), "--out", str(tmp_path / "o"))
    assert "ShortByOne.simulate returned shape (2047,) for a force of 2048 samples" in line, line
    assert "fn = 25 Hz" in line and "one value per input sample" in line, line  # theta, remedy
    assert Counting.runs == 1
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("verb", sorted(API))
def test_api_a_response_one_sample_short_is_told_after_one_run(verb, data, no_long_steps):
    with pytest.raises(ModelRunError, match=r"Short\w*.simulate returned shape \(2047,\)") as info:
        API[verb](data, ShortByOne() if verb != "discrepancy" else ShortWithEffects())
    _one_line(info.value)
    assert Counting.runs == 1


def test_the_check_run_is_at_the_middle_of_the_prior_with_every_effect_at_its_null(data, no_long_steps):
    model = ShortWithEffects()
    with pytest.raises(ModelRunError):
        bu.find_discrepancy(data, model, workers=1)
    (theta,) = Counting.thetas
    assert theta == pytest.approx({"fn": 25.0, "zeta": np.sqrt(0.005 * 0.1), "k": 5.0, "k2": 0.0})


def test_api_nan_in_the_response_is_told_after_one_run(data, no_long_steps):
    with pytest.raises(ModelRunError, match="NaNAtTheMiddle.simulate returned 1 non-finite") as info:
        API["sample"](data, NaNAtTheMiddle())
    assert "ModelError" in _one_line(info.value)  # the remedy: raise ModelError, never NaN
    assert Counting.runs == 1


def test_a_complex_response_is_refused_not_cast(data, no_long_steps):
    """Cast to float it would lose its imaginary part without a word (it did: calibrate ran to
    the end on the real part)."""
    with pytest.raises(ModelRunError, match="dtype complex128") as info:
        API["calibrate"](data, ComplexOut())
    assert "real numbers" in _one_line(info.value)
    assert Counting.runs == 1
    # every later run goes through the same check (Problem.run)
    from bayes_update.core.model import check_response

    with pytest.raises(ModelRunError, match="dtype complex128"):
        check_response(ComplexOut(), {"fn": 20.0}, np.ones(4, complex), 4, 1)


# -------------------------------------------------------------- the data set's structure
def test_cli_two_tests_nonlinear_are_two_stages(data, tmp_path, no_long_steps):
    """Two tests with role 'nonlinear' are two stages of the estimation (a campaign's levels,
    tests/test_campaign_levels.py): the command passes the roles' check and reaches its
    first long step."""
    two = write_dataset(_roles(data, medium_check="nonlinear"), tmp_path / "two")
    argv = ["sample", "--quick", "--model", f"{HERE}:Counting", "--data", str(two), "--out", str(tmp_path / "o")]
    with pytest.raises(LongStepReached):
        main(argv + ["--workers", "1"])
    assert Counting.runs == 1  # the preflight's one run at the middle of the prior, then the first long step


@pytest.mark.parametrize("verb", sorted(API))
def test_api_roles_are_checked_before_any_model_run(verb, data, no_long_steps):
    import dataclasses

    model = Counting() if verb != "discrepancy" else WithEffects()
    twice = dataclasses.replace(data, tests=[*data.tests, data.tests[-1]])
    with pytest.raises(DatasetError, match="appear more than once"):
        API[verb](twice, model)
    with pytest.raises(DatasetError, match="no test has role 'nonlinear'") as info:
        API[verb](_roles(data, loud_high="validation"), model)
    assert "dataset.json" in _one_line(info.value)
    assert Counting.runs == 0


# ---------------------------------------------------------------------- the scheduler
def test_cli_an_unreachable_scheduler_before_the_data_is_read(folder, tmp_path, capsys, monkeypatch, no_long_steps):
    import bayes_update.cli.commands as commands

    monkeypatch.setattr(commands, "read_dataset", lambda *a: (_ for _ in ()).throw(LongStepReached("data read")))
    line = _cli(
        capsys,
        "calibrate",
        "--model",
        f"{HERE}:Counting",
        "--data",
        str(folder),
        "--out",
        str(tmp_path / "o"),
        "--scheduler",
        "tcp://127.0.0.1:9",
    )
    assert "--scheduler tcp://127.0.0.1:9: no Dask scheduler answers there" in line and "start one" in line, line
    assert Counting.runs == 0
    line = _cli(
        capsys,
        "sample",
        "--model",
        f"{HERE}:Counting",
        "--data",
        str(folder),
        "--out",
        str(tmp_path / "o"),
        "--scheduler",
        "tcp://127.0.0.1:port",
    )
    assert "expected tcp://HOST:PORT" in line, line


# -------------------------------------------------------------- the optional members
def test_cli_refined_none_is_told_in_one_line_before_any_run(folder, tmp_path, capsys, no_long_steps):
    line = _cli(
        capsys,
        "sample",
        "--quick",
        "--model",
        f"{HERE}:RefinedNone",
        "--data",
        str(folder),
        "--out",
        str(tmp_path / "o"),
    )
    assert "RefinedNone.refined is None" in line and "not a method" in line and "delete it" in line, line
    assert Counting.runs == 0


@pytest.mark.parametrize(
    "cls, name, hook",
    [(RefineMisspelt, "refine", "refined"), (EffectMisspelt, "candidate_effect", "candidate_effects")],
)
@pytest.mark.parametrize("verb", ["calibrate", "sample"])
def test_api_a_misspelt_hook_is_named_with_the_hook_it_is_close_to(verb, cls, name, hook, data, no_long_steps):
    with pytest.raises(ModelSpecError) as info:
        API[verb](data, cls())
    text = _one_line(info.value)
    assert f"{cls.__name__}.{name} is not a member the framework knows" in text and f"no {hook!r}" in text, text
    assert "rename it" in text and "underscore" in text, text
    assert Counting.runs == 0


@pytest.mark.parametrize(
    "cls, what",
    [
        (EffectsNotCallable, "candidate_effects is {"),
        (MetricsMisnamed, "default_metrics is 'ful'; it must be 'full' or 'paper'"),
    ],
)
def test_api_an_optional_member_of_the_wrong_type(cls, what, data, no_long_steps):
    with pytest.raises(ModelSpecError) as info:
        API["sample"](data, cls())
    assert what in _one_line(info.value), info.value
    assert Counting.runs == 0


def test_the_models_of_the_repository_are_not_taken_for_misspelt_ones():
    """The contract's check refuses no model this repository ships or tests with: the beam (all
    its hooks), the docs' Duffing, the lab chain, the OpenSeesPy frame's file, the new user's."""
    from test_measured_records import LabChain
    from test_user_model import Duffing

    from bayes_update import load_model
    from bayes_update.core.model import check_contract
    from bayes_update.models.beam.model import beam_model

    models = [beam_model(None, "rom"), Duffing(), LabChain(), Spring(), Counting()]
    try:
        models.append(
            load_model(str(Path(HERE).resolve().parents[1] / "notebooks" / "portal_frame.py") + ":PortalFrame")
        )
    except ModelSpecError:  # openseespy is a dev extra
        pass
    for model in models:
        check_contract(model)


def test_cli_parameters_that_are_not_parameter_objects_with_a_prior(folder, tmp_path, capsys, no_long_steps):
    """--prior read the declared parameters before any check: a tuple ended in an AttributeError's
    traceback."""
    line = _cli(
        capsys,
        "calibrate",
        "--model",
        f"{HERE}:TupleParameters",
        "--data",
        str(folder),
        "--out",
        str(tmp_path / "o"),
        "--prior",
        "fn=20:30",
    )
    assert "TupleParameters.parameters" in line and "bayes_update.Parameter" in line, line
    assert Counting.runs == 0


# ------------------------------------------------------------------------ the settings
def test_cli_an_unknown_calibrate_setting_before_the_data_is_read(folder, tmp_path, capsys, monkeypatch, no_long_steps):
    import bayes_update.cli.commands as commands

    monkeypatch.setattr(commands, "read_dataset", lambda *a: (_ for _ in ()).throw(LongStepReached("data read")))
    cfg = tmp_path / "c.toml"
    cfg.write_text("[calibrate]\nn_starts = 8\n")
    line = _cli(
        capsys,
        "calibrate",
        "--model",
        f"{HERE}:Counting",
        "--data",
        str(folder),
        "--out",
        str(tmp_path / "o"),
        "--config",
        str(cfg),
    )
    assert "unknown setting(s) ['n_starts']" in line and "n_start" in line, line
    cfg.write_text("[calibrate]\nn_start = 'many'\n")
    line = _cli(
        capsys,
        "calibrate",
        "--model",
        f"{HERE}:Counting",
        "--data",
        str(folder),
        "--out",
        str(tmp_path / "o"),
        "--config",
        str(cfg),
    )
    assert "must be whole numbers" in line, line


@pytest.mark.parametrize("verb", ["calibrate", "discrepancy"])
def test_cli_prior_reaches_calibrate_and_discrepancy(verb, folder, tmp_path, capsys, monkeypatch):
    """--prior was read and then ignored for a model of your own in calibrate and discrepancy."""
    import bayes_update.cli.commands as commands
    import bayes_update.core.calibrate as calibrate
    import bayes_update.core.discrepancy as discrepancy

    seen = {}

    def stop(data, model, **kw):
        seen.update(kw)
        raise LongStepReached("stop here")

    monkeypatch.setattr(calibrate, "calibrate_model", stop)
    monkeypatch.setattr(discrepancy, "find_discrepancy", stop)
    monkeypatch.setattr(commands, "_first_look", lambda *a: None)
    model = "Counting" if verb == "calibrate" else "WithEffects"
    with pytest.raises(LongStepReached):
        main(
            [
                verb,
                "--model",
                f"{HERE}:{model}",
                "--data",
                str(folder),
                "--out",
                str(tmp_path / "o"),
                "--prior",
                "fn=20:24",
                "--workers",
                "1",
            ]
        )
    space = seen["space"]
    assert (space["fn"].low, space["fn"].high, space["fn"].unit) == (20.0, 24.0, "Hz")
    assert (space["k"].low, space["k"].high) == (2.0, 8.0)


def test_calibrate_keeps_to_the_prior_it_is_given(data):
    """The prior given (e.g. --prior) is the one searched: the result, the check run and every
    design point lie inside it."""
    space = bu.ParameterSet(
        [
            Parameter("fn", 20.0, 22.0, unit="Hz"),
            Parameter("zeta", 0.005, 0.1, log=True),
            Parameter("k", 2.0, 8.0, unit="kN/m"),
        ]
    )
    cal = bu.calibrate(data, Counting(), space=space, n_start=8, workers=1, progress=False, log=lambda *a: None)
    assert 20.0 <= cal.theta["fn"] <= 22.0 and cal.problem.space is space
    assert Counting.thetas[0]["fn"] == pytest.approx(21.0)
    assert all(20.0 <= t["fn"] <= 22.0 + 1e-9 for t in Counting.thetas)


# ------------------------------------------------------------ errors the user can fix
def test_a_model_that_ignores_its_parameters_is_a_model_error_not_a_runtime_error(data):
    with pytest.raises(ModelSpecError, match="does not move with any parameter") as info:
        bu.calibrate(data, IgnoresItsParameters(), n_start=8, workers=1, progress=False, log=lambda *a: None)
    assert "theta[name]" in _one_line(info.value)


def test_a_model_that_runs_nowhere_but_the_middle_is_told(data):
    """Every design point raised ModelError: before, these ranked like any cost and the search went
    on from points that never ran."""
    with pytest.raises(ModelSpecError, match="raised ModelError at all 8 points of the stage 1 design") as info:
        bu.calibrate(data, RunsOnlyAtTheMiddle(), n_start=8, workers=1, progress=False, log=lambda *a: None)
    assert "narrow the prior" in _one_line(info.value)


def test_span_and_design_faults_are_typed():
    from bayes_update.core.span import span_of

    with pytest.raises(ModelSpecError, match="does not move with any parameter"):
        span_of(np.zeros((5, 2)), "linear")


# ------------------------------------------------------------------ once, and only once
def test_the_command_line_checks_once_before_its_first_look(folder, tmp_path, capsys, monkeypatch):
    """The command line checks before its first look at the data; the function it calls then
    finds the same model, data and prior checked: one check run in all."""
    import bayes_update.cli.commands as commands
    import bayes_update.core.problem as problem

    order = []
    monkeypatch.setattr(commands, "_first_look", lambda *a: order.append(("first look", Counting.runs)))

    def built(*a, **kw):
        order.append(("problem", Counting.runs))
        raise LongStepReached("stop at the problem")

    monkeypatch.setattr(problem.Problem, "__init__", built)
    with pytest.raises(LongStepReached):
        main(
            [
                "sample",
                "--quick",
                "--model",
                f"{HERE}:Counting",
                "--data",
                str(folder),
                "--out",
                str(tmp_path / "o"),
                "--workers",
                "1",
            ]
        )
    assert order == [("first look", 1), ("problem", 1)]


def test_a_model_changed_since_its_check_is_checked_again(data, no_long_steps):
    from bayes_update.core.preflight import preflight

    model = Counting()
    preflight(data, model)
    preflight(data, model)
    assert Counting.runs == 1
    model.kind = "velocity"  # another state: checked again
    preflight(data, model)
    assert Counting.runs == 2


def test_cli_prior_on_the_beams_calibrate_is_refused(tmp_path, capsys):
    """The beam's calibrate searches the paper's grids: a --prior would be ignored, so it is
    refused in one line (status 2) before the data are read, naming what to use instead."""
    from bayes_update.cli import main

    t0 = time.perf_counter()
    code = main(["calibrate", "--model", "rom", "--prior", "eta=3.5:4", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and time.perf_counter() - t0 < 5.0, err
    assert len(err.strip().splitlines()) == 1 and "eta_values" in err and "sample" in err, err
