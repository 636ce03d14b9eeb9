"""Model runs per posterior: the pipeline's default sizes against its former ones and a long direct chain.

    python benchmarks/runs_per_posterior.py [--cases beam_rom duffing3 duffing5] [--seed 0]

Per case (a model and a data set made from a finer model plus noise on both
channels):

* **budget**: ``sample`` with ``PosteriorSettings.budget()`` (its own start,
  likelihood scales, MAP, design that stops when the surrogate posterior stops
  moving, chain on the surrogates);
* **default**: ``sample`` with the default sizes and the diagnostics of
  2026-11-25 (96 model-run replicates, a 96 + 5 x 32 design, 32 predictive
  runs, a 128-point Sobol' design, 32 x 12000 steps) on the likelihood the
  budget run measured (its own scales step, 2 (96 + d + 2) runs, is counted,
  not run);
* **reference**: emcee on the model itself (no surrogate) under the same
  likelihood, 48 walkers x 3000 steps (1000 burnt).

Against the reference, per parameter: the mean's shift in reference sd, the
overlap of the 94 % HDIs (intersection / union) and the Kolmogorov-Smirnov
distance between draws thinned to about one per autocorrelation time.  And
the likelihood scales' check: each stage's s measured with every replicate a
model run (96) against the control-variate estimate the pipeline uses.
Not here yet: pyvbmc and a log-evidence reference (the issue's other
columns).  Writes ``benchmarks/results/runs_per_posterior.md`` and ``.json``.
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
sys.path.insert(0, str(ROOT / "tests"))

from bayes_update.core.likelihood import estimate_likelihood, likelihood_runs  # noqa: E402
from bayes_update.core.posterior import PosteriorSettings, sample  # noqa: E402

from _machine import machine  # noqa: E402

BEFORE = dict(n_predictive=32, n_global=128)
REFERENCE = dict(n_walkers=48, direct_steps=3000, direct_burn=1000, n_global=0, n_predictive=0)


def case(name: str):
    """(data, model, description)."""
    if name == "beam_rom":
        from bayes_update.models.beam.model import beam_model
        from bayes_update.models.beam.virtual_rig import load_default_dataset

        data = load_default_dataset()
        return data, beam_model(data, "rom"), "beam, default data set, modal ROM (d = 4)"
    from test_user_model import TRUTH, Duffing, make_dataset

    free = {"duffing3": ("fn", "zeta", "k3"), "duffing5": ("fn", "zeta", "gain", "k3", "k2")}[name]
    model = Duffing(free, fixed={k: v for k, v in TRUTH.items() if k not in free})
    return make_dataset(seed=11), model, f"Duffing oscillator, user model (d = {len(free)})"


def compare(draws: dict, ref: dict, rng) -> dict:
    out = {}
    for name, y in ref.items():
        x = draws[name]
        sd = float(np.std(y))
        (la, ha), (lb, hb) = (_hdi(v) for v in (x, y))
        inter, union = max(0.0, min(ha, hb) - max(la, lb)), max(ha, hb) - min(la, lb)
        xs, ys = (rng.choice(v, min(v.size, 3000), replace=False) for v in (x, y))
        out[name] = {"mean": float(np.mean(x)), "mean_ref": float(np.mean(y)), "sd": float(np.std(x)), "sd_ref": sd,
                     "shift_sd": float((np.mean(x) - np.mean(y)) / sd), "hdi_overlap": float(inter / union),
                     "ks": float(stats.ks_2samp(xs, ys).statistic)}
    return out


def _hdi(x, prob=0.94):
    import arviz as az
    return az.hdi(np.asarray(x), hdi_prob=prob)


def _report(res) -> dict:
    """{reported variable: its draws} (the beam adds P_eff)."""
    return {k: np.asarray(v, float) for k, v in res.space.report(res.draws).items()}


def run_case(name: str, seed: int) -> dict:
    data, model, what = case(name)
    t = time.perf_counter()
    now = sample(data, model, PosteriorSettings.budget(seed=seed), workers=2, progress=False, log=lambda *a: None)
    t_now = time.perf_counter() - t
    lik, start = now.likelihood, now.space.to_parameters(now.map.x)
    d = len(now.space.names)
    t = time.perf_counter()
    before = sample(data, model, PosteriorSettings(seed=seed, **BEFORE), likelihood=lik, workers=2, progress=False,
                    log=lambda *a: None)
    t_before = time.perf_counter() - t
    before_scales = likelihood_runs(now.problem, 96, now.space, True)
    t = time.perf_counter()
    ref = sample(data, model, PosteriorSettings(seed=seed + 1, **REFERENCE), direct=True, likelihood=lik, start=start,
                 workers=2, progress=False, log=lambda *a: None)
    t_ref = time.perf_counter() - t
    # the scales' check: every replicate a model run, at the same point
    full = estimate_likelihood(now.problem, start, n_replicates=96, seed=seed + 2, space=now.space)
    cv = estimate_likelihood(now.problem, start, n_replicates=96, model_replicates=16, seed=seed + 2, space=now.space)
    rng = np.random.default_rng(seed)
    refd = _report(ref)
    thin = max(1, int(np.ceil(max(ref.diagnostics.get("autocorr_time_steps", {}).values() or [1]))))
    refd_thin = {k: v.reshape(-1, 48)[::thin].ravel() if v.size % 48 == 0 else v for k, v in refd.items()}
    return {"case": name, "what": what, "d": d,
            "now": {"runs": now.n_model_runs, "wall_s": t_now, "compare": compare(_report(now), refd_thin, rng),
                    "max_r_hat": now.diagnostics["max_r_hat"]},
            "before": {"runs": {**before.n_model_runs, "likelihood_scales": before_scales,
                                "total": before.n_model_runs["total"] + before_scales},
                       "wall_s": t_before, "compare": compare(_report(before), refd_thin, rng),
                       "max_r_hat": before.diagnostics["max_r_hat"]},
            "reference": {"runs": ref.n_model_runs["total"], "wall_s": t_ref, "max_r_hat": ref.diagnostics["max_r_hat"],
                          "min_ess_bulk": ref.diagnostics["min_ess_bulk"]},
            "scales": {st: {"all_model": full.scales[st].noise_sd, "control_variate": cv.scales[st].noise_sd}
                       for st in full.scales}}


def table(rows) -> list:
    lines = ["| case | pipeline | model runs (start / scales / MAP / design / other) | wall | worst mean shift "
             "[ref sd] | worst 94 % HDI overlap | worst KS | max R-hat |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        for key, label in (("before", "default"), ("now", "budget")):
            p = r[key]
            n = p["runs"]
            other = n["total"] - sum(n.get(k, 0) for k in ("start", "likelihood_scales", "map_laplace",
                                                            "design_and_gp"))
            c = p["compare"].values()
            lines.append(f"| {r['what']} | {label} | **{n['total']}** ({n.get('start', 0)} / "
                         f"{n.get('likelihood_scales', 0)} / {n.get('map_laplace', 0)} / {n.get('design_and_gp', 0)}"
                         f" / {other}) | {p['wall_s']:.0f} s | {max(abs(v['shift_sd']) for v in c):.3f} | "
                         f"{min(v['hdi_overlap'] for v in c):.3f} | {max(v['ks'] for v in c):.3f} | "
                         f"{p['max_r_hat']:.3f} |")
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["beam_rom", "duffing3", "duffing5"])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    rows = []
    for name in args.cases:
        rows.append(run_case(name, args.seed))
        print("\n".join(table(rows[-1:])), flush=True)
    lines = ["# Model runs per posterior", "", f"`python benchmarks/runs_per_posterior.py --cases "
             f"{' '.join(args.cases)} --seed {args.seed}`; {machine()}", "",
             "Against a direct emcee chain on the model under the same likelihood (48 x 3000 steps, 1000 burnt); "
             "'default': the default sizes with the diagnostics of 2026-11-25, its scales step counted as 96 "
             "model-run replicates per stage; 'budget': PosteriorSettings.budget().", "", *table(rows), "",
             "Per parameter (budget against the reference):", "",
             "| case | parameter | mean / reference | sd / reference | shift [sd] | HDI overlap | KS |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        for k, v in r["now"]["compare"].items():
            lines.append(f"| {r['case']} | {k} | {v['mean']:.5g} / {v['mean_ref']:.5g} | {v['sd']:.3g} / "
                         f"{v['sd_ref']:.3g} | {v['shift_sd']:+.3f} | {v['hdi_overlap']:.3f} | {v['ks']:.3f} |")
    lines += ["", "Likelihood scales: the noise sd per direction s_n [%] with every replicate a model run (96) "
              "and with the control variate (96 replicates, 16 run on the model):", "",
              "| case | stage | all model runs | control variate | ratio |", "|---|---|---|---|---|"]
    for r in rows:
        for st, v in r["scales"].items():
            lines.append(f"| {r['case']} | {st} | {100 * v['all_model']:.4f} | {100 * v['control_variate']:.4f} | "
                         f"{v['control_variate'] / v['all_model']:.3f} |")
    out = ROOT / "benchmarks" / "results" / "runs_per_posterior"
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1, default=float))
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
