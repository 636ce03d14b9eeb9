"""The curvature (sandwich) adjustment of the likelihood, on a linear Gaussian
model where the least-squares estimator's sampling covariance is known by
Monte Carlo, independently of the sandwich formula."""
import pickle

import numpy as np

from bayes_update.core.adjustment import curvature_adjustment
from bayes_update.core.likelihood import Likelihood, StageScale

N, D_PAR = 40, 4


def _likelihood(residuals, s, model_error=0.0):
    sc = StageScale("nonlinear", float(np.mean(residuals ** 2) * N), float(N), model_error, N, len(residuals),
                    span_variance=s ** 2 - model_error ** 2)
    return Likelihood({"nonlinear": sc}, {"nonlinear": residuals})


def _problem(seed=0):
    rng = np.random.default_rng(seed)
    G = rng.standard_normal((N, D_PAR)) * np.array([1.0, 0.3, 3.0, 0.05])   # badly scaled columns
    # anisotropic noise: large along G's second column, small elsewhere
    q = G[:, 1] / np.linalg.norm(G[:, 1])
    Sigma = 0.2 ** 2 * np.eye(N) + 0.9 ** 2 * np.outer(q, q)
    return rng, G, Sigma


def test_adjusted_covariance_is_the_estimators_sampling_covariance():
    rng, G, Sigma = _problem()
    L = np.linalg.cholesky(Sigma)
    s = 0.25                                      # one scale for every direction: misspecified
    replicates = (L @ rng.standard_normal((N, 20000))).T
    lik = _likelihood(replicates, s)
    widths = np.full(D_PAR, 1e6)                  # a flat prior: no information from the box
    x_true = np.array([1.0, -2.0, 0.5, 3.0])
    adj = curvature_adjustment(lik, -G / s, x_true, widths)
    H = G.T @ G / s ** 2
    cov_adjusted = np.linalg.inv(adj.A.T @ H @ adj.A)
    # Monte Carlo of the least-squares estimate under the true noise (fresh draws)
    y = G @ x_true + (L @ rng.standard_normal((N, 20000))).T
    est = np.linalg.lstsq(G, y.T, rcond=None)[0].T
    cov_mc = np.cov(est.T)
    sd_a, sd_mc = np.sqrt(np.diag(cov_adjusted)), np.sqrt(np.diag(cov_mc))
    assert np.all(np.abs(sd_a / sd_mc - 1) < 0.03), (sd_a, sd_mc)
    corr = lambda C: C / np.sqrt(np.outer(np.diag(C), np.diag(C)))
    assert np.max(np.abs(corr(cov_adjusted) - corr(cov_mc))) < 0.03
    # the unadjusted likelihood is off by much more than that along the noisy direction
    sd_0 = np.sqrt(np.diag(np.linalg.inv(H)))
    assert np.max(sd_mc / sd_0) > 2.0
    assert np.allclose(adj.sd_ratios, sd_a / sd_0, rtol=1e-6)


def test_well_specified_likelihood_is_left_alone():
    rng, G, _ = _problem(1)
    s, K = 0.3, 64
    Q = np.linalg.qr(rng.standard_normal((K, N)))[0][:, :N]      # orthonormal columns
    replicates = np.sqrt(K) * s * Q                                # second moment exactly s^2 I
    adj = curvature_adjustment(_likelihood(replicates, s), -G / s, np.zeros(D_PAR), np.full(D_PAR, 10.0))
    assert np.allclose(adj.A, np.eye(D_PAR), atol=1e-8)
    assert np.allclose(adj.variance_ratios, 1.0, atol=1e-8)


def test_model_error_is_budgeted_isotropically():
    # with the model error dominating s, the noise's anisotropy hardly matters
    rng, G, Sigma = _problem(2)
    L = np.linalg.cholesky(0.01 * Sigma)
    replicates = (L @ rng.standard_normal((N, 4000))).T
    adj = curvature_adjustment(_likelihood(replicates, 1.0, model_error=0.999), -G, np.zeros(D_PAR),
                               np.full(D_PAR, 1e6))
    assert np.all(np.abs(adj.sd_ratios - 1) < 0.02)


def test_no_replicates_no_adjustment_and_not_pickled():
    rng, G, Sigma = _problem(3)
    lik = _likelihood(rng.standard_normal((8, N)), 1.0)
    assert curvature_adjustment(Likelihood(lik.scales), -G, np.zeros(D_PAR), np.ones(D_PAR)) is None
    back = pickle.loads(pickle.dumps(lik))
    assert back.noise_residuals is None and back.scales == lik.scales
    try:
        curvature_adjustment(lik, -G[:-1], np.zeros(D_PAR), np.ones(D_PAR))
    except ValueError as exc:
        assert "rows" in str(exc)
    else:
        raise AssertionError("a Jacobian of the wrong size was accepted")


def test_the_surrogate_posterior_reads_its_gps_at_the_adjusted_points():
    """WhitenedLogPosterior.gp_points folds x(u), the adjustment and u(x) into one
    affine map: the same points as the three maps one after the other."""
    from bayes_update.core.adjustment import CurvatureAdjustment
    from bayes_update.core.posterior.target import Whitening, WhitenedLogPosterior

    rng = np.random.default_rng(41)
    cov = np.cov(rng.normal(size=(3, 20)))
    whitening = Whitening.from_covariance(rng.normal(size=3), cov)
    adj = CurvatureAdjustment(center=rng.normal(size=3), A=np.eye(3) + 0.3 * rng.normal(size=(3, 3)),
                              variance_ratios=np.ones(3), sd_ratios=np.ones(3))
    target = WhitenedLogPosterior({}, None, np.array([[-4.0, 4.0]] * 3), whitening, adj)
    U = rng.normal(size=(50, 3))
    expected = whitening.to_u(adj(whitening.to_x(U)))
    np.testing.assert_allclose(target.gp_points(U), expected, rtol=0, atol=1e-11)
    np.testing.assert_allclose(target.gp_points(U[:1]), expected[:1], rtol=0, atol=1e-11)
