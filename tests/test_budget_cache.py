"""The run cache (bayes_update.core.runs): every model run of every step kept on disk by
(model, force, theta), so that an interrupted ``sample`` run again makes none of the runs
it finished, a finished one makes none at all, and ``sample`` after ``calibrate`` on the
same data and model starts from calibrate's runs.  Counted exactly: a model that logs
every run it finishes (its theta and force) to a file."""

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

from bayes_update.core.model import ModelError
from bayes_update.core.runs import RunStore, store_in


class LoggingModel:
    """The Duffing oscillator of test_user_model (fn, zeta, k3 free), logging each finished run
    to ``log`` (one line: a hash of theta and the force); raising KeyboardInterrupt, as Ctrl-C
    does, once ``log`` holds ``int(open(stop).read())`` lines, while the file ``stop`` exists
    (a file: the model's state, which keys its runs, stays the same across the calls)."""

    def __init__(self, log, stop, inner=None):
        from test_user_model import TRUTH, Duffing

        free = ("fn", "zeta", "k3")
        self.inner = inner or Duffing(free, fixed={k: v for k, v in TRUTH.items() if k not in free})
        self.parameters = self.inner.parameters
        self.log, self.stop = str(log), str(stop)

    def refined(self):
        return LoggingModel(self.log, self.stop, self.inner.refined())

    def simulate(self, theta, force, fs):
        if os.path.exists(self.stop) and _lines(self.log) >= int(Path(self.stop).read_text()):
            raise KeyboardInterrupt
        y = self.inner.simulate(theta, force, fs)
        key = hashlib.sha256(
            json.dumps(sorted((k, float(v).hex()) for k, v in theta.items())).encode()
            + np.asarray(force, float).tobytes()
        ).hexdigest()[:16]
        with open(self.log, "a") as f:
            f.write(f"{key} {type(self.inner).__name__} {self.inner.substeps}\n")
        return y


def _lines(path) -> int:
    return len(Path(path).read_text().splitlines()) if os.path.exists(path) else 0


def _runs(path) -> list:
    return Path(path).read_text().split("\n")[:-1] if os.path.exists(path) else []


SETTINGS = dict(n_steps=1000, burn=300, max_steps=4000, n_linear=0)


def _sample(data, model, cache):
    from bayes_update.core.posterior import PosteriorSettings, sample

    return sample(
        data, model, PosteriorSettings(**SETTINGS), workers=1, cache_dir=cache, progress=False, log=lambda *a: None
    )


@pytest.fixture(scope="module")
def data():
    from test_user_model import make_dataset

    return make_dataset(seed=11)


