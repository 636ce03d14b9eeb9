"""Surrogate posterior against the direct (surrogate-free) posterior on the same model.

    python benchmarks/posterior_comparison.py [--model rom|fe] [--quick]

Both runs use the default data set, the same prior, likelihood (scales
measured once, at the same start) and seed; the direct one runs emcee on the
model itself.  Per parameter: the posterior means' difference in posterior
sd, the overlap of the 94 % HDIs (intersection / union) and the two-sample
Kolmogorov-Smirnov statistic D on thinned draws.  Thresholds (stated before
the run): |mean difference| < 0.3 sd, HDI overlap > 0.8, D < 0.1.
Writes benchmarks/results/posterior_comparison_<model>.md and
docs/posterior/surrogate_vs_direct_<model>.png.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from _machine import machine  # noqa: E402

from bayes_update.core.posterior import PosteriorSettings, sample  # noqa: E402
from bayes_update.models.beam.model import beam_model  # noqa: E402
from bayes_update.models.beam.virtual_rig import load_default_dataset, truth_paper_units  # noqa: E402

THRESHOLDS = {"mean_diff_sd": 0.3, "hdi_overlap": 0.8, "ks_D": 0.1}


def hdi(x, prob=0.94):
    from bayes_update.core.posterior.arviz_lines import hdi as pooled_hdi

    return np.array(pooled_hdi(x, prob))


def compare(a: dict, b: dict, rng) -> dict:
    out = {}
    for name in ORDER:
        x, y = a[name], b[name]
        sd = np.std(y)
        (la, ha), (lb, hb) = hdi(x), hdi(y)
        inter = max(0.0, min(ha, hb) - max(la, lb))
        union = max(ha, hb) - min(la, lb)
        xs = rng.choice(x, 4000, replace=False)
        ys = rng.choice(y, 4000, replace=False)
        out[name] = {
            "mean_surrogate": float(np.mean(x)),
            "mean_direct": float(np.mean(y)),
            "sd_direct": float(sd),
            "mean_diff_sd": float((np.mean(x) - np.mean(y)) / sd),
            "hdi_overlap": float(inter / union),
            "ks_D": float(stats.ks_2samp(xs, ys).statistic),
        }
        out[name]["pass"] = bool(
            abs(out[name]["mean_diff_sd"]) < THRESHOLDS["mean_diff_sd"]
            and out[name]["hdi_overlap"] > THRESHOLDS["hdi_overlap"]
            and out[name]["ks_D"] < THRESHOLDS["ks_D"]
        )
    return out


def figure(a: dict, b: dict, truth: dict, title: str):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(14, 3.2), constrained_layout=True)
    axes = fig.subplots(1, len(ORDER))
    for ax, name in zip(axes, ORDER):
        lo = min(np.percentile(a[name], 0.1), np.percentile(b[name], 0.1))
        hi = max(np.percentile(a[name], 99.9), np.percentile(b[name], 99.9))
        bins = np.linspace(lo, hi, 50)
        ax.hist(b[name], bins=bins, density=True, color="0.6", label="direct (reference)")
        ax.hist(a[name], bins=bins, density=True, histtype="step", color="C3", lw=1.5, label="GP surrogate")
        ax.axvline(truth[name], color="k", lw=1)
        ax.set_xlabel(LABELS[name])
        ax.set_yticks([])
    axes[0].legend(fontsize=7)
    fig.suptitle(title)
    return fig


ORDER = ("eta", "c", "F", "k_s", "P_eff")
LABELS = {"eta": "eta [MPa s]", "c": "c [N s/mm]", "F": "F [N]", "k_s": "k_s [N/mm]", "P_eff": "P_eff [N]"}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--model", choices=("rom", "fe"), default="rom")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args(argv)
    data = load_default_dataset()
    model = beam_model(data, args.model)
    kw = dict(n_linear=0, n_global=0)
    settings = PosteriorSettings.quick(**kw) if args.quick else PosteriorSettings(**kw)
    if args.model == "fe" and not args.quick:
        # the direct FE chain costs 0.1 s per likelihood: 24 x 1000 steps is 40 CPU-minutes
        settings = PosteriorSettings(**kw, direct_walkers=24, direct_steps=1000, direct_burn=300)
    t0 = time.perf_counter()
    sur = sample(data, model, settings, progress=False)
    t_sur = time.perf_counter() - t0
    t0 = time.perf_counter()
    start = sur.space.to_parameters(sur.map.x)
    direct = sample(data, model, settings, direct=True, start=start, likelihood=sur.likelihood, progress=True)
    t_dir = time.perf_counter() - t0
    a, b = sur.space.report(sur.draws), direct.space.report(direct.draws)
    truth = truth_paper_units(data)
    res = compare(a, b, np.random.default_rng(0))
    name = args.model + ("_quick" if args.quick else "")
    fig = figure(
        a,
        b,
        truth,
        f"{args.model}: surrogate ({sur.n_model_runs['total']} model runs, {t_sur:.0f} s) "
        f"vs direct ({direct.n_model_runs['total']} runs, {t_dir:.0f} s); line = truth",
    )
    (ROOT / "docs" / "posterior").mkdir(parents=True, exist_ok=True)
    fig.savefig(ROOT / "docs" / "posterior" / f"surrogate_vs_direct_{name}.png", dpi=110)
    lines = [
        f"# Surrogate vs direct posterior ({args.model}{', quick' if args.quick else ''})",
        "",
        f"`python benchmarks/posterior_comparison.py --model {args.model}{' --quick' if args.quick else ''}`; "
        f"{machine()}",
        "",
        f"surrogate: {t_sur:.0f} s, {sur.n_model_runs['total']} model runs; direct: {t_dir:.0f} s, "
        f"{direct.n_model_runs['total']} model runs; thresholds {THRESHOLDS}",
        "",
        "| parameter | mean (surrogate) | mean (direct) | sd (direct) | diff / sd | HDI overlap | KS D | pass |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k, v in res.items():
        lines.append(
            f"| {k} | {v['mean_surrogate']:.5g} | {v['mean_direct']:.5g} | {v['sd_direct']:.3g} | "
            f"{v['mean_diff_sd']:+.3f} | {v['hdi_overlap']:.3f} | {v['ks_D']:.3f} | {v['pass']} |"
        )
    lines += [
        "",
        "R-hat / bulk ESS: surrogate max {:.4f} / min {:.0f}; direct max {:.4f} / min {:.0f}".format(
            sur.diagnostics["max_r_hat"],
            sur.diagnostics["min_ess_bulk"],
            direct.diagnostics["max_r_hat"],
            direct.diagnostics["min_ess_bulk"],
        ),
        "",
        "surrogate check at posterior draws: "
        + json.dumps({k: v for k, v in sur.predictive.items() if not k.startswith("_")}),
    ]
    out = ROOT / "benchmarks" / "results" / f"posterior_comparison_{name}.md"
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
