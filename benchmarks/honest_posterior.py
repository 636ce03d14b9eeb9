"""The posterior when the model is wrong: a shear frame whose records hold an effect
the user's model lacks (tests/shear_frame_kit.py), sampled with the default settings.

For each case (the model right; a quadratic damper it lacks; a quadratic storey
spring it lacks) it reports every parameter's posterior mean and sd against the
truth (in posterior sd), whether the 94 % HDI covers it, the likelihood's
scales, R-hat and ESS, the model runs, and the predictive bands' coverage of
every test (``--predictive``).

    python benchmarks/honest_posterior.py [--cases right damper stiffness] [--predictive 32]

writes benchmarks/results/honest_posterior.json and .md.  The records are
cached in benchmarks/results/.cache (they take ~10 s each to integrate).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

import circuit_kit  # noqa: E402
import numpy as np  # noqa: E402
import shear_frame_kit as kit  # noqa: E402
from _machine import machine  # noqa: E402

import bayes_update as bu  # noqa: E402

CASES = {"right": (), "damper": ("damper",), "stiffness": ("stiffness",)}
CIRCUIT = {"A": circuit_kit.SET_A, "B": circuit_kit.SET_B}


def dataset(case: str):
    """The case's records, from the cache when there."""
    from bayes_update.data.folder import write_dataset

    folder = HERE / "results" / ".cache" / f"shear_frame_{case}"
    if not (folder / "dataset.json").exists():
        write_dataset(kit.make_dataset(CASES[case]), folder)
    return bu.read_dataset(folder)


def circuit_dataset(name: str):
    """A circuit data set: estimation set ``name`` (A or B) and the held-out tests, cached."""
    from bayes_update.data.folder import write_dataset

    folder = HERE / "results" / ".cache" / f"circuit_{name}"
    if not (folder / "dataset.json").exists():
        write_dataset(circuit_kit.make_dataset(CIRCUIT[name] + circuit_kit.HELD_OUT), folder)
    return bu.read_dataset(folder)


def run_circuit(predictive: int, seed: int, log=None) -> dict:
    """The circuit (a model of another form than the rig): the posterior from two independent
    estimation sets, their agreement in combined sd, and the held-out prediction errors of the
    posterior's mean against calibrate's."""
    out = {"case": "circuit"}
    quiet = log or (lambda *a: None)
    for name in CIRCUIT:
        data = circuit_dataset(name)
        t0 = time.perf_counter()
        res = bu.sample(
            data,
            circuit_kit.Oscillator(),
            bu.PosteriorSettings(seed=seed, n_predictive=predictive),
            workers=2,
            progress=False,
            log=quiet,
        )
        wall = time.perf_counter() - t0
        cal = bu.calibrate(data, circuit_kit.Oscillator(), workers=2, progress=False, log=quiet)
        out[name] = {
            "wall_s": wall,
            "model_runs": int(sum(res.n_model_runs.values())),
            "summary": {
                k: {m: v[m] for m in ("mean", "sd", "r_hat", "ess_bulk", "ess_tail")} for k, v in res.summary.items()
            },
            "prediction_error": res.predictive.get("prediction_error"),
            "predictive_coverage": res.predictive.get("coverage"),
            "calibrate": {
                "theta": {k: float(v) for k, v in cal.theta.items()},
                "prediction_error": {k: float(v) for k, v in cal.prediction_errors.items()},
            },
            "between_tests": (res.adjustment.between_tests or {}).get("chi2") if res.adjustment else None,
        }
    a, b = out["A"]["summary"], out["B"]["summary"]
    out["agreement_combined_sd"] = {
        k: abs(a[k]["mean"] - b[k]["mean"]) / float(np.hypot(a[k]["sd"], b[k]["sd"])) for k in a
    }
    return out


def circuit_markdown(r: dict) -> str:
    lines = [
        f"## the circuit: two estimation sets, held-out tests {[t[0] for t in circuit_kit.HELD_OUT]}",
        "",
        "| parameter | set A mean +- sd | set B mean +- sd | A - B in combined sd |",
        "|---|---|---|---|",
    ]
    for k, z in r["agreement_combined_sd"].items():
        a, b = r["A"]["summary"][k], r["B"]["summary"][k]
        lines.append(f"| {k} | {a['mean']:.5g} +- {a['sd']:.2g} | {b['mean']:.5g} +- {b['sd']:.2g} | {z:.2f} |")
    lines.append("")
    for name in CIRCUIT:
        x = r[name]
        lines.append(
            f"- set {name} ({x['model_runs']} runs, {x['wall_s']:.0f} s): prediction error of the "
            "posterior mean / calibrate's: "
            + ", ".join(
                f"{t} {100 * e['posterior_mean']:.3f} % / {100 * x['calibrate']['prediction_error'][t]:.3f} % "
                f"({e['posterior_mean'] / x['calibrate']['prediction_error'][t]:.3f}x)"
                for t, e in (x["prediction_error"] or {}).items()
            )
        )
        for test, cov in (x.get("predictive_coverage") or {}).items():
            lines.append(
                f"  - bands, {test}: " + ", ".join(f"{100 * c['50']:.0f} / {100 * c['90']:.0f} %" for c in cov.values())
            )
    return "\n".join(lines) + "\n"


