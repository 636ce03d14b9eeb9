"""Ctrl-C in a long command: one line, exit status 130, OUT untouched, and the same
command resumes from the run cache (bayes_update.core.runs: every model run kept as it
ends) to the same posterior.

One uninterrupted ``sample`` (the reference), one interrupted as a terminal's
Ctrl-C does (SIGINT to the whole process group, the worker processes
included), and its rerun; ROM with small settings (about 25 s per run).  The
rerun finds every run the interrupted one finished in the cache, so its byte-identical
posterior_summary.json is also the check that the same seed gives the same bytes (and
that a run read back is the run made).  Each command its own cache folder (--cache).
"""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

SAMPLE = [sys.executable, "-m", "bayes_update", "sample", "--quick", "--model", "rom", "--workers", "2"]
#: shorter chains and no extras (28 s a run instead of 41): the interruption falls in the design either way
SMALL = "[sample]\nn_steps = 1000\nburn = 300\nn_linear = 0\nn_global = 0\nn_predictive = 0\nn_replicates = 8\n"
# -m slow: three sample runs (170 s of the suite on a slow day, the 15-minute budget)
pytestmark = [
    pytest.mark.skipif(os.name == "nt", reason="process groups and SIGINT are POSIX"),
    pytest.mark.slow,
    pytest.mark.headline,
]


def _command(out):
    config = out.parent / f"{out.name}.toml"
    config.write_text(SMALL)
    return SAMPLE + ["--config", str(config), "--out", str(out), "--cache", str(_cache(out))]


def _cache(out):
    return out.parent / f"{out.name}_cache"


def _made(out) -> int:
    """Runs the command has kept so far (the run cache's journal: a byte a run)."""
    journal = _cache(out) / "runs" / "made.log"
    return journal.stat().st_size if journal.exists() else 0


def _sample(out, **kw):
    return subprocess.run(_command(out), capture_output=True, text=True, timeout=900, **kw)


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    out = tmp_path_factory.mktemp("reference")
    res = _sample(out)
    assert res.returncode == 0, res.stderr[-3000:]
    return out


def test_interrupted_sample_resumes_to_the_same_posterior(tmp_path, reference):
    out = tmp_path / "out"
    # Ctrl-C's SIGINT as a terminal delivers it: a pytest-xdist worker ignores SIGINT, and a child
    # inherits that (Python then installs no KeyboardInterrupt handler: the command ran to its end)
    proc = subprocess.Popen(
        _command(out),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    deadline = time.monotonic() + 600
    # interrupt halfway through the surrogate design: the reference kept _made(reference) runs, the last
    # of them its design's and those of the steps after it
    steps = json.loads((reference / "run.json").read_text())["n_model_runs"]
    design = steps["design_and_gp"]
    after = sum(
        v
        for k, v in steps.items()
        if k not in ("total", "design_and_gp", "check_and_screen", "start", "likelihood_scales", "map_laplace")
    )
    before = _made(reference) - design - after + design // 2
    assert design >= 16 and before > design // 2, steps
    while _made(out) < before:
        assert proc.poll() is None, f"sample ended before it could be interrupted: {proc.communicate()}"
        assert time.monotonic() < deadline, "the design's runs never appeared"
        time.sleep(0.05)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err[-3000:]
    assert "Traceback" not in err, err[-3000:]
    last = err.strip().splitlines()[-1]
    assert last.startswith("bayes-update sample: interrupted;") and "rerun the same command to resume" in last
    # nothing in OUT: no half-written results, no staging folder
    assert not out.exists() or not list(out.iterdir())
    assert _made(out) >= before

    res = _sample(out)
    assert res.returncode == 0, res.stderr[-3000:]
    same = (reference / "posterior_summary.json").read_bytes() == (out / "posterior_summary.json").read_bytes()
    assert same, "the resumed run's posterior differs from the uninterrupted run's (same seed)"
    # every run the interrupted command kept is found again (per step, run.json; tests/test_budget_cache.py
    # checks run by run that none is made twice)
    reused = json.loads((out / "run.json").read_text())["n_model_runs_reused"]
    assert reused.get("design_and_gp", 0) > 0, reused
    assert sum(reused.values()) >= before, reused
    assert not json.loads((reference / "run.json").read_text())["n_model_runs_reused"].get("design_and_gp")
