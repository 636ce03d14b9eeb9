"""The points a refinement round adds: :func:`propose_points`.

Apart from the loop that runs them and refits (:mod:`surrogates.refine`): choosing
points needs a fitted surrogate and a weight, no model run.  A point is worth a run
where ``weight(x) * sd(x)`` is large: ``weight`` is what the caller cares about
(typically the unnormalized posterior density computed from the current surrogate)
and ``sd`` the surrogate's predictive sd in its *transformed* space, the space the
likelihood is written in.

Why this criterion: with a likelihood ``L(t(f(x)))``, an error ``delta`` of the
surrogate at x changes the posterior density there by about
``weight(x) * |d log L / d t| * delta``, so ``weight * sd`` is, to first order
and up to the likelihood's slope (which the package cannot know), the sd of
the posterior density itself: the "maximum posterior variance" rule of active
learning for Bayesian inference (Kandasamy et al. 2015; Jarvenpaa et al.
2019).  Unlike expected improvement it looks for the whole region of mass,
not only the optimum, which is what an MCMC on the surrogate needs.  The
weight is tempered by default (``weight**0.5 * sd``, see ``power``), because
it is computed from a surrogate that is still wrong where it has few points.

A batch is chosen greedily: after each pick, the sd of every candidate is
reduced as if the pick had been run (the "kriging believer": a GP's posterior
variance does not depend on the value observed, so this is exact for the
variance), which spreads the batch over the valley on the scale of the
fitted length scales; a minimum distance in the unit box also keeps picks
away from each other and from the existing design (no near-duplicates, which
add nothing and make the kernel matrix ill-conditioned).
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy.linalg import solve_triangular

from .design import design

__all__ = ["as_list", "propose_points"]


def as_list(surrogate):
    """One surrogate or a list of them (one per output), as a list."""
    return list(surrogate) if isinstance(surrogate, (list, tuple)) else [surrogate]


class _ConditionalVariance:
    """Predictive variances (transformed units) of one fitted GPSurrogate at
    candidates U, updated as points among them are added to the design."""

    def __init__(self, sur, X):
        gp = sur.gp_
        self.k, self.U = gp.kernel_, sur.scale_inputs(X)
        self.alpha = float(np.max(gp.alpha))  # sklearn's jitter on the training diagonal
        # prior variance of a new run (with the white term) and posterior one
        A = solve_triangular(gp.L_, self.k(gp.X_train_, self.U), lower=True, check_finite=False)
        self.A = A
        self.var = np.maximum(self.k.diag(self.U) - np.einsum("ij,ij->j", A, A), 1e-300)
        # to transformed units (sklearn works on standardized t(y))
        _, sd = sur.predict_transformed(X)
        self.scale = sd**2 / self.var
        self.var0 = self.var.copy()
        self.factors = []

    def total(self) -> np.ndarray:
        return self.scale * self.var

    def add(self, j: int):
        # one step of a pivoted Cholesky of the candidates' posterior covariance
        cov = self.k(self.U, self.U[j : j + 1])[:, 0] - self.A.T @ self.A[:, j]
        for u in self.factors:
            cov -= u * u[j]
        u = cov / np.sqrt(self.var[j] + self.alpha)  # var includes the white noise
        self.factors.append(u)
        self.var = np.maximum(self.var - u**2, 1e-300)


def propose_points(
    surrogate,
    candidates,
    weight,
    n: int,
    seed=None,
    *,
    min_distance: float = 0.01,
    log_weight: bool = False,
    power: float = 0.5,
) -> np.ndarray:
    """The next ``n`` design points: high ``weight``, high surrogate uncertainty, spread.

    Parameters
    ----------
    surrogate : a fitted :class:`~surrogates.gp.GPSurrogate`, or a list of them
        on the same inputs (e.g. one per metric: their transformed-space
        variances are added).
    candidates : (m, d) array of points to choose from (e.g. MCMC draws on the
        surrogate posterior), or an int m: that many scrambled Sobol' points in
        the surrogate's box, drawn with ``seed``.
    weight : callable ``weight(X) -> (m,)``: non-negative importance of each
        point (e.g. the unnormalized posterior density from the surrogate), or
        its log with ``log_weight=True`` (-inf allowed; use it when densities
        underflow, which they do for a narrow valley).
    n : number of points to propose.
    seed : int, Generator or None; only used to draw Sobol' candidates.
    min_distance : no proposal closer than this (Euclidean, unit-box
        coordinates) to a training point or an earlier proposal.
    power : score ``weight**power * sd``.  The default 0.5 tempers the
        weight: the weight comes from the current surrogate, which is most
        wrong about the posterior's tails, and a tempered weight spends more
        runs there.  On the curved-valley benchmark (N = 128, 10 seeds) power
        0.5 against 1 cuts the 90th-percentile error at posterior draws from
        1.23 to 0.32 (d = 2) and from 5.7 to 0.87 (d = 3) for a median error
        1.2-1.3 times higher (``benchmarks/bench_surrogates.py``).

    Returns
    -------
    (k, d) array in input units, best first; k < n (with a warning) when
    fewer candidates have a positive weight and respect ``min_distance``.
    """
    surs = as_list(surrogate)
    if not surs:
        raise ValueError("no surrogate given")
    for s in surs:
        s._check_fitted()
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if not min_distance >= 0:
        raise ValueError(f"min_distance must be >= 0, got {min_distance}")
    if not power > 0:
        raise ValueError(f"power must be positive, got {power}")
    s0 = surs[0]
    if any(not np.array_equal(s.bounds_, s0.bounds_) for s in surs[1:]):
        raise ValueError("the surrogates must share one box (bounds)")
    if isinstance(candidates, (int, np.integer)) and not isinstance(candidates, bool):
        C = design(s0.bounds_, int(candidates), "sobol", seed)
    else:
        C = np.asarray(candidates, dtype=float)
        if C.ndim != 2 or C.shape[1] != s0.n_inputs:
            raise ValueError(f"candidates must have shape (m, {s0.n_inputs}), got {C.shape}")
        if not np.all(np.isfinite(C)):
            raise ValueError("candidates contain non-finite values")
    w = np.asarray(weight(C), dtype=float).reshape(-1)
    if w.shape != (len(C),):
        raise ValueError(f"weight(X) must return {len(C)} values, got shape {w.shape}")
    if log_weight:
        if np.any(np.isnan(w)) or np.any(w == np.inf):
            raise ValueError("log weight must be finite or -inf")
        logw = w
    else:
        if np.any(~np.isfinite(w)) or np.any(w < 0):
            raise ValueError("weight must be finite and non-negative (pass log_weight=True for log densities)")
        with np.errstate(divide="ignore"):
            logw = np.log(w)
    logw = power * logw

    conds = [_ConditionalVariance(s, C) for s in surs]
    U = s0.scale_inputs(C)
    # candidates too close to the existing design are out from the start
    dmin = np.full(len(C), np.inf)
    for Xt in {id(s.X_train_): s.X_train_ for s in surs}.values():
        Ut = s0.scale_inputs(Xt)
        for i in range(0, len(C), 2048):  # (chunk, n_train) distances at a time
            dmin[i : i + 2048] = np.minimum(
                dmin[i : i + 2048], np.sqrt(((U[i : i + 2048, None, :] - Ut[None]) ** 2).sum(-1)).min(1)
            )
    alive = np.isfinite(logw) & (dmin >= min_distance)
    picks = []
    while len(picks) < n and alive.any():
        score = logw + 0.5 * np.log(sum(c.total() for c in conds))
        score[~alive] = -np.inf
        j = int(np.argmax(score))
        picks.append(j)
        alive &= np.sqrt(((U - U[j]) ** 2).sum(1)) >= max(min_distance, 1e-12)
        for c in conds:
            c.add(j)
    if not picks:
        raise ValueError("no candidate has a positive weight at the minimum distance from the design")
    if len(picks) < n:
        warnings.warn(
            f"only {len(picks)} of {n} points could be proposed (weight zero or min_distance "
            "excludes the others); pass more candidates or a smaller min_distance",
            stacklevel=2,
        )
    return C[picks]
