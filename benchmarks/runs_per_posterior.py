"""Model runs per posterior: the pipeline's default sizes against its former ones and a long direct chain.

    python benchmarks/runs_per_posterior.py [--cases beam_rom duffing3 chain6] [--seed 0] [--tag _part]

Per case (a model and a data set made from a finer model plus noise on both
channels):

* **default** ("now"): ``sample`` with ``PosteriorSettings()`` (its own start,
  likelihood scales, MAP, design that stops when the surrogate posterior stops
  moving, chain on the surrogates);
* **thorough** ("before"): ``sample`` with ``PosteriorSettings.thorough()`` (the
  former default sizes) and the diagnostics of 2026-11-25 (96 model-run replicates, a 96 + 5 x 32 design, 32 predictive
  runs, a 128-point Sobol' design, 32 x 12000 steps) on the likelihood the
  default run measured (its own scales step, 2 (96 + d + 2) runs, is counted,
  not run);
* **pyvbmc** (Acerbi 2018; a benchmark extra, ``pip install pyvbmc``, skipped
  with a note when absent) on the same log posterior (the direct one, with the
  same curvature adjustment), started at the default run's MAP with plausible
  bounds MAP +- 3 Laplace sd, its default budget of 50 (2 + d) evaluations;
  its runs are counted from the default run's start and scales on (it needs
  them: the same likelihood);
* **reference**: emcee on the model itself (no surrogate) under the same
  likelihood, 48 walkers x 8000 steps (2000 burnt).

Against the reference, per parameter: the mean's shift in reference sd, the
overlap of the 94 % HDIs (intersection / union) and the Kolmogorov-Smirnov
distance between draws thinned to about one per autocorrelation time (with
the KS distance between the reference's own two halves, its Monte Carlo
floor).  The log evidence (up to the prior's constant, the same for all):
the default run's from its surrogate (importance sampling, no model run:
``PosteriorResult.log_evidence``), the reference by the same importance
sampler on the model itself (4000 points from a Student-t fitted to the
reference draws), pyvbmc's ELBO.  And the likelihood scales' check: each
stage's s measured with every replicate a model run (96) against the
control-variate estimate the pipeline uses.  Writes
``benchmarks/results/runs_per_posterior.md`` and ``.json``.
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

from _machine import machine  # noqa: E402

from bayes_update.core.likelihood import estimate_likelihood, likelihood_runs  # noqa: E402
from bayes_update.core.posterior import PosteriorSettings, sample  # noqa: E402
from bayes_update.core.posterior.evidence import log_evidence  # noqa: E402
from bayes_update.core.posterior.target import DirectLogPosterior, Evaluate  # noqa: E402
from surrogates.evaluation import default_executor  # noqa: E402

BEFORE = dict(n_predictive=32, n_global=128)
REFERENCE = dict(direct_walkers=48, direct_steps=8000, direct_burn=2000, n_global=0, n_predictive=0)
N_EVIDENCE = 4000


def case(name: str):
    """(data, model, description)."""
    if name == "beam_rom":
        from bayes_update.models.beam.model import beam_model
        from bayes_update.models.beam.virtual_rig import load_default_dataset

        data = load_default_dataset()
        return data, beam_model(data, "rom"), "beam, default data set, modal ROM (d = 4)"
    from test_user_model import TRUTH, Duffing, make_dataset

    if name == "chain6":
        import tempfile

        import test_measured_records as lab_chain

        records = lab_chain.lab_tests(quadratic_damping=lab_chain.QUADRATIC_DAMPER)
        data = lab_chain.read_back(records, Path(tempfile.mkdtemp()) / "chain6")
        return (
            data,
            LabChain6(),
            ("3-DOF chain on lab records (3 accelerometers, noisy force, offsets, drifts, 2.5x sampling; d = 6)"),
        )
    free = {"duffing3": ("fn", "zeta", "k3"), "duffing5": ("fn", "zeta", "gain", "k3", "k2")}[name]
    model = Duffing(free, fixed={k: v for k, v in TRUTH.items() if k not in free})
    return make_dataset(seed=11), model, f"Duffing oscillator, user model (d = {len(free)})"


class LabChain6:
    """The lab chain of tests/test_measured_records.py with k2 and the quadratic damper
    free as well (d = 6; the records hold the damper: the model has the data's form)."""

    def __init__(self):
        import test_measured_records as lab_chain

        from bayes_update import Parameter

        self.parameters = [
            *lab_chain.LabChain.parameters[:1],
            Parameter("k2", 45.0, 75.0, unit="kN/m"),
            *lab_chain.LabChain.parameters[1:],
            *lab_chain.LabChain().candidate_effects()["quadratic_damper"],
        ]

    def simulate(self, theta, force, fs):
        import test_measured_records as lab_chain

        from bayes_update import ModelError

        old, lab_chain.K2 = lab_chain.K2, float(theta["k2"])  # the user model reads the module's K2
        try:
            y = lab_chain.LabChain().simulate(theta, force, fs)
        finally:
            lab_chain.K2 = old
        if not np.all(np.isfinite(y)):  # a negative quadratic damper can feed energy in: no response
            raise ModelError(f"the response diverges (cq = {theta['cq']} N s^2/m^2, zeta = {theta['zeta']})")
        return y


def compare(draws: dict, ref: dict, rng) -> dict:
    out = {}
    for name, y in ref.items():
        x = draws[name]
        sd = float(np.std(y))
        (la, ha), (lb, hb) = (_hdi(v) for v in (x, y))
        inter, union = max(0.0, min(ha, hb) - max(la, lb)), max(ha, hb) - min(la, lb)
        xs, ys = (rng.choice(v, min(v.size, 3000), replace=False) for v in (x, y))
        out[name] = {
            "mean": float(np.mean(x)),
            "mean_ref": float(np.mean(y)),
            "sd": float(np.std(x)),
            "sd_ref": sd,
            "shift_sd": float((np.mean(x) - np.mean(y)) / sd),
            "hdi_overlap": float(inter / union),
            "ks": float(stats.ks_2samp(xs, ys).statistic),
        }
    return out


def _hdi(x, prob=0.94):
    from bayes_update.core.posterior.arviz_lines import hdi as pooled_hdi

    return np.array(pooled_hdi(x, prob))


def _report(res) -> dict:
    """{reported variable: its draws} (the beam adds P_eff)."""
    return {k: np.asarray(v, float) for k, v in res.space.report(res.draws).items()}


def run_case(name: str, seed: int, parts=("before", "vbmc", "scales")) -> dict:
    data, model, what = case(name)
    t = time.perf_counter()
    now = sample(data, model, PosteriorSettings(seed=seed), workers=2, progress=False, log=lambda *a: None)
    t_now = time.perf_counter() - t
    lik, start = now.likelihood, now.space.to_parameters(now.map.x)
    d = len(now.space.names)
    before, t_before, before_scales = None, 0.0, likelihood_runs(now.problem, 96, now.space, True)
    if "before" in parts:
        t = time.perf_counter()
        before = sample(
            data,
            model,
            PosteriorSettings.thorough(seed=seed, **BEFORE),
            likelihood=lik,
            workers=2,
            progress=False,
            log=lambda *a: None,
        )
        t_before = time.perf_counter() - t
    ref = _reference(name, data, model, now, lik, start, seed)
    full = cv = None
    if "scales" in parts:
        # the scales' check: every replicate a model run, at the same point
        full = estimate_likelihood(now.problem, start, n_replicates=96, seed=seed + 2, space=now.space)
        cv = estimate_likelihood(
            now.problem, start, n_replicates=96, model_replicates=16, seed=seed + 2, space=now.space
        )
    rng = np.random.default_rng(seed)
    refd = ref["report"]
    thin = max(1, int(np.ceil(max(ref["diagnostics"].get("autocorr_time_steps", {}).values() or [1]))))
    refd_thin = {k: v.reshape(-1, 48)[::thin].ravel() if v.size % 48 == 0 else v for k, v in refd.items()}
    half = {k: v.size // 2 for k, v in refd_thin.items()}
    floor = compare(
        {k: v[: half[k]] for k, v in refd_thin.items()}, {k: v[half[k] :] for k, v in refd_thin.items()}, rng
    )
    target = DirectLogPosterior(Evaluate(now.problem, now.space, now.problem.stages), lik, ref["adjustment"])
    vb = _vbmc(target, now, refd_thin, rng, seed) if "vbmc" in parts else {"skipped": "not run (--parts)"}
    ref_evidence, t_evidence, t_ref = ref["evidence"], ref["evidence_wall_s"], ref["wall_s"]
    return {
        "case": name,
        "what": what,
        "d": d,
        "reference_floor": {
            "ks": max(v["ks"] for v in floor.values()),
            "hdi_overlap": min(v["hdi_overlap"] for v in floor.values()),
        },
        "evidence": {
            "reference": {**ref_evidence.to_dict(), "runs": N_EVIDENCE * len(now.problem.stages), "wall_s": t_evidence},
            "default": now.log_evidence(seed=seed + 4).to_dict(),
        },
        "vbmc": vb,
        "now": {
            "runs": now.n_model_runs,
            "wall_s": t_now,
            "compare": compare(_report(now), refd_thin, rng),
            "max_r_hat": now.diagnostics["max_r_hat"],
        },
        "before": None
        if before is None
        else {
            "runs": {
                **before.n_model_runs,
                "likelihood_scales": before_scales,
                "total": before.n_model_runs["total"] + before_scales,
            },
            "wall_s": t_before,
            "compare": compare(_report(before), refd_thin, rng),
            "max_r_hat": before.diagnostics["max_r_hat"],
        },
        "reference": {
            "runs": ref["runs"],
            "wall_s": t_ref,
            "max_r_hat": ref["diagnostics"]["max_r_hat"],
            "min_ess_bulk": ref["diagnostics"]["min_ess_bulk"],
            "cached": ref["cached"],
        },
        "scales": {}
        if full is None
        else {
            st: {"all_model": full.scales[st].noise_sd, "control_variate": cv.scales[st].noise_sd} for st in full.scales
        },
    }


def _reference(name, data, model, now, lik, start, seed) -> dict:
    """The direct chain and its evidence under ``lik``, from the cache when the same
    case, seed and likelihood scales were run before (``benchmarks/results/cache``,
    not in git): a rerun of the pipeline compares against it in minutes."""
    import hashlib
    import pickle

    # the scales to 6 digits: the pool's summation order moves their last digits, which moves
    # no posterior by anything a 400 000-run chain could see
    key = json.dumps(
        {
            "case": name,
            "seed": seed,
            "reference": REFERENCE,
            "scales": {st: f"{sc.sd:.6e}" for st, sc in lik.scales.items()},
        },
        sort_keys=True,
    )
    path = (
        ROOT
        / "benchmarks"
        / "results"
        / "cache"
        / f"reference_{name}_{hashlib.sha1(key.encode()).hexdigest()[:12]}.pkl"
    )
    if path.exists():
        return {**pickle.loads(path.read_bytes()), "cached": True}
    t = time.perf_counter()
    # the d = 6 chain's runs cost 5 ms: a shorter reference (its halves' distances say what that costs)
    sizes = {**REFERENCE, **({"direct_steps": 4000, "direct_burn": 1000} if name == "chain6" else {})}
    sizes["direct_max_steps"] = sizes["direct_steps"]  # a fixed length: the reference is not extended
    ref = sample(
        data,
        model,
        PosteriorSettings(seed=seed + 1, **sizes),
        direct=True,
        likelihood=lik,
        start=start,
        workers=2,
        progress=False,
        log=lambda *a: None,
    )
    t_ref = time.perf_counter() - t
    target = DirectLogPosterior(Evaluate(now.problem, now.space, now.problem.stages), lik, ref.adjustment)
    t = time.perf_counter()
    with default_executor(2) as pool:
        evidence = log_evidence(
            lambda X: np.array([v[0] for v in pool.map(target, list(X), chunksize=50)]),
            ref.draws,
            n=N_EVIDENCE,
            seed=seed + 3,
        )
    out = {
        "report": _report(ref),
        "adjustment": ref.adjustment,
        "diagnostics": ref.diagnostics,
        "runs": ref.n_model_runs["total"],
        "wall_s": t_ref,
        "evidence": evidence,
        "evidence_wall_s": time.perf_counter() - t,
        "key": key,
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(pickle.dumps(out))
    return {**out, "cached": False}


def _vbmc(target, now, refd, rng, seed) -> dict | None:
    """pyvbmc on ``target`` from the default run's MAP (None when pyvbmc is absent)."""
    try:
        from pyvbmc import VBMC
    except ImportError as exc:
        return {"skipped": f"pyvbmc not installed ({exc}); pip install pyvbmc"}
    box = now.space.box()
    sd = np.sqrt(np.diag(now.map.covariance))
    inner = box[:, 0] + 1e-6 * (box[:, 1] - box[:, 0]), box[:, 1] - 1e-6 * (box[:, 1] - box[:, 0])
    x0 = np.clip(now.map.x, *inner)
    plb, pub = np.maximum(x0 - 3 * sd, inner[0]), np.minimum(x0 + 3 * sd, inner[1])
    count = [0]

    def fun(x):
        count[0] += 1
        return float(target(np.asarray(x, float).ravel())[0])

    np.random.seed(seed)  # pyvbmc draws from numpy's global generator
    t = time.perf_counter()
    vbmc = VBMC(
        fun, x0[None, :], box[:, 0][None, :], box[:, 1][None, :], plb[None, :], pub[None, :], options={"display": "off"}
    )
    vp, results = vbmc.optimize()
    wall = time.perf_counter() - t
    X = vp.sample(20000)[0]
    draws = now.space.report(X)
    stages = len(now.problem.stages)
    before = sum(now.n_model_runs.get(k, 0) for k in ("check_and_screen", "start", "likelihood_scales"))
    return {
        "runs": {"start_and_scales": before, "vbmc": stages * count[0], "total": before + stages * count[0]},
        "wall_s": wall,
        "elbo": float(results["elbo"]),
        "elbo_sd": float(results["elbo_sd"]),
        "success": bool(results.get("success_flag", False)),
        "compare": compare({k: np.asarray(v, float) for k, v in draws.items()}, refd, rng),
    }


def table(rows) -> list:
    lines = [
        "| case | pipeline | model runs (start / scales / MAP / design / other) | wall | worst mean shift "
        "[ref sd] | worst 94 % HDI overlap | worst KS | max R-hat | log evidence |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        for key, label in (("before", "thorough (before)"), ("now", "default (now)")):
            p = r[key]
            if p is None:
                continue
            n = p["runs"]
            other = n["total"] - sum(
                n.get(k, 0) for k in ("start", "likelihood_scales", "map_laplace", "design_and_gp")
            )
            c = p["compare"].values()
            ev = r["evidence"]["default"]["log_evidence"] if key == "now" else None
            lines.append(
                f"| {r['what']} | {label} | **{n['total']}** ({n.get('start', 0)} / "
                f"{n.get('likelihood_scales', 0)} / {n.get('map_laplace', 0)} / {n.get('design_and_gp', 0)}"
                f" / {other}) | {p['wall_s']:.0f} s | {max(abs(v['shift_sd']) for v in c):.3f} | "
                f"{min(v['hdi_overlap'] for v in c):.3f} | {max(v['ks'] for v in c):.3f} | "
                f"{p['max_r_hat']:.3f} | {'' if ev is None else f'{ev:.3f}'} |"
            )
        vb = r["vbmc"]
        if "skipped" in vb:
            lines.append(f"| {r['what']} | pyvbmc | {vb['skipped']} | | | | | | |")
        else:
            n, c = vb["runs"], vb["compare"].values()
            lines.append(
                f"| {r['what']} | pyvbmc | **{n['total']}** ({n['start_and_scales']} start and scales / "
                f"{n['vbmc']} VBMC) | {vb['wall_s']:.0f} s | {max(abs(v['shift_sd']) for v in c):.3f} | "
                f"{min(v['hdi_overlap'] for v in c):.3f} | {max(v['ks'] for v in c):.3f} | - | "
                f"{vb['elbo']:.3f} +- {vb['elbo_sd']:.3f} (ELBO) |"
            )
        e = r["evidence"]["reference"]
        lines.append(
            f"| {r['what']} | reference | {r['reference']['runs']} (+ {e['runs']} for the evidence) | "
            f"{r['reference']['wall_s'] + e['wall_s']:.0f} s | its halves: 0 | "
            f"{r['reference_floor']['hdi_overlap']:.3f} | {r['reference_floor']['ks']:.3f} | "
            f"{r['reference']['max_r_hat']:.3f} | {e['log_evidence']:.3f} +- {e['sd']:.3f} |"
        )
    return lines


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="+", default=["beam_rom", "duffing3", "chain6"])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tag", default="", help="suffix of the result files (a run of some cases)")
    ap.add_argument(
        "--parts",
        nargs="*",
        default=["before", "vbmc", "scales"],
        choices=["before", "vbmc", "scales"],
        help="what to run beside the default pipeline and the reference (a rerun against a cached "
        "reference: --parts with none of them)",
    )
    args = ap.parse_args(argv)
    rows = []
    for name in args.cases:
        rows.append(run_case(name, args.seed, tuple(args.parts)))
        print("\n".join(table(rows[-1:])), flush=True)
    lines = [
        "# Model runs per posterior",
        "",
        f"`python benchmarks/runs_per_posterior.py --cases {' '.join(args.cases)} --seed {args.seed}`; {machine()}",
        "",
        "Against a direct emcee chain on the model under the same likelihood (48 x 8000 steps, 2000 burnt; "
        "the d = 6 chain 48 x 4000, 1000 burnt; "
        "its row: the distances between its own two halves, the floor of KS and overlap); "
        "'thorough': PosteriorSettings.thorough() (the former defaults) with the diagnostics of 2026-11-25, "
        "its scales step counted as 96 model-run replicates per stage; 'default': PosteriorSettings().",
        "",
        *table(rows),
        "",
        "Per parameter (default against the reference):",
        "",
        "| case | parameter | mean / reference | sd / reference | shift [sd] | HDI overlap | KS |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        for k, v in r["now"]["compare"].items():
            lines.append(
                f"| {r['case']} | {k} | {v['mean']:.5g} / {v['mean_ref']:.5g} | {v['sd']:.3g} / "
                f"{v['sd_ref']:.3g} | {v['shift_sd']:+.3f} | {v['hdi_overlap']:.3f} | {v['ks']:.3f} |"
            )
    lines += [
        "",
        "Likelihood scales: the noise sd per direction s_n [%] with every replicate a model run (96) "
        "and with the control variate (96 replicates, 16 run on the model):",
        "",
        "| case | stage | all model runs | control variate | ratio |",
        "|---|---|---|---|---|",
    ]
    for r in rows:
        for st, v in r["scales"].items():
            lines.append(
                f"| {r['case']} | {st} | {100 * v['all_model']:.4f} | {100 * v['control_variate']:.4f} | "
                f"{v['control_variate'] / v['all_model']:.3f} |"
            )
    out = ROOT / "benchmarks" / "results" / ("runs_per_posterior" + args.tag)
    out.with_suffix(".json").write_text(json.dumps(rows, indent=1, default=float))
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
