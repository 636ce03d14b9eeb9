"""The GP fit in numpy (surrogates.gp_fit) against scikit-learn's: the same objective and
gradient, and the same optimum from the same starts."""

import numpy as np
import pytest


def test_the_matern52_likelihood_and_gradient_are_scikit_learns():
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    from surrogates.gp_fit import log_marginal_likelihood

    rng = np.random.default_rng(1)
    U = rng.uniform(size=(30, 3))
    y = np.sin(4 * U[:, 0]) + U[:, 1] ** 2 + 0.01 * rng.standard_normal(30)
    y = (y - y.mean()) / y.std()
    kernel = ConstantKernel(1.3) * Matern([0.2, 0.5, 1.1], nu=2.5) + WhiteKernel(1e-4)
    ref = GaussianProcessRegressor(kernel, optimizer=None).fit(U, y)
    for theta in (kernel.theta, kernel.theta + 0.3 * rng.standard_normal(kernel.theta.size)):
        ll, grad = log_marginal_likelihood(theta, U, y)
        ll_ref, grad_ref = ref.log_marginal_likelihood(theta, eval_gradient=True)
        assert ll == pytest.approx(ll_ref, rel=1e-10)
        np.testing.assert_allclose(grad, grad_ref, rtol=1e-7, atol=1e-9)


def test_the_fast_fit_finds_scikit_learns_optimum():
    """The same objective and optimiser from the same starts: the same hyperparameters."""
    from surrogates.gp import GPSurrogate

    rng = np.random.default_rng(2)
    X = rng.uniform(size=(40, 3))
    y = np.sin(3 * X).sum(axis=1) + 0.02 * rng.standard_normal(40)
    slow = GPSurrogate([[0, 1]] * 3, transform="none", n_restarts_optimizer=2, seed=4).fit(X, y)
    fast = GPSurrogate([[0, 1]] * 3, transform="none", n_restarts_optimizer=2, seed=4, fast=True).fit(X, y)
    assert fast.gp_.log_marginal_likelihood_value_ == pytest.approx(slow.gp_.log_marginal_likelihood_value_, abs=1e-5)
    np.testing.assert_allclose(
        fast.hyperparameters()["length_scales"], slow.hyperparameters()["length_scales"], rtol=1e-3
    )
