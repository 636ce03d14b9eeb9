"""The log evidence of a posterior, log Z = log int p(D | x) p(x) dx, by importance
sampling: a Student-t proposal (5 degrees of freedom, its scale the draws' covariance
widened by 1.2) fitted to draws of the posterior, n points from it weighed by
exp(log density - log proposal).  With a proposal this close to the posterior the
weights' effective sample size is a large share of n and the estimate's sd (delta
method) some 1/sqrt(n): it is checked against a closed form in
``tests/test_evidence.py``.  The density need not be normalised: the estimate is of the
same density's integral (the package's log priors drop their constants, so compare
evidences of one model family under one prior, not across priors)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special, stats


@dataclass(frozen=True)
class Evidence:
    log_z: float  # log of the integral of exp(log density)
    sd: float  # its Monte Carlo sd (delta method on the mean weight)
    ess_share: float  # effective sample size of the weights / n
    n: int

    def to_dict(self) -> dict:
        return {"log_evidence": self.log_z, "sd": self.sd, "ess_share": self.ess_share, "n": self.n}


def log_evidence(log_density, draws, n: int = 4000, seed=0, df: float = 5.0, widen: float = 1.2) -> Evidence:
    """Importance-sampling estimate of log int exp(log_density(x)) dx.

    Parameters
    ----------
    log_density : callable
        Vectorised, (n, d) -> (n,), -inf outside the support (a model run per
        point if it is the model's posterior: n of them).
    draws : array (m, d)
        Draws of the normalised density, m > d, to fit the proposal.
    """
    draws = np.atleast_2d(np.asarray(draws, float))
    m, d = draws.shape
    if m <= d or not np.all(np.isfinite(draws)):
        raise ValueError(f"need more finite draws than dimensions to fit the proposal, got {draws.shape}")
    if int(n) != n or n < 100:
        raise ValueError(f"n must be an integer >= 100, got {n!r}")
    shape = np.cov(draws.T).reshape(d, d) * widen**2
    q = stats.multivariate_t(loc=draws.mean(axis=0), shape=shape, df=df, seed=np.random.default_rng(seed))
    X = np.atleast_2d(q.rvs(size=int(n))).reshape(int(n), d)
    logp = np.asarray(log_density(X), float).reshape(-1)
    if logp.shape != (n,):
        raise ValueError(f"log_density returned shape {logp.shape} for {n} points")
    if np.any(np.isnan(logp)) or np.any(logp == np.inf):
        raise ValueError("log_density returned NaN or +inf")
    logw = logp - q.logpdf(X)
    if not np.any(np.isfinite(logw)):
        raise ValueError("every proposal point has zero density: the draws are not of this density")
    log_z = float(special.logsumexp(logw) - np.log(n))
    w = np.exp(logw - np.max(logw))
    ess = float(w.sum() ** 2 / np.sum(w**2))
    sd = float(np.std(w) / (np.sqrt(n) * np.mean(w)))
    return Evidence(log_z, sd, ess / n, int(n))


def surrogate_log_evidence(result, n: int = 4000, seed: int = 0) -> Evidence:
    """log p(data) of a :class:`~bayes_update.core.posterior.result.PosteriorResult`
    from its surrogate (no model run), in the internal coordinates, up to the
    prior's constant (the log priors drop it): for comparing models under one
    prior.  A direct result has no surrogate: evaluate
    :class:`~bayes_update.core.posterior.target.DirectLogPosterior` with
    :func:`log_evidence` (n model runs per test)."""
    if result.target is None:
        raise ValueError(
            "this posterior was sampled on the model itself (direct): it has no surrogate to "
            "integrate; use evidence.log_evidence with a DirectLogPosterior (n model runs per test)"
        )
    w = result.design["whitening"]
    ev = log_evidence(result.target, w.to_u(result.draws), n=n, seed=seed)
    # the surrogate lives in u, x = center + L u: dx = |det L| du
    return Evidence(ev.log_z + float(np.linalg.slogdet(w.L)[1]), ev.sd, ev.ess_share, ev.n)
