"""The hyperparameters of ``C * Matern(nu=5/2, ARD) + White`` by maximum marginal likelihood,
in plain numpy: :func:`fit_matern52`.

scikit-learn's optimiser evaluates the log marginal likelihood and its gradient through
its kernel objects (a tree of kernels, each building an n x n x p gradient array with
its own checks).  Here the same objective (scikit-learn's, to round-off: the same
kernel, the same log parameters and bounds, y standardised as ``normalize_y`` does) and
its analytic gradient take a Cholesky factorisation and a few n x n products, in one
BLAS thread (matrices of tens to a few hundred rows: more threads only contend, the more
so on a shared machine).  Measured (benchmarks/gp_fit_time.py): an evaluation 2-4 times
cheaper for 48-112 points in 4 inputs, a cold fit 1.1-2.6 times faster for 24-192 points,
and the GP fits of a whole posterior 11-17 times faster (a Duffing user model 3.8 -> 0.35 s,
the beam's ROM 14.1 -> 0.85 s; the same hyperparameters, the same posterior).  The fitted
values go back into scikit-learn's kernel, whose regressor is then conditioned on them
without an optimisation, so that everything downstream (predictions,
:mod:`surrogates.gp_mean`) is unchanged.

The gradient, in log parameters: with ``K = C M(r) + s I``, r the length-scaled distance
and ``M(r) = (1 + sqrt5 r + 5 r^2 / 3) exp(-sqrt5 r)``,
``dK/dlog C = C M``, ``dK/dlog s = s I`` and
``dK/dlog l_k = C (5 / 3) (1 + sqrt5 r) exp(-sqrt5 r) d_k^2 / l_k^2`` (d_k the k-th
coordinate difference); ``dlogML/dtheta = 1/2 tr((alpha alpha^T - K^-1) dK/dtheta)``.
Checked against scikit-learn's value and gradient in ``tests/test_budget_surrogates.py``.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import minimize

__all__ = ["fit_matern52", "log_marginal_likelihood"]

SQRT5 = np.sqrt(5.0)


#: scikit-learn's ``alpha``: added to the kernel matrix's diagonal in every fit
JITTER = 1e-10


def log_marginal_likelihood(theta, U, y) -> tuple[float, np.ndarray]:
    """(log marginal likelihood, its gradient) of ``C * Matern52 + White`` at the log
    parameters ``theta = [log C, log l_1..l_d, log s]`` for inputs U (n, d) and targets y (n,)
    (scikit-learn's ``alpha`` = :data:`JITTER` on the diagonal, as its regressor adds it)."""
    theta = np.asarray(theta, float)
    n, d = U.shape
    C, ls, s = np.exp(theta[0]), np.exp(theta[1 : 1 + d]), np.exp(theta[-1])
    D2 = (U[:, None, :] - U[None, :, :]) ** 2 / ls**2  # (n, n, d)
    r = np.sqrt(np.sum(D2, axis=2))
    e = np.exp(-SQRT5 * r)
    M = (1.0 + SQRT5 * r + 5.0 / 3.0 * r * r) * e
    K = C * M + (s + JITTER) * np.eye(n)
    try:
        cf = cho_factor(K, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return -np.inf, np.zeros_like(theta)
    alpha = cho_solve(cf, y, check_finite=False)
    ll = -0.5 * float(y @ alpha) - float(np.sum(np.log(np.diag(cf[0])))) - 0.5 * n * np.log(2 * np.pi)
    W = np.outer(alpha, alpha) - cho_solve(cf, np.eye(n), check_finite=False)
    grad = np.empty_like(theta)
    grad[0] = 0.5 * np.sum(W * (C * M))
    G = C * 5.0 / 3.0 * (1.0 + SQRT5 * r) * e
    for k in range(d):
        grad[1 + k] = 0.5 * np.sum(W * (G * D2[:, :, k]))
    grad[-1] = 0.5 * s * np.trace(W)
    return ll, grad


def fit_matern52(U, y, theta0, bounds, n_restarts: int = 0, seed=0, max_iterations: int | None = None):
    """The log parameters maximising :func:`log_marginal_likelihood` from ``theta0`` and
    ``n_restarts`` starts drawn uniformly within ``bounds`` ((p, 2), log units) with
    ``seed``, by L-BFGS-B (scikit-learn's optimiser and defaults); returns (theta, log ML)."""
    from threadpoolctl import threadpool_limits

    U, y = np.asarray(U, float), np.asarray(y, float)
    bounds = np.asarray(bounds, float)
    with threadpool_limits(1):  # n x n with n in the tens to hundreds: BLAS threads only contend
        return _fit(U, y, theta0, bounds, n_restarts, seed, max_iterations)


def _fit(U, y, theta0, bounds, n_restarts, seed, max_iterations):

    def objective(t):
        ll, g = log_marginal_likelihood(t, U, y)
        return (np.inf, np.zeros_like(g)) if not np.isfinite(ll) else (-ll, -g)

    starts = [np.clip(np.asarray(theta0, float), bounds[:, 0], bounds[:, 1])]
    rng = np.random.RandomState(seed) if not isinstance(seed, np.random.RandomState) else seed
    starts += [rng.uniform(bounds[:, 0], bounds[:, 1]) for _ in range(int(n_restarts))]
    best = None
    options = {} if max_iterations is None else {"maxiter": int(max_iterations)}
    for t0 in starts:
        res = minimize(objective, t0, method="L-BFGS-B", jac=True, bounds=bounds, options=options)
        if np.isfinite(res.fun) and (best is None or res.fun < best.fun):
            best = res
    if best is None:
        return starts[0], -np.inf
    return best.x, -float(best.fun)
