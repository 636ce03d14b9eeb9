"""Time to error: how long a user waits for each kind of user error, from the
command's start to its one-line message (issues 40 and 43: every such error
within 5 s of the start).

Each case runs in a fresh process, as a user meets it: the command line
(``python -m bayes_update ...``, interpreter start, imports and reading the
data included) or a script calling the Python API (``import bayes_update``
included).  Two data sets: the Duffing oscillator of docs/models.md on two
chirps of 4096 samples (one sensor), and the laboratory-like records of
docs/measured_records.md (three tests of 5096 samples, three accelerometers)
with the chain model of tests/test_measured_records.py; the model and data
variants below each carry one fault.

    python benchmarks/fail_fast.py [--code DIR] [--only NAME ...] [--timeout S]

``--code DIR``: the source tree to time (default: this one; e.g. an export of
an older commit for the "before" column).  Writes
``benchmarks/results/fail_fast.json`` (``--out``) and prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path[:0] = [str(HERE), str(REPO / "tests")]

from _machine import machine  # noqa: E402

#: the model variants, one fault each (appended to the Duffing of docs/models.md)
DUFFING_VARIANTS = '''

class Short(Duffing):
    def simulate(self, theta, force, fs):
        return super().simulate(theta, force, fs)[:-1]


class NaNs(Duffing):
    def simulate(self, theta, force, fs):
        y = super().simulate(theta, force, fs)
        y[100] = np.nan
        return y


class Complex(Duffing):
    def simulate(self, theta, force, fs):
        return super().simulate(theta, force, fs) * (1 + 0.5j)


class RefinedNone(Duffing):
    refined = None


class Misspelt:
    """The Duffing with its refined() misspelt."""

    parameters = Duffing.parameters
    simulate = Duffing.simulate

    def __init__(self, substeps=4):
        self.substeps = substeps

    def refine(self):
        return Misspelt(4 * self.substeps)


class EffectsNotCallable(Duffing):
    candidate_effects = {"k2": [Parameter("k2", -1.0, 1.0, null=0.0)]}


class BadParameters(Duffing):
    parameters = [("fn", 30.0, 50.0), ("zeta", 0.005, 0.08)]
'''

LAB_VARIANTS = """
import sys
sys.path.insert(0, {tests!r})
import numpy as np
from test_measured_records import LabChain


class LabShort(LabChain):
    def simulate(self, theta, force, fs):
        return super().simulate(theta, force, fs)[:-1]


class LabRefinedNone(LabChain):
    refined = None
"""


def _write_inputs(tmp: Path) -> None:
    """The data sets and model files of the cases, in ``tmp``."""
    import test_measured_records as acceptance
    from test_user_model import make_dataset

    from bayes_update.data.folder import read_dataset, write_dataset

    doc = (REPO / "docs" / "models.md").read_text()
    duffing = re.findall(r"```python\n(.*?)```", doc, flags=re.S)[0]
    (tmp / "duffing_models.py").write_text(duffing + DUFFING_VARIANTS)
    (tmp / "lab_models.py").write_text(LAB_VARIANTS.format(tests=str(REPO / "tests")))
    write_dataset(make_dataset(seed=31), tmp / "duffing")
    acceptance.read_back(acceptance.lab_tests(), tmp / "lab")
    for name in ("duffing", "lab"):
        # the same records, the validation (or a copy of the high) test marked nonlinear too
        meta = json.loads((tmp / name / "dataset.json").read_text())
        two = tmp / f"{name}_two_nonlinear"
        two.mkdir()
        for f in (tmp / name).iterdir():
            (two / f.name).write_bytes(f.read_bytes())
        extra = [t for t in meta["tests"] if t["role"] == "validation"]
        if extra:
            extra[0]["role"] = "nonlinear"
        else:
            high = next(t for t in meta["tests"] if t["role"] == "nonlinear")
            (two / "copy_high.csv").write_bytes((tmp / name / high["file"]).read_bytes())
            meta["tests"].append({**high, "file": "copy_high.csv"})
        (two / "dataset.json").write_text(json.dumps(meta, indent=2))
        read_dataset(two)  # a valid folder: only its roles are wrong
    (tmp / "unknown_key.toml").write_text("[calibrate]\nn_starts = 8\n")


def _cases():
    """(name, command line) of each case; the model files and data sets are in the working folder."""
    d = "duffing_models.py"
    lab = "lab_models.py"
    return [
        ("short sample, duffing", f"calibrate --model {d}:Short --data duffing"),
        ("short sample, lab", f"calibrate --model {lab}:LabShort --data lab"),
        ("short sample, lab, sample", f"sample --quick --model {lab}:LabShort --data lab"),
        ("NaN in the response, duffing", f"sample --quick --model {d}:NaNs --data duffing"),
        ("complex response, duffing", f"calibrate --model {d}:Complex --data duffing"),
        ("parameters not Parameter, duffing", f"calibrate --model {d}:BadParameters --data duffing"),
        ("two tests nonlinear, duffing", f"calibrate --model {d}:Duffing --data duffing_two_nonlinear"),
        ("two tests nonlinear, lab", f"sample --quick --model {lab}:LabChain --data lab_two_nonlinear"),
        (
            "unreachable scheduler, duffing",
            f"calibrate --model {d}:Duffing --data duffing --scheduler tcp://127.0.0.1:9",
        ),
        (
            "unreachable scheduler, lab",
            f"sample --quick --model {lab}:LabChain --data lab --scheduler tcp://127.0.0.1:9",
        ),
        ("refined = None, duffing", f"sample --quick --model {d}:RefinedNone --data duffing"),
        ("refined = None, lab", f"sample --quick --model {lab}:LabRefinedNone --data lab"),
        ("misspelt hook (refine), duffing", f"sample --quick --model {d}:Misspelt --data duffing"),
        (
            "candidate_effects not callable, duffing",
            f"discrepancy --quick --model {d}:EffectsNotCallable --data duffing",
        ),
        ("unknown [calibrate] key, duffing", f"calibrate --model {d}:Duffing --data duffing --config unknown_key.toml"),
    ]


API = """
import json, sys
import bayes_update as bu
from bayes_update.core.model import load_model
verb, spec, data = sys.argv[1:4]
try:
    fn = {"calibrate": bu.calibrate, "sample": bu.sample, "discrepancy": bu.find_discrepancy}[verb]
    fn(bu.read_dataset(data), load_model(spec), workers=1, progress=False)
    print(json.dumps({"error": None}))
