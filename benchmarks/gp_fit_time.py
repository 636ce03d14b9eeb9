"""GP fits: scikit-learn's optimiser against surrogates.gp_fit's (``GPSurrogate(fast=True)``).

    python benchmarks/gp_fit_time.py

Two measurements, the machine noted:

* **one fit**: ``GPSurrogate`` (``C * Matern 5/2 ARD + White``, 2 restarts, as the
  posterior's design fits it) on n points of a smooth function of d inputs plus a
  little noise, n = 24 ... 192, d = 3 and 6: wall time of a cold fit and of a
  warm-started one (``warm_from``, no restart), each way, and the log marginal
  likelihoods reached (the same optimum: the same objective from the same starts);
* **in a posterior**: the seconds spent in ``GPSurrogate.fit`` during ``sample`` of
  the Duffing user model (tests/test_user_model.py, d = 3) and of the beam's ROM on
  the embedded data set (d = 4), default settings, one worker, each way, beside the
  command's wall time, runs and convergence.

Writes ``benchmarks/results/gp_fit_time.md`` and ``.json``.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from _machine import machine  # noqa: E402

from surrogates.gp import GPSurrogate  # noqa: E402


def _data(n, d, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.uniform(size=(n, d))
    y = np.sin(3 * X).sum(axis=1) + X[:, 0] * X[:, -1] + 0.01 * rng.standard_normal(n)
    return X, y


def one_fit(n, d, fast):
    X, y = _data(n, d)
    box = [[0.0, 1.0]] * d
    t = time.perf_counter()
    cold = GPSurrogate(box, transform="none", n_restarts_optimizer=2, seed=0, fast=fast).fit(X, y)
    t_cold = time.perf_counter() - t
    X2, y2 = _data(n + 8, d)
    t = time.perf_counter()
    warm = GPSurrogate(box, transform="none", n_restarts_optimizer=2, seed=0, fast=fast).warm_from(cold).fit(X2, y2)
    t_warm = time.perf_counter() - t
    return {
        "cold_s": t_cold,
        "warm_s": t_warm,
        "cold_log_ml": float(cold.gp_.log_marginal_likelihood_value_),
        "warm_log_ml": float(warm.gp_.log_marginal_likelihood_value_),
    }


def _duffing():
    from test_user_model import TRUTH, Duffing, make_dataset

    free = ("fn", "zeta", "k3")
    return make_dataset(seed=11), Duffing(free, fixed={k: v for k, v in TRUTH.items() if k not in free})


def _rom():
    from bayes_update.models.beam.model import beam_model
    from bayes_update.models.beam.virtual_rig import load_default_dataset

    data = load_default_dataset()
    return data, beam_model(data, kind="rom")


CASES = {
    "duffing": ("Duffing, tests/test_user_model.py, d = 3", _duffing),
    "beam_rom": ("the beam's ROM on the embedded data set, d = 4", _rom),
}


def in_posterior(fast, case="duffing"):
    """Seconds in GPSurrogate.fit during a sample of ``case``, and the sample's wall time."""
    from bayes_update.core.posterior import PosteriorSettings, design, sample

    spent = [0.0, 0]
    real_fit, real_factory = GPSurrogate.fit, design.design_gp

    def timed_fit(self, X, y):
        t = time.perf_counter()
        try:
            return real_fit(self, X, y)
        finally:
            spent[0] += time.perf_counter() - t
            spent[1] += 1

    def factory(*a, **kw):
        sur = real_factory(*a, **kw)
        sur.fast = fast
        return sur

    GPSurrogate.fit, design.design_gp = timed_fit, factory
    try:
        data, model = CASES[case][1]()
        t = time.perf_counter()
        res = sample(data, model, PosteriorSettings(seed=0), workers=1, progress=False, log=lambda *a: None)
        wall = time.perf_counter() - t
    finally:
        GPSurrogate.fit, design.design_gp = real_fit, real_factory
    conv = res.diagnostics["convergence"]
    return {
        "fit_s": spent[0],
        "n_fits": spent[1],
        "wall_s": wall,
        "runs": res.n_model_runs["total"],
        "max_r_hat": conv["max_r_hat"],
        "min_ess_bulk": conv["min_ess_bulk"],
        "means": {k: float(v) for k, v in zip(res.space.coordinate_names, res.draws.mean(axis=0))},
    }


def main():
    import os

    # the machine is shared: its load says how far the seconds are from a quiet machine's
    out = {"machine": machine(), "load_average_1min": os.getloadavg()[0], "one_fit": [], "posterior": {}}
    for d in (3, 6):
        for n in (24, 48, 96, 192):
            row = {"n": n, "d": d}
            for fast in (False, True):
                r = one_fit(n, d, fast)
                row.update({f"{k}_{'fast' if fast else 'sklearn'}": v for k, v in r.items()})
            out["one_fit"].append(row)
            print(row, flush=True)
    for case in CASES:
        out["posterior"][case] = {}
        for fast in (False, True):
            out["posterior"][case]["fast" if fast else "sklearn"] = in_posterior(fast, case)
            print(out["posterior"], flush=True)
    res_dir = ROOT / "benchmarks" / "results"
    (res_dir / "gp_fit_time.json").write_text(json.dumps(out, indent=1) + "\n")
    md = report(out)
    (res_dir / "gp_fit_time.md").write_text(md)
    print(md)


def report(out) -> str:
    """The markdown of a run's numbers (``out``, as written to gp_fit_time.json)."""
    md = [
        "# GP fits: scikit-learn's optimiser against surrogates.gp_fit",
        "",
        f"Machine: {out['machine']}; load average {out['load_average_1min']:.1f} at the start "
        "(a shared machine: the seconds are upper bounds).",
        "",
        "| n | d | cold fit [s] sklearn | fast | warm fit [s] sklearn | fast | log ML sklearn | fast |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in out["one_fit"]:
        md.append(
            f"| {r['n']} | {r['d']} | {r['cold_s_sklearn']:.3f} | {r['cold_s_fast']:.3f} | "
            f"{r['warm_s_sklearn']:.3f} | {r['warm_s_fast']:.3f} | {r['cold_log_ml_sklearn']:.3f} | "
            f"{r['cold_log_ml_fast']:.3f} |"
        )
    md += [
        "",
        "In a posterior (default settings, one worker):",
        "",
        "| case | GP fits by | fits | seconds in fits | sample wall [s] | model runs | max R-hat | min bulk ESS |",
        "|---|---|---:|---:|---:|---:|---:|---:|",
    ]
    for case, p in out["posterior"].items():
        for k in ("sklearn", "fast"):
            md.append(
                f"| {CASES[case][0]} | {k} | {p[k]['n_fits']} | {p[k]['fit_s']:.2f} | {p[k]['wall_s']:.1f} | "
                f"{p[k]['runs']} | {p[k]['max_r_hat']:.4f} | {p[k]['min_ess_bulk']:.0f} |"
            )
    md.append("")
    for case, p in out["posterior"].items():
        md += [
            f"Posterior means ({case}): "
            + "; ".join(
                f"{k}: " + ", ".join(f"{n} {v:.6g}" for n, v in p[k]["means"].items()) for k in ("sklearn", "fast")
            ),
            "",
        ]
    return "\n".join(md)


if __name__ == "__main__":
    main()
