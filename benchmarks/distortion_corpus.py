"""volterra.record_distortion over the front end's randomized corpus (benchmarks/front_end_draws.py).

Every test of records 0..300 (structures of seven classes, excitations, sensors, noise, offsets
and drifts drawn from the seed; none built for this analysis) goes through
``volterra.record_distortion``: a periodic test's unexcited lines (``volterra.distortion``), a
sine sweep's harmonics (``volterra.sweep_distortion``), nothing for another record.  No exception
is allowed, and a linear structure's test should read at
the noise on every sensor (a detection there is a false alarm), a nonlinear one's high level
should not.

    python benchmarks/distortion_corpus.py [--n 301]

writes ``benchmarks/results/distortion_corpus.{json,md}``.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import sys
import time
import traceback
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent)]  # this checkout's packages, not an installed copy

from _machine import machine  # noqa: E402
from front_end_draws import draw  # noqa: E402

from volterra.distortion import Distortion  # noqa: E402
from volterra.sweep_distortion import record_distortion  # noqa: E402

#: the corpus's classes whose structure is nonlinear (the others are linear: a detection is false)
NONLINEAR = ("sdof_ode", "nonlinear")


def rows_of(seed: int) -> list:
    data, truth, _ = draw(seed)
    out = []
    for t in data.tests:
        row = {"seed": seed, "class": truth.details["class"], "test": t.name, "level": t.level, "signal": t.signal}
        try:
            names = [n for n, _ in t.sensors]
            d = record_distortion(t.force, t.response, data.sampling_rate_hz, t.period_samples, sensors=names)
            if d is None:
                if t.signal in ("sweep", "chirp"):  # a sweep the reader turned down: counted
                    row["not_read"] = "not a sweep by the reader's tests (frames of one sine, f0 moving smoothly)"
                    out.append(row)
                continue
            row.update(
                kind="periodic" if isinstance(d, Distortion) else "sweep",
                classes=d.classes,
                detected={s: [c for c, r in cl.items() if r["detected"]] for s, cl in d.sensors.items()},
                force_detected=[c for c, r in d.force.items() if r["detected"]],
                noise_ratio={s: {c: r["noise_ratio"] for c, r in cl.items()} for s, cl in d.sensors.items()},
            )
        except ValueError as exc:  # a documented refusal
            row["refused"] = str(exc)
        except Exception as exc:  # a crash: a bug to report
            row["crash"] = f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"
        out.append(row)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=301)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    rows = [r for seed in range(args.n) for r in rows_of(seed)]
    wall = time.perf_counter() - t0
    table = collections.defaultdict(lambda: {"tests": 0, "sensor_detected": 0, "force_detected": 0})
    for r in rows:
        if "detected" not in r:
            continue
        cell = table[(r["kind"], r["class"], r["level"])]
        cell["tests"] += 1
        cell["sensor_detected"] += any(r["detected"].values())
        cell["force_detected"] += bool(r["force_detected"])
    crashes = [r for r in rows if "crash" in r]
    refused = [r for r in rows if "refused" in r]
    false = [r for r in rows if "detected" in r and r["class"] not in NONLINEAR and any(r["detected"].values())]
    linear = [r for r in rows if "detected" in r and r["class"] not in NONLINEAR]
    kinds = collections.Counter(r.get("kind", "not read" if "not_read" in r else "refused or crashed") for r in rows)
    false_kinds = collections.Counter(r["kind"] for r in false)
    linear_kinds = collections.Counter(r["kind"] for r in linear)
    lines = [
        "# Odd and even distortion over the randomized corpus",
        "",
        f"`python benchmarks/distortion_corpus.py --n {args.n}`; {machine()}; {wall:.0f} s",
        "",
        f"{len(rows)} tests read of {args.n} records ({dict(kinds)}): {len(crashes)} exceptions, "
        f"{len(refused)} refused (a documented ValueError); linear structures: {len(false)} of {len(linear)} "
        f"tests with a detection on some sensor (false alarms; periodic {false_kinds['periodic']} of "
        f"{linear_kinds['periodic']}, sweeps {false_kinds['sweep']} of {linear_kinds['sweep']}).",
        "",
        "| read as | class | level | tests | a sensor detected | the force detected |",
        "|---|---|---|---|---|---|",
        *(
            f"| {k} | {c} | {lv} | {v['tests']} | {v['sensor_detected']} | {v['force_detected']} |"
            for (k, c, lv), v in sorted(table.items())
        ),
    ]
    out = HERE / "results" / "distortion_corpus"
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1, default=str))
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
