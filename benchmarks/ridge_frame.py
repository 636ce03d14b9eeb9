"""A posterior on a ridge: the portal frame whose members' modulus and joint stiffness trade (issue 42).

The user's model of notebooks/portal_frame.py with the members' Young's modulus
scale ``e_scale`` updated in place of the corner masses (fixed at 1 kg).  On the
QUICK rig (the sway mode alone in band, 2-40 Hz at 512 Hz) the sway frequency
depends on the column's and the joint's flexibility in series, so e_scale and
k_j trade along a curved ridge that only the mode's shape (the mid-height
displacement against the top acceleration) and the joint's cubic term bound.

    python benchmarks/ridge_frame.py [--seed 0] [--rig-seed 21]

writes ``benchmarks/results/ridge_frame.{json,md}``: the model runs per step,
the wall time and its GP-fitting share, R-hat and ESS, and each parameter's
posterior against the rig's truth.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "notebooks"), str(ROOT / "benchmarks")]

import portal_frame as pf  # noqa: E402
from _machine import machine  # noqa: E402

import bayes_update as bu  # noqa: E402
from bayes_update import Parameter  # noqa: E402

#: the corner masses the ridge frame holds fixed [kg]
M_TOP_KG = 1.0
#: the rig's truth: a joint and a modulus that are not the notebook's (its k_j 0.5, E 200 GPa)
TRUTH = {"k_j": 0.65, "k3": 70.0, "zeta": 0.022, "e_scale": 0.91}


class RidgeFrame(pf.PortalFrame):
    """:class:`portal_frame.PortalFrame` with ``e_scale`` [-], the members' Young's modulus
    over 200 GPa, in place of ``m_top`` (fixed at :data:`M_TOP_KG`)."""

    parameters = [*pf.PortalFrame.parameters[:3], Parameter("e_scale", 0.7, 1.3)]

    def build(self, theta) -> dict:
        return super().build({"m_top": M_TOP_KG, **theta})

    def refined(self) -> "RidgeFrame":
        return type(self)(3 * self.n_elements, 4 * self.substeps, self.table_points, self.element)


class TopOnlyRidgeFrame(RidgeFrame):
    """The ridge frame read by its top accelerometer alone: nothing but the joint's cubic
    term and the prior bounds e_scale against k_j along the sway mode's ridge."""

    sensors = (("acc_top", "acceleration"),)

    def simulate(self, theta, force, fs):
        return super().simulate(theta, force, fs)[:, 0]


def top_only(data):
    """``data`` with the top accelerometer's channel alone."""
    import dataclasses

    tests = [
        dataclasses.replace(t, response=np.asarray(t.response)[:, 0], sensors=(("acc_top", "acceleration"),))
        for t in data.tests
    ]
    return dataclasses.replace(data, tests=tests)


def quick_rig(folder, seed: int, truth=TRUTH) -> dict:
    """The notebook's QUICK rig (2-40 Hz at 512 Hz, two 1-s periods) made by a finer ridge frame."""
    return pf.make_dataset(
        folder,
        seed=seed,
        truth=truth,
        fs=512.0,
        period=512,
        band_hz=(2.0, 40.0),
        levels={"low": 0.25, "medium": 2.0, "high": 4.0},
        rig=RidgeFrame(4, 12, 4001),
        measure_share=False,
        log=None,
    )