def run_case(case: str, predictive: int, seed: int, log=None, figures: bool = False) -> dict:
    data = dataset(case)
    settings = bu.PosteriorSettings(seed=seed, n_predictive=predictive)
    t0 = time.perf_counter()
    res = bu.sample(data, kit.ShearFrame(), settings, workers=2, progress=False, log=log or (lambda *a: None))
    wall = time.perf_counter() - t0
    rows = {}
    for name, truth in kit.TRUTH.items():
        s = res.summary[name]
        rows[name] = {
            "truth": truth,
            "mean": s["mean"],
            "sd": s["sd"],
            "off_sd": (s["mean"] - truth) / s["sd"],
            "covered": bool(s["hdi_3%"] <= truth <= s["hdi_97%"]),
            "r_hat": s["r_hat"],
            "ess_bulk": s["ess_bulk"],
            "ess_tail": s["ess_tail"],
        }
    out = {
        "case": case,
        "wall_s": wall,
        "model_runs": int(sum(res.n_model_runs.values())),
        "parameters": rows,
        "likelihood": res.likelihood.to_dict(),
    }
    if res.predictive:
        out["predictive_coverage"] = res.predictive.get("coverage")
        out["prediction_error"] = res.predictive.get("prediction_error")
        out["error_model"] = res.predictive.get("error_model")
    out["diagnostics"] = {
        k: res.diagnostics.get(k)
        for k in ("max_r_hat", "min_ess_bulk", "min_ess_tail", "curvature_adjustment", "pointwise_linearisation_error")
    }
    if figures:
        from bayes_update.reports.posterior import write_posterior

        write_posterior(res, HERE / "results" / f"honest_posterior_{case}", truth=dict(kit.TRUTH))
    return out


def markdown(results: list) -> str:
    lines = [
        "# The posterior when the model is wrong (benchmarks/honest_posterior.py)",
        "",
        f"Machine: {machine()}.",
        "",
    ]
    for r in results:
        lines += [
            f"## {r['case']} ({r['model_runs']} model runs, {r['wall_s']:.0f} s)",
            "",
            "| parameter | truth | mean | sd | (mean - truth) / sd | 94 % HDI covers | R-hat | ESS bulk / tail |",
            "|---|---|---|---|---|---|---|---|",
        ]
        for n, p in r["parameters"].items():
            lines.append(
                f"| {n} | {p['truth']:.4g} | {p['mean']:.5g} | {p['sd']:.3g} | {p['off_sd']:+.1f} | "
                f"{'yes' if p['covered'] else 'no'} | {p['r_hat']:.3f} | "
                f"{p['ess_bulk']:.0f} / {p['ess_tail']:.0f} |"
            )
        for test, cov in (r.get("predictive_coverage") or {}).items():
            lines.append(
                f"- predictive bands, {test}: "
                + ", ".join(f"{s} {100 * c['50']:.0f} / {100 * c['90']:.0f} %" for s, c in cov.items())
                + " of the samples inside the 50 / 90 % bands"
            )
        for test, e in (r.get("prediction_error") or {}).items():
            lines.append(f"- prediction error, {test}: " + ", ".join(f"{k} {100 * v:.3f} %" for k, v in e.items()))
        lines.append("")
    return "\n".join(lines)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=list(CASES) + ["circuit"], choices=list(CASES) + ["circuit"])
    ap.add_argument("--predictive", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tag", default="")
    ap.add_argument("--verbose", action="store_true", help="the pipeline's log lines")
    ap.add_argument("--figures", action="store_true", help="write each case's posterior folder (figures)")
    a = ap.parse_args()
    results = []
    circuit = None
    for case in a.cases:
        if case == "circuit":
            circuit = run_circuit(a.predictive, a.seed, print if a.verbose else None)
            print(circuit_markdown(circuit), flush=True)
            continue
        results.append(run_case(case, a.predictive, a.seed, print if a.verbose else None, a.figures))
        print(markdown(results[-1:]), flush=True)
    stem = HERE / "results" / f"honest_posterior{a.tag}"
    stem.with_suffix(".json").write_text(
        json.dumps({"shear_frame": results, "circuit": circuit}, indent=1, default=float)
    )
    stem.with_suffix(".md").write_text(markdown(results) + "\n" + (circuit_markdown(circuit) if circuit else ""))


if __name__ == "__main__":
    main()
