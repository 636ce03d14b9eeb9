"""Walkers and steps of the chain on the surrogates: many walkers, few steps.

    python benchmarks/chain_geometry.py [--cases beam_rom duffing3] [--seeds 3]

The chain on the GP surrogates costs per emcee step (a step's walkers are one
vectorised call of the surrogate posterior), not per walker.  Per case: the
default ``sample`` once (its surrogate posterior kept), then emcee on that same
surrogate posterior with several (walkers, steps, burn, thin) geometries and
seeds, each against a long chain (256 x 20000, 2000 burnt, every 10th step)
on it: the worst mean shift in the long chain's sd, the worst log ratio of
sds, the worst Kolmogorov-Smirnov distance of 3000 draws against 3000 (its
own Monte Carlo floor is about 0.02-0.03), emcee's integrated autocorrelation
time and the wall time.  No model run: only the sampling of the surrogate is
compared.  Writes ``benchmarks/results/chain_geometry.md``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import arviz as az
import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bayes_update.core.posterior import PosteriorSettings, sample  # noqa: E402
from bayes_update.core.posterior.mcmc import initial_walkers, run_emcee  # noqa: E402

GEOMETRIES = [(64, 6000, 1000, 5), (128, 3000, 500, 5), (256, 1500, 300, 5)]
LONG = (256, 20000, 2000, 10)


def _chain(target, d, geometry, seed):
    walkers, steps, burn, thin = geometry
    init = initial_walkers(target, np.zeros(d), np.eye(d), walkers, seed)
    t = time.perf_counter()
    smp = run_emcee(target, init, walkers, steps, seed + 1, vectorize=True, progress=False)
    wall = time.perf_counter() - t
    tau = float(np.max(smp.get_autocorr_time(discard=burn, tol=0)))
    kept = smp.get_chain(discard=burn, thin=thin)  # (steps, walkers, d)
    r_hat = float(np.max(az.rhat(az.convert_to_dataset(np.swapaxes(kept, 0, 1))).to_array().values))
    return kept.reshape(-1, d), wall, tau, r_hat


def run_case(name: str, n_seeds: int) -> list:
    from runs_per_posterior import case

    data, model, what = case(name)
    res = sample(data, model, PosteriorSettings(), workers=2, progress=False, log=lambda *a: None)
    target, d = res.target, len(res.space.coordinate_names)
    _chain(target, d, (32, 50, 10, 1), 0)  # warm-up
    long = _chain(target, d, LONG, 999)[0]
    rows = []
    for geometry in GEOMETRIES:
        for seed in range(n_seeds):
            x, wall, tau, r_hat = _chain(target, d, geometry, 10 * seed)
            rng = np.random.default_rng(seed)
            ks = max(
                stats.ks_2samp(
                    rng.choice(x[:, i], 3000, replace=False), rng.choice(long[:, i], 3000, replace=False)
                ).statistic
                for i in range(d)
            )
            rows.append(
                {
                    "case": what,
                    "geometry": geometry,
                    "seed": seed,
                    "wall_s": wall,
                    "tau_steps": tau,
                    "r_hat": r_hat,
                    "shift_sd": float(np.max(np.abs(x.mean(0) - long.mean(0)) / long.std(0))),
                    "sd_log_ratio": float(np.max(np.abs(np.log(x.std(0) / long.std(0))))),
                    "ks": float(ks),
                    "draws": len(x),
                }
            )
            print(rows[-1], flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["beam_rom", "duffing3"])
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args(argv)
    from _machine import machine

    lines = [
        "# Walkers and steps of the chain on the surrogates",
        "",
        f"`python benchmarks/chain_geometry.py --cases {' '.join(args.cases)} --seeds {args.seeds}`; "
        f"{machine()}. Against a {LONG[0]} x {LONG[1]} chain on the same surrogate posterior "
        "(worst over the parameters; median and range over the seeds).",
        "",
        "| case | walkers x steps (burn, thin) | wall [s] | autocorr. time [steps] | max R-hat (ArviZ, "
        "walkers as chains) | mean shift [sd] | sd log ratio | KS (3000 v 3000) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in args.cases:
        rows = run_case(name, args.seeds)
        for g in GEOMETRIES:
            sel = [r for r in rows if r["geometry"] == g]

            def cell(key, fmt):
                v = np.array([r[key] for r in sel])
                return f"{np.median(v):{fmt}} ({v.min():{fmt}}-{v.max():{fmt}})"

            lines.append(
                f"| {sel[0]['case']} | {g[0]} x {g[1]} ({g[2]}, {g[3]}) | {cell('wall_s', '.1f')} | "
                f"{cell('tau_steps', '.0f')} | {cell('r_hat', '.3f')} | {cell('shift_sd', '.3f')} | "
                f"{cell('sd_log_ratio', '.3f')} | "
                f"{cell('ks', '.3f')} |"
            )
    out = ROOT / "benchmarks" / "results" / "chain_geometry.md"
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