def fidelity(post, model, truth, n: int, seed: int) -> dict:
    """The surrogate posterior against the model's: the log posterior on the model itself
    (``DirectLogPosterior``, the same likelihood and curvature adjustment) at ``n`` of
    the draws and at the truth, against the surrogate's at the same draws."""
    from bayes_update.core.posterior.target import DirectLogPosterior, Evaluate
    from surrogates.evaluation import default_executor

    rng = np.random.default_rng(seed + 7)
    X = post.draws[rng.choice(len(post.draws), n, replace=False)]
    direct = DirectLogPosterior(
        Evaluate(post.problem, post.space, post.problem.stages), post.likelihood, post.adjustment
    )
    x_truth = post.space.to_internal({k: truth[k] for k in post.space.names})
    with default_executor(2) as pool:
        values = [v[0] for v in pool.map(direct, [*X, x_truth])]
    lp, lp_truth = np.array(values[:-1]), values[-1]
    surrogate = post.target(post.target.whitening.to_u(X))
    diff = lp - surrogate
    diff -= np.median(diff)  # the whitening's constant Jacobian
    # the draws reweighted to the model's own posterior (importance sampling): how far its means
    # are from the surrogate posterior's, in the surrogate's sd, and the weights' effective share
    w = np.exp(diff - np.max(diff))
    w /= w.sum()
    rep = post.space.report(X)
    shift = {k: float((w @ v - v.mean()) / np.std(v)) for k, v in ((k, np.asarray(v, float)) for k, v in rep.items())}
    return {
        "n": n,
        "sd": float(np.std(diff)),
        "max": float(np.max(np.abs(diff))),
        "reweighted_shift_sd": shift,
        "reweighting_ess": float(1.0 / np.sum(w**2) / n),
        "truth_level": float(np.mean(lp > lp_truth)),
        "lp_truth": float(lp_truth),
        "lp_draws_quantiles": np.quantile(lp, [0.05, 0.5, 0.95]).tolist(),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0, help="the posterior's seed")
    ap.add_argument("--rig-seed", type=int, default=21, help="the virtual rig's seed")
    ap.add_argument("--top-only", action="store_true", help="the top accelerometer alone (a weaker bound)")
    ap.add_argument("--check", type=int, default=120, help="posterior draws run on the model for the check")
    args = ap.parse_args(argv)
    folder = Path(tempfile.mkdtemp()) / "ridge"
    quick_rig(folder, args.rig_seed)
    data = bu.read_dataset(folder)
    model = (TopOnlyRidgeFrame if args.top_only else RidgeFrame)(n_elements=2, substeps=4)
    if args.top_only:
        data = top_only(data)
    lines = []
    t = time.perf_counter()
    post = bu.sample(
        data,
        model,
        bu.PosteriorSettings(seed=args.seed),
        workers=2,
        progress=False,
        log=lambda m: (lines.append(m), print(m, flush=True)),
    )
    wall = time.perf_counter() - t
    d = post.diagnostics
    check = fidelity(post, model, TRUTH, n=args.check, seed=args.seed)
    rows = {}
    for p in model.parameters:
        x = post.idata.posterior[p.name].values.ravel()
        lo, hi = np.quantile(x, [0.05, 0.95])
        rows[p.name] = {
            "mean": float(x.mean()),
            "sd": float(x.std()),
            "q05": float(lo),
            "q95": float(hi),
            "truth": TRUTH[p.name],
            "shift_sd": float((x.mean() - TRUTH[p.name]) / x.std()),
            "covered": bool(lo <= TRUTH[p.name] <= hi),
        }
    corr = np.corrcoef(np.vstack([post.idata.posterior[n].values.ravel() for n in ("k_j", "e_scale")]))[0, 1]
    out = {
        "runs": post.n_model_runs,
        "wall_s": wall,
        "timing": post.timing,
        "max_r_hat": d["max_r_hat"],
        "min_ess_bulk": d["min_ess_bulk"],
        "min_ess_tail": d["min_ess_tail"],
        "corr_kj_e": float(corr),
        "parameters": rows,
        "check": check,
        "seed": args.seed,
        "rig_seed": args.rig_seed,
        "log": lines,
    }
    res = ROOT / "benchmarks" / "results" / ("ridge_frame" + ("_top_only" if args.top_only else ""))
    res.with_suffix(".json").write_text(json.dumps(out, indent=1, default=float))
    md = [
        "# A posterior on a ridge: the portal frame's modulus and joint stiffness",
        "",
        f"`python benchmarks/ridge_frame.py --seed {args.seed} --rig-seed {args.rig_seed}"
        f"{' --top-only' if args.top_only else ''}`; {machine()}",
        "",
        f"model runs: {post.n_model_runs}; wall {wall:.0f} s; max R-hat {d['max_r_hat']:.3f}, "
        f"min ESS bulk {d['min_ess_bulk']:.0f} / tail {d['min_ess_tail']:.0f}; "
        f"correlation of k_j and e_scale {corr:+.3f}",
        "",
        f"The surrogate against the model ({check['n']} posterior draws run on the model, "
        f"{check['n'] + 1} runs beyond the pipeline's): their log posterior differs from the surrogate's by "
        f"{check['sd']:.2f} (sd, the constant removed; largest {check['max']:.2f}); the truth lies at the "
        f"{100 * check['truth_level']:.0f} % highest-posterior level of the model's own log posterior "
        f"(the share of draws above it; a right posterior puts it anywhere, uniformly). Reweighted to the "
        f"model's posterior (importance sampling, effective share {100 * check['reweighting_ess']:.0f} %) "
        "the draws' means move " + ", ".join(f"{k} {v:+.2f}" for k, v in check["reweighted_shift_sd"].items()) + " sd.",
        "",
        "| parameter | truth | mean +- sd | 90 % interval | shift [sd] |",
        "|---|---|---|---|---|",
    ]
    md += [
        f"| {k} | {v['truth']:g} | {v['mean']:.4g} +- {v['sd']:.2g} | {v['q05']:.4g} .. {v['q95']:.4g} | "
        f"{v['shift_sd']:+.2f} |"
        for k, v in rows.items()
    ]
    res.with_suffix(".md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
