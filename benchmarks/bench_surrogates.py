"""Benchmark of the surrogates package on the synthetic curved valley (not a test).

For each dimension and seed, the same total number of runs N is spent on
* a one-shot scrambled Sobol' design of N points;
* refinement from a Sobol' design of N/4 points in rounds of ``--batch``,
  with the criterion ``weight**power * sd`` for power 1, 0.5 and 0.25
  (tempered weights explore more of the posterior's tails), and ``sd`` alone
  (weight 1: uncertainty sampling, space filling in the GP's metric);
and the surrogate's error is measured where the posterior has its mass: the
median (and 90th percentile) relative error of the predicted metric at 500
exact posterior draws, and the coverage of the 95 % band there.

Usage:
    python benchmarks/bench_surrogates.py [--dims 2 3] [--seeds 10] [--n 128] [--batch 16]

BLAS is limited to one thread (small matrices on a small shared machine).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(var, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from _machine import machine  # noqa: E402

from surrogates import CurvedValley, GPSurrogate, design, refine  # noqa: E402


def errors(sur, T, yT):
    rel = np.abs(sur.predict(T, return_std=False) - yT) / yT
    lo, hi = sur.predict_interval(T)
    return np.median(rel), np.percentile(rel, 90), np.mean((yT >= lo) & (yT <= hi))


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--dims", type=int, nargs="+", default=[2, 3])
    p.add_argument("--seeds", type=int, default=10)
    p.add_argument("--n", type=int, default=128)
    p.add_argument("--batch", type=int, default=16)
    a = p.parse_args()
    print(f"# surrogates on the curved valley (width 1/50 of the box); {machine()}")
    print(f"# N = {a.n} runs in all; refinement starts from {a.n // 4} Sobol' points, batches of {a.batch}")
    print("# columns: median / 90th percentile relative error at 500 posterior draws, 95 % band coverage")
    for d in a.dims:
        prob = CurvedValley(d=d)
        T = prob.sample_posterior(500, seed=12345)
        yT = prob.values(T)

        def factory():
            return GPSurrogate(prob.bounds, n_restarts_optimizer=2, seed=0)

        def posterior(s):  # log density exp(-(e/floor - 1)/2) on the surrogate
            return lambda X: -0.5 * (s.predict(X, return_std=False) / prob.floor - 1)

        variants = {
            "weight*sd": dict(power=1.0, weight=posterior),
            "weight^0.5*sd": dict(power=0.5, weight=posterior),
            "weight^0.25*sd": dict(power=0.25, weight=posterior),
            "sd only": dict(power=1.0, weight=lambda s: lambda X: np.zeros(len(X))),
        }
        table = {k: [] for k in ["one-shot Sobol", *variants]}
        t0 = time.perf_counter()
        for seed in range(a.seeds):
            X = design(prob.bounds, a.n, seed=seed)
            table["one-shot Sobol"].append(errors(factory().fit(X, prob.values(X)), T, yT))
            X0 = design(prob.bounds, a.n // 4, seed=seed)
            for name, v in variants.items():
                res = refine(
                    prob,
                    factory,
                    X0,
                    prob.values(X0),
                    v["weight"],
                    (a.n - a.n // 4) // a.batch,
                    a.batch,
                    None,
                    seed=seed,
                    log_weight=True,
                    power=v["power"],
                    progress=False,
                )
                table[name].append(errors(res.surrogate, T, yT))
        print(f"\n## d = {d} ({a.seeds} seeds, {time.perf_counter() - t0:.0f} s)")
        print(
            f"{'design':<16} {'median rel err (seed min / median / max)':>42} {'p90 (median)':>13} "
            f"{'coverage (median)':>18}"
        )
        for name, rows in table.items():
            r = np.array(rows)
            print(
                f"{name:<16} {r[:, 0].min():>12.3g} {np.median(r[:, 0]):>12.3g} {r[:, 0].max():>12.3g}   "
                f"{np.median(r[:, 1]):>13.3g} {np.median(r[:, 2]):>18.3g}"
            )
        one = np.array(table["one-shot Sobol"])[:, 0]
        for name in variants:
            f = one / np.array(table[name])[:, 0]
            print(
                f"improvement factor, one-shot / {name} (median rel. error, same seed): "
                f"min {f.min():.2f}, median {np.median(f):.2f}, max {f.max():.2f}"
            )


if __name__ == "__main__":
    main()
