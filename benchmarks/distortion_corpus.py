"""volterra.distortion over the front end's randomized corpus (benchmarks/front_end_draws.py).

Every periodic test of records 0..300 (structures of seven classes, excitations, sensors, noise,
offsets and drifts drawn from the seed; none built for this analysis) goes through
``volterra.distortion``: no exception is allowed, and a linear structure's test should read at
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

from volterra.distortion import distortion  # noqa: E402
from volterra.periods import PeriodLayout, find_periods  # noqa: E402

#: the corpus's classes whose structure is nonlinear (the others are linear: a detection is false)
NONLINEAR = ("sdof_ode", "nonlinear")


def rows_of(seed: int) -> list:
    data, truth, _ = draw(seed)
    out = []
    for t in data.tests:
        layout = find_periods(t.force, t.period_samples)
        if not isinstance(layout, PeriodLayout):
            continue
        row = {"seed": seed, "class": truth.details["class"], "test": t.name, "level": t.level}
        try:
            d = distortion(t.force, t.response, data.sampling_rate_hz, layout, sensors=[n for n, _ in t.sensors])
            row.update(
                classes=d.classes,
                periods=d.periods,
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
        cell = table[(r["class"], r["level"])]
        cell["tests"] += 1
        cell["sensor_detected"] += any(r["detected"].values())
        cell["force_detected"] += bool(r["force_detected"])
    crashes = [r for r in rows if "crash" in r]
    refused = [r for r in rows if "refused" in r]
    false = [r for r in rows if "detected" in r and r["class"] not in NONLINEAR and any(r["detected"].values())]
    linear = [r for r in rows if "detected" in r and r["class"] not in NONLINEAR]
    lines = [
        "# Odd and even distortion over the randomized corpus",
        "",
        f"`python benchmarks/distortion_corpus.py --n {args.n}`; {machine()}; {wall:.0f} s",
        "",
        f"{len(rows)} periodic tests of {args.n} records: {len(crashes)} exceptions, {len(refused)} refused "
        f"(a documented ValueError); linear structures: {len(false)} of {len(linear)} tests with a detection "
        "on some sensor (false alarms).",
        "",
        "| class | level | tests | a sensor detected | the force detected |",
        "|---|---|---|---|---|",
        *(
            f"| {c} | {lv} | {v['tests']} | {v['sensor_detected']} | {v['force_detected']} |"
            for (c, lv), v in sorted(table.items())
        ),
    ]
    out = HERE / "results" / "distortion_corpus"
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1, default=str))
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
