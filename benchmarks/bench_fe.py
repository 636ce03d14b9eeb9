"""Cost of one FE run: the high-level chirp (4096 samples, paper's parameters).

Median of several runs after JIT warm-up, one core.  Also: the cost against
the number of elements (banded solves: it should grow about linearly) and the
first-call time in a fresh process (numba compile, or load from its cache).

    python benchmarks/bench_fe.py
"""

import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine  # noqa: E402

import fe  # noqa: E402
from bayes_update.data.signals import chirp  # noqa: E402

PARAMS = fe.PAPER_PARAMETERS
FORCE = chirp(0.1)


def median_time(model, repeats=7):
    model.simulate(PARAMS, FORCE)  # warm-up (JIT)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        res = model.simulate(PARAMS, FORCE)
        times.append(time.perf_counter() - t0)
    steps = (FORCE.size - 1) * model.substeps
    return float(np.median(times)), res.newton_iterations / steps


def first_call_seconds():
    code = (
        "import time; t0 = time.perf_counter(); import fe; from bayes_update.data.signals import chirp; "
        "fe.BeamModel().simulate(fe.PAPER_PARAMETERS, chirp(0.1)); print(time.perf_counter() - t0)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip())


def main():
    print(f"machine: {machine()}\n")
    default = fe.BeamModel()
    t, it = median_time(default)
    print(
        f"default model ({default.n_elements} elements, {default.substeps} substeps, "
        f"rho_inf {default.rho_inf}): median {1e3 * t:.1f} ms per 4096-sample run, "
        f"{it:.2f} Newton iterations per step\n"
    )
    print("| elements | substeps | ms per run | us per step | Newton it./step |")
    print("|---|---|---|---|---|")
    for n in (10, 20, 40, 80, 160):
        model = fe.BeamModel(n_elements=n)
        t, it = median_time(model, repeats=3 if n >= 80 else 5)
        steps = (FORCE.size - 1) * model.substeps
        print(f"| {n} | {model.substeps} | {1e3 * t:.1f} | {1e6 * t / steps:.2f} | {it:.2f} |")
    print()
    print(
        f"first call in a fresh process (import + compile or cache load + one run): "
        f"{first_call_seconds():.2f} s (numba cache warm)"
    )


if __name__ == "__main__":
    main()
