"""Simulation-based calibration of `bayes-update sample` (Talts et al. 2018).

    python benchmarks/sbc.py [--truths 50] [--seed 0] [--budget former|default|budget]

For each of N truths drawn from the prior (uniform in eta, c, F, k_s on the
prior box of docs/design.md): a data set of the two updating tests (chirp 20-50 Hz, 0.02 N
and 0.2 N, 4 s at 1024 Hz) made by the modal ROM at the truth, with white
noise at 40 dB on the force and on the velocity (the model is driven by the
clean force, the updating sees the noisy one, as on the rig); then the whole
surrogate pipeline on the same ROM: deterministic start on coarse grids,
likelihood scales from noise replicates (model-error term off: the data come
from the updating model itself), MAP, GP design and refinement, emcee.  The
generative model is the ROM so that the test is about the inference, not
about the model error (which benchmarks/posterior_comparison.py and the
default data set cover).

Reported per parameter: coverage of the 90 % central credible interval
(acceptance 80-98 %) and the chi-square p-value of the rank histogram (rank of
the truth among 99 thinned draws, 10 bins).  Writes
benchmarks/results/sbc.md and docs/posterior/sbc_ranks.png.
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

import fe  # noqa: E402
from bayes_update.core.parameters import ParameterSet  # noqa: E402
from bayes_update.core.posterior import PosteriorSettings, sample  # noqa: E402
from bayes_update.data import signals  # noqa: E402
from bayes_update.data.dataset import Dataset, Record  # noqa: E402
from bayes_update.models.beam.model import Beam  # noqa: E402
from bayes_update.models.beam.virtual_rig import PAPER_EQUIVALENT_RIG  # noqa: E402

LEVELS = {"chirp_low": (0.02, "linear"), "chirp_high": (0.2, "nonlinear")}
FS = 1024.0
SNR_DB = 40.0
N_RANK = 99
ORDER = ("eta", "c", "F", "k_s", "P_eff")


def synthetic_dataset(model, params, rng) -> Dataset:
    tests = []
    for name, (amp, role) in LEVELS.items():
        f = signals.chirp(amp)
        v = model.simulate(params, f, FS)
        f_rec = signals.add_noise(f, SNR_DB, rng)
        v_rec = signals.add_noise(v, SNR_DB, rng)
        t = np.arange(f.size) / FS
        tests.append(Record(f"{name}.csv", "chirp", name.split("_")[1], role, t, f_rec, v_rec))
    return Dataset("sbc", FS, model.rig, tests)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truths", type=int, default=50)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--budget",
        choices=("former", "default", "budget"),
        default="former",
        help="former: the sizes of the first SBC (96 model replicates, 64 + 3 x 24 design, 24 x 5000 "
        "steps; results/sbc.md); default: PosteriorSettings() as shipped (results/sbc_default.md); "
        "budget: PosteriorSettings.budget() (results/sbc_budget.md)",
    )
    args = ap.parse_args(argv)
    rig = PAPER_EQUIVALENT_RIG
    model = Beam(fe.ModalROM(rig))
    space = ParameterSet(model.parameters, model)
    rng = np.random.default_rng(args.seed)
    truths = space.sample_prior(args.truths, seed=args.seed)
    if args.budget == "former":
        settings = PosteriorSettings(
            n_initial=64,
            n_rounds=3,
            batch=24,
            n_walkers=24,
            n_steps=5000,
            burn=1000,
            thin=5,
            n_linear=0,
            n_global=0,
            n_predictive=0,
            model_error=False,
            n_replicates=96,
            model_replicates=None,
            stop_tolerance=0.0,
        )
    elif args.budget == "default":
        settings = PosteriorSettings(n_linear=0, model_error=False)
    else:
        settings = PosteriorSettings.budget(n_linear=0, model_error=False)
    tag = "" if args.budget == "former" else f"_{args.budget}"
    rows = []
    t_all = time.perf_counter()
    for k, x in enumerate(truths):
        t0 = time.perf_counter()
        data = synthetic_dataset(model, space.to_parameters(x), rng)
        try:
            res = sample(data, model, settings, workers=2, progress=False, log=lambda *a: None)
        except Exception as exc:  # a failed inference is a result, not a crash of the study
            rows.append({"truth": x.tolist(), "error": f"{type(exc).__name__}: {exc}"})
            print(f"{k}: failed: {exc}", flush=True)
            continue
        d = space.report(res.draws)
        tr = space.report(x[None, :])
        thin = rng.choice(len(res.draws), N_RANK, replace=False)
        row = {
            "truth": x.tolist(),
            "time_s": time.perf_counter() - t0,
            "max_r_hat": res.diagnostics["max_r_hat"],
            "model_runs": res.n_model_runs["total"],
        }
        for name in ORDER:
            lo, hi = np.percentile(d[name], [5, 95])
            row[name] = {
                "covered": bool(lo <= tr[name][0] <= hi),
                "rank": int(np.sum(d[name][thin] < tr[name][0])),
                "truth": float(tr[name][0]),
                "mean": float(np.mean(d[name])),
                "sd": float(np.std(d[name])),
                "q05": float(lo),
                "q95": float(hi),
            }
        rows.append(row)
        print(
            f"{k}: {row['time_s']:.0f} s, {row['model_runs']} runs, r_hat {row['max_r_hat']:.3f}, covered "
            f"{[row[n]['covered'] for n in ORDER]}",
            flush=True,
        )
        (ROOT / "benchmarks" / "results" / f"sbc_rows{tag}.json").write_text(json.dumps(rows, indent=1))
    ok = [r for r in rows if "error" not in r]
    lines = [
        "# Simulation-based calibration of the surrogate posterior",
        "",
        f"`python benchmarks/sbc.py --truths {args.truths} --seed {args.seed} --budget {args.budget}`; "
        f"{machine()}; "
        f"{time.perf_counter() - t_all:.0f} s; {len(ok)} of {len(rows)} truths inferred",
        "",
        "| parameter | coverage of the 90 % interval | rank histogram (10 bins) | chi-square p |",
        "|---|---|---|---|",
    ]
    from matplotlib.figure import Figure

    fig = Figure(figsize=(14, 3), constrained_layout=True)
    axes = fig.subplots(1, len(ORDER))
    summary = {}
    for ax, name in zip(axes, ORDER):
        cov = float(np.mean([r[name]["covered"] for r in ok]))
        ranks = np.array([r[name]["rank"] for r in ok])
        counts = np.histogram(ranks, bins=10, range=(0, N_RANK + 1))[0]
        p = float(stats.chisquare(counts).pvalue)
        summary[name] = {"coverage_90": cov, "chi2_p": p}
        lines.append(f"| {name} | {100 * cov:.0f} % | {' '.join(map(str, counts))} | {p:.3f} |")
        ax.bar(np.arange(10), counts, color="C0")
        ax.axhline(len(ok) / 10, color="k", lw=0.8)
        ax.set_title(f"{name}: 90 % cover {100 * cov:.0f} %, p = {p:.2f}", fontsize=9)
        ax.set_xticks([])
    fig.suptitle(f"SBC rank histograms, {len(ok)} truths from the prior (uniform = calibrated)")
    (ROOT / "docs" / "posterior").mkdir(parents=True, exist_ok=True)
    fig.savefig(ROOT / "docs" / "posterior" / f"sbc_ranks{tag}.png", dpi=110)
    failed = [r for r in rows if "error" in r]
    if failed:
        lines += ["", f"failed inferences: {len(failed)}: " + "; ".join(r["error"][:120] for r in failed)]
    lines += [
        "",
        "max R-hat over truths: " + f"{max(r['max_r_hat'] for r in ok):.4f}",
        "median time per truth: " + f"{np.median([r['time_s'] for r in ok]):.0f} s",
        "model runs per truth (median, max): "
        + (
            f"{np.median([r['model_runs'] for r in ok]):.0f}, {max(r['model_runs'] for r in ok)}"
            if all("model_runs" in r for r in ok)
            else "not recorded"
        ),
    ]
    (ROOT / "benchmarks" / "results" / f"sbc{tag}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
