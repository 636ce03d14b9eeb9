"""Linearised calibration check of the likelihood at the SBC's truths.

    python benchmarks/sbc_linearised.py [--truths 50] [--replicates 96]

For each truth and noisy data set of ``benchmarks/sbc.py`` (same seed, same
noise realisations), at the truth itself: the scaled residual vector r of
both stages, its Jacobian J (central differences) and the bootstrap's noise
replicates.  The least-squares error dx = (J^T J)^-1 J^T r is what the
posterior's spread has to cover; its squared Mahalanobis distance under

* the plain likelihood's covariance (J^T J)^-1, and
* the curvature-adjusted (sandwich) covariance H^-1 M H^-1, M = J^T Sigma J
  from the first 24 and from all K replicates,

is chi^2_4 when that covariance is right: 10 % of truths beyond 7.78, 5 %
beyond 9.49, mean 4; and each parameter's marginal 90 % interval (F by the
delta method) should cover its truth in 90 % of them.  No surrogate, no MCMC: this isolates the likelihood
and its adjustment from the sampler (a few seconds per truth on the ROM).
Writes benchmarks/results/sbc_linearised_seed<seed>.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _machine import machine  # noqa: E402
from sbc import N_RANK, synthetic_dataset  # noqa: E402

import fe  # noqa: E402
from bayes_update.core.likelihood import estimate_likelihood  # noqa: E402
from bayes_update.core.mode import ResidualFunction, SpacePoint  # noqa: E402
from bayes_update.core.parameters import ParameterSet  # noqa: E402
from bayes_update.core.problem import Problem  # noqa: E402
from bayes_update.models.beam.model import Beam  # noqa: E402
from bayes_update.models.beam.virtual_rig import PAPER_EQUIVALENT_RIG  # noqa: E402

#: kept draws per SBC truth (24 walkers x (5000 - 1000) / 5): sbc.py draws its
#: rank thinning from the same generator, replayed here to meet the same noise
SBC_DRAWS = 19200
CHI2_4_90, CHI2_4_95 = 7.779, 9.488
Z90 = 1.6449
PARAMS = ("eta", "c", "F", "k_s", "P_eff")


def covariances(J, residuals, stages, scales, k_small=24) -> list:
    """[(J^T J)^-1, sandwich from the first ``k_small`` replicates, sandwich
    from all of them]."""
    H = J.T @ J
    out = [np.linalg.inv(H)]
    for k_max in (k_small, None):
        M, row = np.zeros_like(H), 0
        for st in stages:
            D = residuals[st][0][:k_max] / scales[st]  # (rows, weights): all-model replicates, weights 1/K
            DJ = D @ J[row : row + D.shape[1]]
            row += D.shape[1]
            M += DJ.T @ DJ / len(D)
        out.append(np.linalg.solve(H, np.linalg.solve(H, M).T))
    return out


def statistics(dx, C, grad_F) -> tuple:
    """Squared Mahalanobis distance of dx under C and the marginal z of eta,
    c, F, k_s, P_eff (F by the delta method)."""
    sd = np.sqrt(np.diag(C))
    z_F = grad_F @ dx / np.sqrt(grad_F @ C @ grad_F)
    z = [dx[0] / sd[0], dx[1] / sd[1], z_F, dx[3] / sd[3], dx[2] / sd[2]]
    return float(dx @ np.linalg.solve(C, dx)), z


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--truths", type=int, default=50)
    ap.add_argument("--replicates", type=int, default=96)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    if args.replicates < 24:
        raise SystemExit("--replicates must be at least 24 (the small sandwich uses the first 24)")
    rig = PAPER_EQUIVALENT_RIG
    model = Beam(fe.ModalROM(rig))
    space = ParameterSet(model.parameters, model)
    rng = np.random.default_rng(args.seed)
    truths = space.sample_prior(args.truths, seed=args.seed)
    widths = np.diff(space.box(), axis=1)[:, 0]
    rows, t0 = [], time.perf_counter()
    for k, x in enumerate(truths):
        data = synthetic_dataset(model, space.to_parameters(x), rng)
        rng.choice(SBC_DRAWS, N_RANK, replace=False)
        problem = Problem(data, model)
        lik = estimate_likelihood(
            problem, space.to_parameters(x), model_error=False, n_replicates=args.replicates, seed=k, space=space
        )
        stages = lik.stages
        scales = {st: lik.scales[st].sd for st in stages}
        fun = ResidualFunction(problem, stages, tuple(scales[st] for st in stages), SpacePoint(space, model))
        r = fun(x)
        cols = []
        for i in range(len(x)):
            h = np.zeros_like(x)
            h[i] = 1e-4 * widths[i]
            cols.append((fun(x + h) - fun(x - h)) / (2 * h[i]))
        J = np.array(cols).T
        dx = np.linalg.solve(J.T @ J, J.T @ r)
        grad_F = np.array([0.0, 0.0, (model.kb + x[3]) / model.kb, x[2] / model.kb])
        row = [statistics(dx, C, grad_F) for C in covariances(J, lik.noise_residuals, stages, scales)]
        rows.append(row)
        print(
            f"{k}: chi^2 plain {row[0][0]:.2f}, sandwich(24) {row[1][0]:.2f}, "
            f"sandwich({args.replicates}) {row[2][0]:.2f}",
            flush=True,
        )
    S = np.array([[c[0] for c in r] for r in rows])  # (n, 3)
    Z = np.array([[c[1] for c in r] for r in rows])  # (n, 3, 5)
    names = [
        "plain likelihood, (J^T J)^-1",
        "sandwich from 24 replicates",
        f"sandwich from {args.replicates} replicates",
    ]
    lines = [
        "# Linearised calibration of the likelihood at the SBC truths",
        "",
        f"`python benchmarks/sbc_linearised.py --truths {args.truths} --replicates {args.replicates} "
        f"--seed {args.seed}`; {machine()}; {time.perf_counter() - t0:.0f} s",
        "",
        "Squared Mahalanobis distance of the least-squares error at the truth (chi^2_4 if the covariance "
        "is right: mean 4, 10 % beyond 7.78, 5 % beyond 9.49) and the coverage of the marginal 90 % "
        f"intervals (binomial sd over {args.truths} truths: {100 * np.sqrt(0.09 / args.truths):.1f} %).",
        "",
        "| covariance | mean | beyond 7.78 | beyond 9.49 | " + " | ".join(f"{n} 90 % cover" for n in PARAMS) + " |",
        "|---" * (4 + len(PARAMS)) + "|",
    ]
    for j, name in enumerate(names):
        cover = np.mean(np.abs(Z[:, j]) < Z90, axis=0)
        lines.append(
            f"| {name} | {S[:, j].mean():.2f} | {100 * np.mean(S[:, j] > CHI2_4_90):.0f} % | "
            f"{100 * np.mean(S[:, j] > CHI2_4_95):.0f} % | " + " | ".join(f"{100 * c:.0f} %" for c in cover) + " |"
        )
    (ROOT / "benchmarks" / "results" / f"sbc_linearised_seed{args.seed}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
