"""A model that passes the first check run and then fails at some theta: the error names the
model, the theta (each parameter with its unit) and the remedy, pickles (it is raised in worker
processes) and reaches the command line as one line with exit status 2."""

import pickle
import subprocess
import sys
import textwrap
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
from new_user_kit import TRUTH, Spring, make_dataset

from bayes_update import ModelError, Problem

BAD = {"fn": 33.4, "zeta": 0.0271, "k": 5.15}  # beyond fn = 31 Hz every model below fails


class NanAboveSpring(Spring):
    def simulate(self, theta, force, fs):
        y = super().simulate(theta, force, fs)
        return np.full_like(y, np.nan) if theta["fn"] > 31.0 else y


class ShortAboveSpring(Spring):
    def simulate(self, theta, force, fs):
        y = super().simulate(theta, force, fs)
        return y[:-1] if theta["fn"] > 31.0 else y


class BuggySpring(Spring):
    def simulate(self, theta, force, fs):
        if theta["fn"] > 31.0:
            return {"table": 1}["tabel"]  # a typo: a bug, not a region of the parameters
        return super().simulate(theta, force, fs)


class RefusingSpring(Spring):
    def simulate(self, theta, force, fs):
        if theta["fn"] > 31.0:
            raise ModelError("beyond the model's range of validity")
        return super().simulate(theta, force, fs)


@pytest.fixture(scope="module")
def data():
    return make_dataset()


def _check_message(text, kind, *what):
    assert kind in text, text
    # the theta, each parameter with its unit
    assert "fn = 33.4 Hz" in text and "zeta = 0.0271" in text and "k = 5.15 kN/m" in text, text
    for w in what:
        assert w in text, (w, text)
    assert "\n" not in text


@pytest.mark.parametrize(
    "cls, what",
    [
        (NanAboveSpring, ("NaN", "ModelError")),
        (ShortAboveSpring, ("(2047,)", "(2048,)")),
        (BuggySpring, ("KeyError", "tabel", "ModelError")),
    ],
)
def test_a_run_error_names_the_model_the_theta_and_the_remedy(data, cls, what):
    problem = Problem(data, cls())
    assert problem.evaluate(TRUTH)["error"] is None
    with pytest.raises(Exception) as info:
        problem.evaluate(BAD)
    exc = info.value
    assert isinstance(exc, ValueError) and not isinstance(exc, ModelError), type(exc)
    _check_message(str(exc), cls.__name__, *what)
    again = pickle.loads(pickle.dumps(exc))
    assert type(again) is type(exc) and str(again) == str(exc)
    # the validation tests go through the same check
    with pytest.raises(type(exc), match=cls.__name__):
        problem.prediction_errors(BAD)


def test_a_run_error_in_a_worker_process_reaches_the_caller_whole(data):
    problem = Problem(data, NanAboveSpring())
    with ProcessPoolExecutor(max_workers=1) as pool:
        with pytest.raises(ValueError) as info:
            pool.submit(problem.evaluate, BAD).result()
    _check_message(str(info.value), "NanAboveSpring", "NaN", "ModelError")


def test_model_error_still_means_this_point_cannot_run(data):
    problem = Problem(data, RefusingSpring())
    out = problem.evaluate(BAD)
    assert np.isnan(out["e_lin"]) and np.isnan(out["e_nlin"]) and "range of validity" in out["error"]
    assert np.isnan(problem.prediction_errors(BAD)["medium_check"])


MODEL_FILE = """
import numpy as np
from scipy import signal
from bayes_update import Parameter


class LateNaN:
    parameters = [Parameter("fn", 15.0, 35.0, unit="Hz"), Parameter("zeta", 0.005, 0.1, log=True),
                  Parameter("k", 2.0, 8.0, unit="kN/m")]

    def simulate(self, theta, force, fs):
        wn = 2 * np.pi * theta["fn"]
        k = 1e3 * theta["k"]
        b, a = signal.bilinear([1.0], [k / wn ** 2, 2 * theta["zeta"] * k / wn, k], fs)
        y = signal.lfilter(b, a, force)
        if theta["fn"] > 31.0:
            y[::2] = {how}
        return y
"""


@pytest.mark.parametrize("how, what", [("np.nan", "NaN"), ("1 / 0", "ZeroDivisionError")])
def test_cli_reports_a_run_error_in_one_line_with_status_2(tmp_path, data, how, what):
    from bayes_update.data.folder import write_dataset

    write_dataset(data, tmp_path / "data")
    (tmp_path / "late_nan.py").write_text(textwrap.dedent(MODEL_FILE.replace("{how}", how)))
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "bayes_update",
            "calibrate",
            "--quick",
            "--workers",
            "1",
            "--model",
            f"{tmp_path / 'late_nan.py'}:LateNaN",
            "--data",
            str(tmp_path / "data"),
            "--out",
            str(tmp_path / "out"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert res.returncode == 2, res.stderr[-3000:]
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("bayes-update calibrate: error:")]
    assert len(lines) == 1 and "Traceback" not in res.stderr, res.stderr[-3000:]
    assert "LateNaN" in lines[0] and "fn = " in lines[0] and " Hz" in lines[0] and what in lines[0], lines[0]
    assert "ModelError" in lines[0], lines[0]
    assert not (tmp_path / "out").exists()