def test_an_interrupted_sample_run_again_makes_none_of_its_finished_runs(data, tmp_path):
    ref_log, log, stop = tmp_path / "ref.log", tmp_path / "runs.log", tmp_path / "stop"
    ref = _sample(data, LoggingModel(ref_log, stop), tmp_path / "ref_cache")
    made = _runs(ref_log)
    assert len(made) == len(set(made)), "an uninterrupted sample made a run twice"
    # interrupted halfway, as Ctrl-C would (the run in flight raises and is not kept)
    stop.write_text(str(len(made) // 2))
    with pytest.raises(KeyboardInterrupt):
        _sample(data, LoggingModel(log, stop), tmp_path / "cache")
    first = _runs(log)
    assert len(first) == len(made) // 2
    stop.unlink()
    again = _sample(data, LoggingModel(log, stop), tmp_path / "cache")
    second = _runs(log)[len(first) :]
    # every run finished before the interruption is read, none made again; together they are the
    # uninterrupted command's runs, each made once
    assert not set(first) & set(second)
    assert sorted(first + second) == sorted(made)
    assert again.summary == ref.summary
    assert sum(again.n_model_runs_reused.values()) >= len(first)
    # and a finished command run again makes no run at all
    third = _sample(data, LoggingModel(log, stop), tmp_path / "cache")
    assert _runs(log)[len(first) + len(second) :] == []
    assert third.summary == ref.summary


def test_sample_after_calibrate_starts_from_calibrates_runs(data, tmp_path):
    from bayes_update.core.calibrate import calibrate_model

    log, stop = tmp_path / "runs.log", tmp_path / "stop"
    cal = calibrate_model(
        data,
        LoggingModel(log, stop),
        n_start=16,
        n_best=1,
        workers=1,
        progress=False,
        log=lambda *a: None,
        cache_dir=tmp_path / "cache",
    )
    by_calibrate = set(_runs(log))
    res = _sample(data, LoggingModel(log, stop), tmp_path / "cache")
    by_sample = _runs(log)[len(by_calibrate) :]
    assert not set(by_sample) & by_calibrate  # none of calibrate's runs made again
    assert res.n_model_runs["start"] == 0  # its start is calibrate's best point
    assert res.start == pytest.approx(cal.theta, rel=1e-12)
    assert res.n_model_runs_reused.get("check_and_screen", 0) >= 1  # the screen's runs were found


def test_the_store_keys_runs_by_model_force_and_theta(tmp_path):
    """A run is found again only for the same model state, force (to the bit) and theta (to the
    bit); a ModelError is kept and raised again; the journal counts what was written."""
    from test_user_model import Duffing

    store = RunStore(tmp_path, "sample")
    model, other = Duffing(("fn", "zeta"), fixed={"k3": 4.2}), Duffing(("fn", "zeta"), fixed={"k3": 4.2}, substeps=8)
    theta = {"fn": 41.3, "zeta": 0.021}
    force = np.sin(np.arange(64) / 3.0)
    y = model.simulate(theta, force, 1024.0)
    store.put(model, force, 1024.0, theta, response=y)
    np.testing.assert_array_equal(store.get(model, force, 1024.0, theta), y)
    assert store.get(other, force, 1024.0, theta) is None
    assert store.get(model, force, 2048.0, theta) is None
    f2 = force.copy()
    f2[5] = np.nextafter(f2[5], 2.0)
    assert store.get(model, f2, 1024.0, theta) is None
    assert store.get(model, force, 1024.0, {"fn": np.nextafter(41.3, 50.0), "zeta": 0.021}) is None
    store.put(model, force, 1024.0, {"fn": 30.0, "zeta": 0.021}, error="diverges")
    err = store.get(model, force, 1024.0, {"fn": 30.0, "zeta": 0.021})
    assert isinstance(err, ModelError) and "diverges" in str(err)
    assert store.made() == 2
    # points(): thetas run on every force given, without another command's exclusion
    store.put(model, f2, 1024.0, theta, response=y)
    assert [t for t, _ in store.points(model, [force, f2], 1024.0)] == [theta]
    assert store.points(model, [force, f2], 1024.0, exclude_source="sample") == []
    assert store_in(tmp_path, "x").root == tmp_path / "runs"


def test_a_direct_chain_keeps_no_run(data, tmp_path):
    """sample --direct: the chain's runs (10^4 and more of a cheap model) are not written to
    the cache; the steps before it are."""
    from bayes_update.core.posterior import PosteriorSettings, sample

    settings = PosteriorSettings(
        direct_walkers=8, direct_steps=40, direct_burn=10, direct_max_steps=40, n_linear=0, n_global=0, n_predictive=0
    )
    res = sample(
        data,
        LoggingModel(tmp_path / "runs.log", tmp_path / "stop"),
        settings,
        workers=1,
        direct=True,
        cache_dir=tmp_path / "cache",
        progress=False,
        log=lambda *a: None,
    )
    made = RunStore(tmp_path / "cache" / "runs").made()
    assert res.n_model_runs["mcmc"] >= 2 * 8 * 40
    assert 0 < made <= res.n_model_runs["total"] - res.n_model_runs["mcmc"]


def test_calibrate_run_again_makes_no_run(data, tmp_path):
    """A finished calibrate run again on the same cache reads every run (none made) and ends at
    the same point; interrupted halfway, its rerun makes only the runs it had not finished."""
    from bayes_update.core.calibrate import calibrate_model

    log, stop = tmp_path / "runs.log", tmp_path / "stop"

    def calibrate():
        return calibrate_model(
            data,
            LoggingModel(log, stop),
            n_start=16,
            n_best=1,
            workers=1,
            progress=False,
            log=lambda *a: None,
            cache_dir=tmp_path / "cache",
        )

    first = calibrate()
    made = _runs(log)
    again = calibrate()
    assert _runs(log) == made
    assert again.theta == first.theta
    # interrupted halfway on a fresh cache, then run again
    log2, cache2 = tmp_path / "runs2.log", tmp_path / "cache2"
    stop.write_text(str(len(made) // 2))
    with pytest.raises(KeyboardInterrupt):
        calibrate_model(
            data,
            LoggingModel(log2, stop),
            n_start=16,
            n_best=1,
            workers=1,
            progress=False,
            log=lambda *a: None,
            cache_dir=cache2,
        )
    before = _runs(log2)
    stop.unlink()
    resumed = calibrate_model(
        data,
        LoggingModel(log2, stop),
        n_start=16,
        n_best=1,
        workers=1,
        progress=False,
        log=lambda *a: None,
        cache_dir=cache2,
    )
    after = _runs(log2)[len(before) :]
    assert not set(before) & set(after)
    assert sorted(before + after) == sorted(made)
    assert resumed.theta == first.theta


def test_the_cache_command_shows_and_clears_the_kept_runs(tmp_path, capsys):
    """``bayes-update cache`` counts the runs it keeps (against what was put), ``--clear
    --older-than`` deletes only the old ones, ``--clear`` the rest, and a run cleared is
    not found again."""
    from test_user_model import Duffing

    from bayes_update.cli import main
    from bayes_update.core.runs import runs_usage

    store = store_in(tmp_path, "sample")
    model = Duffing(("fn", "zeta"), fixed={"k3": 4.2})
    force = np.sin(np.arange(64) / 3.0)
    thetas = [{"fn": 40.0 + i, "zeta": 0.02} for i in range(3)]
    for theta in thetas:
        store.put(model, force, 1024.0, theta, response=model.simulate(theta, force, 1024.0))
    store.put(model, force, 1024.0, {"fn": 30.0, "zeta": 0.02}, error="diverges")
    old = next(store.root.glob("*/*/*.npz"))
    os.utime(old, (old.stat().st_atime - 3 * 86400, old.stat().st_mtime - 3 * 86400))
    usage = runs_usage(tmp_path)
    assert usage["runs"] == 4 and usage["models"] == 1 and usage["oldest_days"] > 2.9, usage
    assert main(["cache", "--cache", str(tmp_path)]) == 0
    assert "4 runs of 1 model(s)" in capsys.readouterr().out
    assert main(["cache", "--cache", str(tmp_path), "--clear", "--older-than", "1"]) == 0
    assert "deleted 1 runs" in capsys.readouterr().out and runs_usage(tmp_path)["runs"] == 3
    assert main(["cache", "--cache", str(tmp_path), "--clear"]) == 0
    assert runs_usage(tmp_path)["runs"] == 0 and not list(store.root.glob("*"))
    assert all(store.get(model, force, 1024.0, theta) is None for theta in thetas)
    assert main(["cache", "--cache", str(tmp_path), "--older-than", "1"]) == 2  # without --clear: an error
