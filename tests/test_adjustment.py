"""The curvature (sandwich) adjustment of the likelihood, on a linear Gaussian
model where the least-squares estimator's sampling covariance is known by
Monte Carlo, independently of the sandwich formula."""

import pickle

import numpy as np

from bayes_update.core.adjustment import curvature_adjustment
from bayes_update.core.likelihood import Likelihood, StageScale

N, D_PAR = 40, 4


def _likelihood(residuals, s, model_error=0.0):
    sc = StageScale(
        "nonlinear",
        float(np.mean(residuals**2) * N),
        float(N),
        model_error,
        N,
        len(residuals),
        span_variance=s**2 - model_error**2,
    )
    return Likelihood({"nonlinear": sc}, {"nonlinear": residuals})


def _problem(seed=0):
    rng = np.random.default_rng(seed)
    G = rng.standard_normal((N, D_PAR)) * np.array([1.0, 0.3, 3.0, 0.05])  # badly scaled columns
    # anisotropic noise: large along G's second column, small elsewhere
    q = G[:, 1] / np.linalg.norm(G[:, 1])
    Sigma = 0.2**2 * np.eye(N) + 0.9**2 * np.outer(q, q)
    return rng, G, Sigma


def test_adjusted_covariance_is_the_estimators_sampling_covariance():
    rng, G, Sigma = _problem()
    L = np.linalg.cholesky(Sigma)
    s = 0.25  # one scale for every direction: misspecified
    replicates = (L @ rng.standard_normal((N, 20000))).T
    lik = _likelihood(replicates, s)
    widths = np.full(D_PAR, 1e6)  # a flat prior: no information from the box
    x_true = np.array([1.0, -2.0, 0.5, 3.0])
    adj = curvature_adjustment(lik, -G / s, x_true, widths)
    H = G.T @ G / s**2
    cov_adjusted = np.linalg.inv(adj.A.T @ H @ adj.A)
    # Monte Carlo of the least-squares estimate under the true noise (fresh draws)
    y = G @ x_true + (L @ rng.standard_normal((N, 20000))).T
    est = np.linalg.lstsq(G, y.T, rcond=None)[0].T
    cov_mc = np.cov(est.T)
    sd_a, sd_mc = np.sqrt(np.diag(cov_adjusted)), np.sqrt(np.diag(cov_mc))
    assert np.all(np.abs(sd_a / sd_mc - 1) < 0.03), (sd_a, sd_mc)

    def corr(C):
        return C / np.sqrt(np.outer(np.diag(C), np.diag(C)))

    assert np.max(np.abs(corr(cov_adjusted) - corr(cov_mc))) < 0.03
    # the unadjusted likelihood is off by much more than that along the noisy direction
    sd_0 = np.sqrt(np.diag(np.linalg.inv(H)))
    assert np.max(sd_mc / sd_0) > 2.0
    assert np.allclose(adj.sd_ratios, sd_a / sd_0, rtol=1e-6)


def test_well_specified_likelihood_is_left_alone():
    rng, G, _ = _problem(1)
    s, K = 0.3, 64
    Q = np.linalg.qr(rng.standard_normal((K, N)))[0][:, :N]  # orthonormal columns
    replicates = np.sqrt(K) * s * Q  # second moment exactly s^2 I
    adj = curvature_adjustment(_likelihood(replicates, s), -G / s, np.zeros(D_PAR), np.full(D_PAR, 10.0))
    assert np.allclose(adj.A, np.eye(D_PAR), atol=1e-8)
    assert np.allclose(adj.variance_ratios, 1.0, atol=1e-8)


def test_model_error_is_budgeted_isotropically():
    # with the model error dominating s, the noise's anisotropy hardly matters
    rng, G, Sigma = _problem(2)
    L = np.linalg.cholesky(0.01 * Sigma)
    replicates = (L @ rng.standard_normal((N, 4000))).T
    adj = curvature_adjustment(
        _likelihood(replicates, 1.0, model_error=0.999), -G, np.zeros(D_PAR), np.full(D_PAR, 1e6)
    )
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
    from bayes_update.core.posterior.target import WhitenedLogPosterior, Whitening

    rng = np.random.default_rng(41)
    cov = np.cov(rng.normal(size=(3, 20)))
    whitening = Whitening.from_covariance(rng.normal(size=3), cov)
    adj = CurvatureAdjustment(
        center=rng.normal(size=3),
        A=np.eye(3) + 0.3 * rng.normal(size=(3, 3)),
        variance_ratios=np.ones(3),
        sd_ratios=np.ones(3),
    )
    target = WhitenedLogPosterior({}, None, np.array([[-4.0, 4.0]] * 3), whitening, adj)
    U = rng.normal(size=(50, 3))
    expected = whitening.to_u(adj(whitening.to_x(U)))
    np.testing.assert_allclose(target.gp_points(U), expected, rtol=0, atol=1e-11)
    np.testing.assert_allclose(target.gp_points(U[:1]), expected[:1], rtol=0, atol=1e-11)