except Exception as exc:
    print(json.dumps({"error": f"{type(exc).__name__}: {exc}"}))
"""

API_CASES = [
    ("API: short sample, lab", "calibrate", "lab_models.py:LabShort", "lab"),
    ("API: two tests nonlinear, lab", "sample", "lab_models.py:LabChain", "lab_two_nonlinear"),
    ("API: refined = None, lab", "sample", "lab_models.py:LabRefinedNone", "lab"),
    ("API: misspelt hook (refine), duffing", "sample", "duffing_models.py:Misspelt", "duffing"),
]


def _run(argv, cwd, env, timeout):
    t0 = time.perf_counter()
    try:
        res = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {
            "seconds": None,
            "status": None,
            "message": f"no error within {timeout:.0f} s (stopped)",
            "traceback": False,
        }
    seconds = time.perf_counter() - t0
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    err = [ln for ln in lines if ": error: " in ln]
    message = err[-1] if err else (lines[-1] if lines else "")
    if res.returncode == 0:
        message = "completed without an error"
    return {
        "seconds": seconds,
        "status": res.returncode,
        "message": message[:300],
        "traceback": "Traceback" in res.stderr,
    }


def _run_api(argv, cwd, env, timeout):
    """A script's wall time (process start to its exception) and the exception."""
    t0 = time.perf_counter()
    try:
        res = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"seconds": None, "message": f"no error within {timeout:.0f} s (stopped)"}
    seconds = time.perf_counter() - t0
    try:
        got = json.loads(res.stdout.strip().splitlines()[-1])
    except (ValueError, IndexError):
        return {"seconds": seconds, "message": "the script failed: " + res.stderr[-300:]}
    return {"seconds": seconds, "message": (got["error"] or "completed without an error")[:300]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--code", type=Path, default=REPO, help="the source tree to time (default: this one)")
    ap.add_argument("--only", nargs="*", default=None, help="cases whose name contains one of these words")
    ap.add_argument("--timeout", type=float, default=150.0, help="stop a case after this many seconds")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "fail_fast.json")
    args = ap.parse_args()
    code = args.code.resolve()
    env = {**os.environ, "PYTHONPATH": str(code)}
    rows = []
    load = [os.getloadavg()[0]]  # the machine is shared: its load, at the start and the end
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        _write_inputs(tmp)
        cases = _cases()

        def wanted(name):
            return args.only is None or any(w in name for w in args.only)

        for i, (name, command) in enumerate(cases):
            if not wanted(name):
                continue
            # an OUT of its own: sample keeps its model runs in OUT/cache, which another case would reuse
            argv = [sys.executable, "-m", "bayes_update"] + command.split() + ["--out", f"out{i}"]
            row = {"case": name, "how": "bayes-update " + command, **_run(argv, tmp, env, args.timeout)}
            rows.append(row)
            print(
                f"{name:42s} {row['seconds'] or float('nan'):6.1f} s  status {row['status']}  {row['message']}",
                flush=True,
            )
        for name, verb, spec, data in API_CASES:
            if not wanted(name):
                continue
            res = _run_api([sys.executable, "-c", API, verb, spec, data], tmp, env, args.timeout)
            rows.append(
                {"case": name, "how": f"bu.{verb if verb != 'discrepancy' else 'find_discrepancy'}(data, model)", **res}
            )
            print(f"{name:42s} {res['seconds'] or float('nan'):6.1f} s  {res['message']}", flush=True)
    load.append(os.getloadavg()[0])
    doc = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "code": str(code),
        "load_average_1min": load,
        "cases": rows,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(doc, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
