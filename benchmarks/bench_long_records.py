"""Cost of one model run and one metric evaluation on long records (10^5 samples).

A user's measured tests are often long; the framework's cost per likelihood
evaluation is one model run plus the projection of its response on the
Volterra regressors, which are factored once per test.  Measured on the
Duffing test model (numba RK4, 4 steps per sample) at a non-round sampling
rate, and the beam's modal ROM and full FE on a chirp of the same length.
Median of 7 runs after warm-up, one core (BLAS limited to one thread).

    python benchmarks/bench_long_records.py [--samples N]
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(ROOT / "tests"))
from _machine import machine, median_time  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=100_000)
    n = parser.parse_args().samples

    from test_user_model import FS, TRUTH, Duffing

    import fe
    from bayes_update.core import Problem
    from bayes_update.data.dataset import Dataset, Record

    rng = np.random.default_rng(0)
    t = np.arange(n) / FS
    sweep = np.sin(2 * np.pi * (15 * t + 60 / (2 * t[-1]) * t**2))
    model = Duffing()
    tests = []
    for name, level, role in (("low", 0.05, "linear"), ("high", 1.0, "nonlinear")):
        f = level * sweep
        y = model.simulate(TRUTH, f, FS)
        tests.append(
            Record(
                f"{name}.csv",
                "chirp",
                name,
                role,
                t,
                f + 1e-2 * level * rng.standard_normal(n),
                y + 1e-2 * np.std(y) * rng.standard_normal(n),
            )
        )
    data = Dataset("long", FS, fe.Rig(), tests)
    rows = []
    with threadpool_limits(1):
        t0 = time.perf_counter()
        problem = Problem(data, model)
        rows.append(("Kautz basis from the linear test (pole search)", time.perf_counter() - t0))
        t0 = time.perf_counter()
        for st in problem.stages:
            problem.projector(st)
        rows.append(("regressors factored, both tests (once per data set)", time.perf_counter() - t0))
        force = tests[1].force
        rows.append(
            ("Duffing model run (numba RK4, 4 steps per sample)", median_time(lambda: model.simulate(TRUTH, force, FS)))
        )
        v = model.simulate(TRUTH, force, FS)
        rows.append(
            (
                "metric e_nlin of a given response (projection, orders 1-3)",
                median_time(lambda: problem.metric("nonlinear", v)),
            )
        )
        rows.append(("one evaluation: both tests, run + metrics", median_time(lambda: problem.evaluate(TRUTH))))
        chirp = 0.1 * np.sin(2 * np.pi * (20 * t + 30 / (2 * t[-1]) * t**2))
        rom = fe.ModalROM()
        rows.append(
            (
                "beam ROM run (3 modes), same length at 1187.5 Hz",
                median_time(lambda: rom.simulate(fe.PAPER_PARAMETERS, chirp, FS), repeats=5),
            )
        )
        beam = fe.BeamModel()
        rows.append(
            (
                "beam full FE run (10 elements, 4 substeps), same length",
                median_time(lambda: beam.simulate(fe.PAPER_PARAMETERS, chirp, FS), repeats=3),
            )
        )
    print(f"{n} samples at {FS} Hz; {machine()}")
    print("| step | time |\n|---|---|")
    for what, sec in rows:
        print(f"| {what} | {sec * 1e3:.1f} ms |" if sec < 10 else f"| {what} | {sec:.1f} s |")


if __name__ == "__main__":
    main()