# ---------------------------------------------------------------- tests that disagree
def _two_tests(rng, tau, n=30, sigma=1.0, k=200):
    """A linear Gaussian model seen by two tests whose parameters differ by random
    effects b_k ~ N(0, tau^2 v v^T) (what an effect the model lacks does from one level
    to the next), noise sigma.  Returns the truth, the direction v and a function
    drawing one realisation: (likelihood, jacobian, residual, joint estimate)."""
    d = 3
    G = [
        rng.standard_normal((n, d)) * np.array([1.0, 0.5, 2.0]),
        rng.standard_normal((n, d)) * np.array([0.7, 1.5, 1.0]),
    ]
    theta = np.array([1.0, -0.5, 2.0])
    v = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    scales = {
        st: StageScale(st, n * sigma**2, float(n), 0.0, n, k, span_variance=sigma**2) for st in ("linear", "nonlinear")
    }
    noise = {st: (sigma * rng.standard_normal((k, n)), np.full(k, 1.0 / k)) for st in scales}
    lik = Likelihood(scales, noise)
    Gs = np.vstack(G)

    def realisation():
        y = np.concatenate([g @ (theta + tau * rng.standard_normal() * v) + sigma * rng.standard_normal(n) for g in G])
        est = np.linalg.lstsq(Gs, y, rcond=None)[0]
        return lik, -Gs / sigma, (y - Gs @ est) / sigma, est

    return theta, v, realisation


def test_agreeing_tests_leave_the_adjustment_alone():
    rng = np.random.default_rng(7)
    _, _, realisation = _two_tests(rng, tau=0.0)
    flagged = 0
    for _ in range(200):
        lik, J, r, est = realisation()
        adj = curvature_adjustment(lik, J, est, np.full(3, 1e4), residual=r)
        flagged += adj.between_tests is not None
    # the chi-square test at its 99 % point: about 2 of 200 by chance
    assert flagged <= 8, flagged


def test_disagreeing_tests_widen_the_intervals_to_cover_the_truth():
    rng = np.random.default_rng(8)
    theta, v, realisation = _two_tests(rng, tau=1.5)  # the effect moves v . theta by ~10 noise sd per test
    covered = {"with": 0, "without": 0}
    m, spanned = 300, []
    for _ in range(m):
        lik, J, r, est = realisation()
        H_inv = np.linalg.inv(J.T @ J)
        for key, res in (("with", r), ("without", None)):
            adj = curvature_adjustment(lik, J, est, np.full(3, 1e4), residual=res)
            sd = np.sqrt(v @ adj.covariance(H_inv) @ v)
            covered[key] += abs(v @ (est - theta)) <= 1.645 * sd
            if key == "with" and adj.between_tests:
                # each test's own estimate along v, in sd of the adjusted posterior
                spanned += [abs(v @ np.array(b)) / sd for b in adj.between_tests["offsets"].values()]
    # Two tests estimate the between-test variance from one difference: with equal weights the
    # joint estimate's error over its estimated sd is (b1 + b2) / |b1 - b2|, a Cauchy variable,
    # so the 90 % interval covers 2 / pi atan(1.645) = 65 % of the truths (the noise adds a
    # little); without the term, a fraction of that.  What holds every time the tests are found to
    # disagree (7 in 10 realisations here; else |b1 - b2| was within their noise): the posterior
    # spans both tests' own estimates, each within about one sd of the joint estimate.
    assert covered["with"] / m >= 0.58, covered
    assert covered["without"] / m <= 0.3, covered
    assert len(spanned) >= 2 * 0.6 * m and max(spanned) < 1.6, (len(spanned), max(spanned))
