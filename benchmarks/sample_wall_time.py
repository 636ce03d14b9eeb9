"""Wall time of the beam's default ``sample`` on the full FE model, step by step.

    python benchmarks/sample_wall_time.py [--repeats 3] [--model fe]

One warm-up run (numba's JIT, imports), then ``--repeats`` runs of
``sample(load_default_dataset(), beam_model(data, "fe"), PosteriorSettings())``
on two workers, each from scratch (no evaluation cache): the median wall
time, each run's time per step (``PosteriorResult.timing``) and model runs.
Writes ``benchmarks/results/sample_wall_time_<model>.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from _machine import machine  # noqa: E402

from bayes_update.core.posterior import PosteriorSettings, sample  # noqa: E402
from bayes_update.models.beam.model import beam_model  # noqa: E402
from bayes_update.models.beam.virtual_rig import load_default_dataset  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--model", choices=("fe", "rom"), default="fe")
    args = ap.parse_args(argv)
    data = load_default_dataset()
    model = beam_model(data, args.model)
    quiet = dict(workers=2, progress=False, log=lambda *a: None)
    sample(data, model, PosteriorSettings(seed=0), **quiet)  # warm-up
    rows = []
    for i in range(args.repeats):
        t = time.perf_counter()
        res = sample(data, model, PosteriorSettings(seed=i), **quiet)
        rows.append((time.perf_counter() - t, res.timing, res.n_model_runs))
        print(
            f"run {i}: {rows[-1][0]:.1f} s, {res.n_model_runs['total']} runs; "
            + ", ".join(f"{k} {v:.1f}" for k, v in res.timing.items()),
            flush=True,
        )
    walls = [r[0] for r in rows]
    steps = [k for k in rows[0][1] if k != "total"]
    lines = [
        f"# Wall time of the default `sample`, beam, {args.model}",
        "",
        f"`python benchmarks/sample_wall_time.py --repeats {args.repeats} --model {args.model}`; {machine()}; "
        "after a warm-up run, seeds 0.., two workers, no evaluation cache.",
        "",
        f"**median {np.median(walls):.1f} s** (runs: {', '.join(f'{w:.1f}' for w in walls)} s)",
        "",
        "| run | wall [s] | model runs | " + " | ".join(steps) + " |",
        "|---|---|---|" + "---|" * len(steps),
    ]
    for i, (wall, timing, runs) in enumerate(rows):
        lines.append(
            f"| {i} | {wall:.1f} | {runs['total']} | " + " | ".join(f"{timing.get(k, 0.0):.1f}" for k in steps) + " |"
        )
    out = ROOT / "benchmarks" / "results" / f"sample_wall_time_{args.model}.md"
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
