"""The importance-sampling log evidence against closed forms."""

import numpy as np
import pytest

from bayes_update.core.posterior.evidence import log_evidence


def _gaussian(d, seed):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(d, d))
    cov = A @ A.T + 0.3 * np.eye(d)
    mean = rng.normal(size=d)
    P = np.linalg.inv(cov)
    c = -3.7  # an arbitrary constant in the log density

    def logp(X):
        D = np.atleast_2d(X) - mean
        return c - 0.5 * np.einsum("ij,jk,ik->i", D, P, D)

    # int exp(c - q/2) dx = e^c (2 pi)^(d/2) det(cov)^(1/2)
    exact = c + 0.5 * d * np.log(2 * np.pi) + 0.5 * np.linalg.slogdet(cov)[1]
    return logp, rng.multivariate_normal(mean, cov, size=2000), exact


@pytest.mark.parametrize("d", [2, 4, 6])
def test_gaussian_closed_form(d):
    logp, draws, exact = _gaussian(d, seed=10 + d)
    ev = log_evidence(logp, draws, n=4000, seed=1)
    assert ev.ess_share > 0.4
    assert abs(ev.log_z - exact) < 4 * ev.sd + 1e-3
    assert ev.sd < 0.02


def test_truncated_uniform_closed_form():
    # a density that is flat on a box and zero outside: log Z = log(volume) + c
    low, high = np.array([0.0, -1.0, 2.0]), np.array([1.0, 3.0, 2.5])

    def logp(X):
        inside = np.all((X >= low) & (X <= high), axis=1)
        return np.where(inside, 1.25, -np.inf)

    draws = np.random.default_rng(3).uniform(low, high, size=(3000, 3))
    ev = log_evidence(logp, draws, n=20000, seed=2)
    exact = 1.25 + np.log(np.prod(high - low))
    assert abs(ev.log_z - exact) < 4 * ev.sd
    assert ev.sd < 0.03


def test_same_seed_same_number_and_bad_input():
    logp, draws, _ = _gaussian(3, seed=0)
    assert log_evidence(logp, draws, seed=5).log_z == log_evidence(logp, draws, seed=5).log_z
    with pytest.raises(ValueError, match="more finite draws"):
        log_evidence(logp, draws[:3], seed=0)
    with pytest.raises(ValueError, match="NaN"):
        log_evidence(lambda X: np.full(len(X), np.nan), draws)
    with pytest.raises(ValueError, match="zero density"):
        log_evidence(lambda X: np.full(len(X), -np.inf), draws)
