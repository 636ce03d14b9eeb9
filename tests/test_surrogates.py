"""The surrogates package against independent references: stratification
properties of the designs, a Gaussian-process posterior computed by hand,
Monte Carlo moments, a synthetic valley with an exact posterior, sha256 of a
literal JSON string, and evaluations through another executor."""

import hashlib
import math
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from functools import partial

import numpy as np
import pytest
from scipy.stats import qmc
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel
from threadpoolctl import threadpool_limits

from surrogates import (
    CurvedValley,
    EvaluationCache,
    GPSurrogate,
    cached_evaluate,
    config_hash,
    design,
    holdout_validation,
    propose_points,
    refine,
)
from surrogates.evaluation import default_executor, evaluate_many


@pytest.fixture(autouse=True, scope="module")
def _one_blas_thread():
    # GP matrices here are ~100 x 100: threaded BLAS only fights the other
    # processes of a small machine
    with threadpool_limits(1):
        yield


# -- designs ---------------------------------------------------------------
BOX = [[1.0, 6.0], [0.0, 25.0], [-3.0, -1.0]]


@pytest.mark.parametrize("method", ["sobol", "lhs", "random"])
def test_design_is_seeded_and_in_the_box(method):
    a = design(BOX, 32, method, seed=7)
    assert a.shape == (32, 3)
    np.testing.assert_array_equal(a, design(BOX, 32, method, seed=7))
    assert not np.allclose(a, design(BOX, 32, method, seed=8))
    b = np.array(BOX)
    assert np.all(a >= b[:, 0]) and np.all(a <= b[:, 1])


def test_design_stratification():
    b = np.array(BOX)
    # LHS: each of the n slices of every axis holds exactly one point
    u = (design(BOX, 50, "lhs", seed=1) - b[:, 0]) / (b[:, 1] - b[:, 0])
    for j in range(3):
        np.testing.assert_array_equal(np.sort(np.floor(u[:, j] * 50)), np.arange(50))
    # Sobol' (a (t, m, s)-net, t = 0 in one dimension): 2^m points put one in
    # each of the 2^m slices of every axis
    u = (design(BOX, 64, "sobol", seed=1) - b[:, 0]) / (b[:, 1] - b[:, 0])
    for j in range(3):
        np.testing.assert_array_equal(np.sort(np.floor(u[:, j] * 64)), np.arange(64))
    # and is more uniform than independent points (centred L2 discrepancy)
    r = (design(BOX, 64, "random", seed=1) - b[:, 0]) / (b[:, 1] - b[:, 0])
    assert qmc.discrepancy(u) < 0.5 * qmc.discrepancy(r)


def test_design_rejects_bad_input():
    with pytest.raises(ValueError, match="shape"):
        design([0, 1], 4)
    with pytest.raises(ValueError, match="low < high"):
        design([[0, 1], [2, 2]], 4)
    with pytest.raises(ValueError, match="finite"):
        design([[0, np.inf]], 4)
    with pytest.raises(ValueError, match="positive integer"):
        design([[0, 1]], 0)
    with pytest.raises(ValueError, match="method"):
        design([[0, 1]], 4, method="grid")


# -- Gaussian process ------------------------------------------------------
def _matern52(A, B, ls):
    r = np.sqrt((((A[:, None, :] - B[None, :, :]) / ls) ** 2).sum(-1))
    return (1 + math.sqrt(5) * r + 5 * r**2 / 3) * np.exp(-math.sqrt(5) * r)


def test_gp_reproduces_the_closed_form_posterior():
    """Fixed hyperparameters: mean, sd, interval and back-transform against
    the textbook GP formulas written out here (Rasmussen & Williams eq. 2.25-26)."""
    bounds = np.array([[0.0, 2.0], [10.0, 30.0]])
    X = design(bounds, 12, seed=3)
    y = np.exp(np.sin(2 * X[:, 0]) + 0.05 * X[:, 1])
    Xs = design(bounds, 7, seed=4)
    c, ls, noise = 1.7, np.array([0.4, 0.7]), 1e-4
    kernel = ConstantKernel(c) * Matern(ls, nu=2.5) + WhiteKernel(noise)
    sur = GPSurrogate(bounds, transform="log", kernel=kernel, optimize=False).fit(X, y)

    U, Us = (X - bounds[:, 0]) / [2.0, 20.0], (Xs - bounds[:, 0]) / [2.0, 20.0]  # the unit box
    z = np.log(y)
    m, s = z.mean(), z.std()  # normalize_y standardizes the targets
    K = c * _matern52(U, U, ls) + (noise + 1e-10) * np.eye(len(U))  # 1e-10: sklearn's default alpha
    ks = c * _matern52(Us, U, ls)
    mu = m + s * ks @ np.linalg.solve(K, (z - m) / s)
    var = s**2 * (c + noise - np.einsum("ij,ji->i", ks, np.linalg.solve(K, ks.T)))
    mu_s, sd_s = sur.predict_transformed(Xs)
    np.testing.assert_allclose(mu_s, mu, rtol=0, atol=1e-9)
    np.testing.assert_allclose(sur.mean_transformed(Xs), mu, rtol=0, atol=1e-9)  # the MCMC's fast path
    np.testing.assert_allclose(sd_s, np.sqrt(var), rtol=1e-7)

    pred, sd = sur.predict(Xs)
    np.testing.assert_allclose(pred, np.exp(mu), rtol=1e-9)  # the median
    np.testing.assert_allclose(sd, np.sqrt((np.exp(var) - 1) * np.exp(2 * mu + var)), rtol=1e-6)  # lognormal
    lo, hi = sur.predict_interval(Xs, 0.9)
    np.testing.assert_allclose(lo, np.exp(mu - 1.6448536269514722 * np.sqrt(var)), rtol=1e-7)
    np.testing.assert_allclose(hi, np.exp(mu + 1.6448536269514722 * np.sqrt(var)), rtol=1e-7)
    # interpolation at the training points: the noise is tiny
    np.testing.assert_allclose(sur.predict(X, return_std=False), y, rtol=1e-3)


@pytest.mark.parametrize("nu", [0.5, 1.5, 2.5, np.inf])
def test_plain_numpy_mean_equals_scikit_learns_prediction(nu):
    """mean_transformed's numpy path (surrogates.gp_mean) against scikit-learn's own
    predict, fitted hyperparameters, every smoothness, with and without a prior
    mean; a kernel of another form keeps scikit-learn's path."""
    from sklearn.gaussian_process.kernels import RBF

    from surrogates.gp_mean import kernel_mean

    bounds = np.array([[-1.0, 3.0], [100.0, 400.0], [0.0, 1.0]])
    X = design(bounds, 30, seed=11)
    y = np.cos(X[:, 0]) + 0.004 * X[:, 1] + X[:, 2] ** 2
    Xs = design(bounds, 9, seed=12) * 1.1  # some points outside the box
    for prior_mean in (None, _QuadraticMean()):
        sur = GPSurrogate(bounds, transform="none", nu=nu, n_restarts_optimizer=0, prior_mean=prior_mean).fit(X, y)
        assert kernel_mean(sur) is not None
        gp = sur.gp_
        mu_sklearn = gp.predict(sur.scale_inputs(Xs)) + sur._mean(Xs)
        # both sum k_i alpha_i in floating point: they may differ by rounding of the largest terms
        terms = np.abs(gp.kernel_(sur.scale_inputs(Xs), gp.X_train_)) @ np.abs(gp.alpha_) * gp._y_train_std
        np.testing.assert_array_less(np.abs(sur.mean_transformed(Xs) - mu_sklearn), 1e-14 + 64 * 2.2e-16 * terms)
    other = GPSurrogate(bounds, transform="none", kernel=ConstantKernel() * RBF([0.3] * 3)).fit(X, y)
    assert kernel_mean(other) is None
    np.testing.assert_allclose(other.mean_transformed(Xs), other.predict_transformed(Xs)[0], rtol=0, atol=1e-10)


class _QuadraticMean:
    def __call__(self, X):
        return 0.1 * X[:, 0] ** 2


def test_sqrt_transform_moments_against_monte_carlo():
    bounds = [[0.0, 1.0]]
    X = np.linspace(0, 1, 6)[:, None]
    kernel = ConstantKernel(1.0) * Matern(0.3, nu=2.5) + WhiteKernel(1e-6)
    sur = GPSurrogate(bounds, transform="sqrt", kernel=kernel, optimize=False).fit(X, [0.0, 0.04, 0.3, 1.0, 0.2, 0.01])
    Xs = np.array([[0.05], [0.5], [1.3]])  # 1.3: extrapolation, large sd, mass below 0
    mu, s = sur.predict_transformed(Xs)
    pred, sd = sur.predict(Xs)
    z = np.random.default_rng(0).normal(mu, s, size=(400_000, 3))
    y = np.maximum(z, 0) ** 2
    np.testing.assert_allclose(pred, np.median(y, axis=0), rtol=0.02, atol=1e-4)
    np.testing.assert_allclose(sd, y.std(axis=0), rtol=0.01)


def _log_smooth(X):
    """Positive, spans ~3 decades, smooth in log; the third input is inert."""
    X = np.atleast_2d(X)
    return 1e-3 * np.exp(2 * X[:, 0] ** 2 - 1.5 * X[:, 0] * X[:, 1] + 2 * np.sin(2 * X[:, 1]))


def test_gp_fit_holdout_and_summary():
    bounds = np.array([[-1.0, 1.0], [-1.0, 1.5], [0.0, 100.0]])
    X = design(bounds, 96, seed=0)
    y = _log_smooth(X)
    assert y.max() / y.min() > 300
    factory = partial(GPSurrogate, bounds, names=["a", "b", "inert"], n_restarts_optimizer=2, seed=1)
    out = holdout_validation(factory, X, y, fraction=0.25, seed=0)
    print("holdout (log):", {k: out[k] for k in ("n_train", "n_test", "median_rel_error", "max_rel_error", "coverage")})
    assert (out["n_train"], out["n_test"]) == (72, 24)
    assert out["median_rel_error"] < 0.02
    assert out["max_rel_error"] < 0.3
    assert out["coverage"] >= 0.85
    sur = out["surrogate"]
    hp = sur.hyperparameters()
    # the inert input gets a long length scale (in unit-box units)
    assert hp["length_scales_unit"][2] > 5 * max(hp["length_scales_unit"][:2])
    np.testing.assert_allclose(hp["length_scales"], hp["length_scales_unit"] * [2.0, 2.5, 100.0])
    text = sur.summary()
    assert "inert" in text and "transform='log'" in text and "72 training points" in text
    assert repr(sur) == "GPSurrogate(transform='log', names=['a', 'b', 'inert'], n_train=72)"
    # the log transform against none on the same split: for a function smooth
    # in log, modelling it in its own units costs accuracy at the small values
    lin = holdout_validation(
        partial(GPSurrogate, bounds, transform="none", n_restarts_optimizer=2, seed=1), X, y, fraction=0.25, seed=0
    )
    print("holdout (none):", {k: lin[k] for k in ("median_rel_error", "max_rel_error", "coverage")})
    assert out["median_rel_error"] < lin["median_rel_error"]
    # same seed and data: the same fit
    again = factory().fit(X, y)
    np.testing.assert_array_equal(again.predict(X[:5])[0], factory().fit(X, y).predict(X[:5])[0])


def test_gp_rejects_bad_input():
    X = design([[0, 1], [0, 1]], 10, seed=0)
    with pytest.raises(ValueError, match="y > 0"):
        GPSurrogate([[0, 1], [0, 1]]).fit(X, np.linspace(-1, 1, 10))
    with pytest.raises(ValueError, match="non-finite"):
        GPSurrogate([[0, 1], [0, 1]]).fit(X, np.r_[np.ones(9), np.nan])
    with pytest.raises(ValueError, match="columns"):
        GPSurrogate([[0, 1], [0, 1]]).fit(X[:, :1], np.ones(10))
    with pytest.raises(ValueError, match="transform"):
        GPSurrogate(transform="exp")
    with pytest.raises(RuntimeError, match="not fitted"):
        GPSurrogate([[0, 1]]).predict([[0.5]])
    with pytest.raises(ValueError, match="constant"):
        GPSurrogate().fit(np.c_[X[:, 0], np.zeros(10)], np.ones(10))
    sur = GPSurrogate(transform="none", n_restarts_optimizer=0).fit(X, X.sum(1))
    np.testing.assert_array_equal(sur.bounds_, np.c_[X.min(0), X.max(0)])  # no bounds: the data's range
    with pytest.raises(ValueError, match="columns"):
        sur.predict(np.ones((2, 3)))


# -- refinement ------------------------------------------------------------
def test_propose_points_where_weight_and_sd_are_high():
    bounds = [[0.0, 1.0], [0.0, 1.0]]
    X = design(bounds, 16, seed=0)
    f = lambda P: 1 + np.sin(3 * P[:, 0]) * np.cos(2 * P[:, 1])  # noqa: E731
    sur = GPSurrogate(bounds, n_restarts_optimizer=0).fit(X, f(X))
    inside = lambda P: np.all((P > 0.4) & (P < 0.7), axis=1).astype(float)  # noqa: E731
    P = propose_points(sur, 2048, inside, 6, seed=1, min_distance=0.05)
    np.testing.assert_array_equal(P, propose_points(sur, 2048, inside, 6, seed=1, min_distance=0.05))
    assert P.shape == (6, 2) and np.all(inside(P) == 1)
    dist = lambda A, B: np.sqrt(((A[:, None] - B[None]) ** 2).sum(-1))  # noqa: E731
    assert np.min(dist(P, X)) >= 0.05
    assert np.min(dist(P, P) + np.eye(6)) >= 0.05
    # the first pick maximizes the sd in the region (weight is flat there)
    C = design(bounds, 2048, seed=1)
    C = C[inside(C) == 1]
    C = C[np.min(dist(C, X), axis=1) >= 0.05]
    _, sd = sur.predict_transformed(C)
    np.testing.assert_array_equal(P[0], C[np.argmax(sd)])
    # with a flat weight, a batch fills the box: sd-driven picks with the
    # kriging-believer update spread much wider than the minimum distance
    Q = propose_points(sur, 2048, lambda P: np.ones(len(P)), 8, seed=1, min_distance=0.01)
    print(f"flat weight: smallest distance within a batch of 8: {np.min(dist(Q, Q) + np.eye(8)):.3f}")
    assert np.min(dist(Q, Q) + np.eye(8)) > 0.1
    # log weights, candidates given explicitly
    R = propose_points(sur, C, lambda P: np.where(inside(P) > 0, 0.0, -np.inf), 3, log_weight=True, min_distance=0.05)
    np.testing.assert_array_equal(R, P[:3])
    with pytest.raises(ValueError, match="positive weight"):
        propose_points(sur, 256, lambda P: np.zeros(len(P)), 2, seed=0)
    with pytest.raises(ValueError, match="non-negative"):
        propose_points(sur, 256, lambda P: -np.ones(len(P)), 2, seed=0)
    with pytest.warns(UserWarning, match="only"):
        assert len(propose_points(sur, 256, inside, 50, seed=0, min_distance=0.1)) < 50


def test_batch_variance_update_is_exact_gp_conditioning():
    """The kriging-believer update of propose_points against refitting the GP
    (same hyperparameters) with the picked points added: the posterior
    variance of a GP does not depend on the values observed."""
    from surrogates.proposal import _ConditionalVariance

    bounds = [[0.0, 1.0], [0.0, 2.0]]
    X = design(bounds, 10, seed=0)
    f = lambda P: np.exp(P[:, 0] - P[:, 1] ** 2)  # noqa: E731
    # fixed hyperparameters with a 1e-4 nugget: a well-conditioned kernel
    # matrix, so that round-off does not blur the comparison (with a 1e-10
    # nugget the two agree to ~2e-12 in absolute terms, the cancellation
    # error of variances computed as differences of O(1) terms)
    kernel = ConstantKernel(1.0) * Matern([0.3, 0.5], nu=2.5) + WhiteKernel(1e-4)
    sur = GPSurrogate(bounds, kernel=kernel, optimize=False).fit(X, f(X))
    C = design(bounds, 64, seed=5)
    cond = _ConditionalVariance(sur, C)
    for j in (3, 17):
        cond.add(j)
    X2 = np.vstack([X, C[[3, 17]]])
    z2 = np.log(f(X2)) + np.r_[np.zeros(10), 0.3, -2.0]  # any values: the variance ignores them
    ref = GPSurrogate(bounds, kernel=sur.gp_.kernel_, optimize=False).fit(X2, np.exp(z2))
    _, sd = ref.predict_transformed(C)
    np.testing.assert_allclose(cond.var, (sd / z2.std()) ** 2, rtol=1e-6, atol=1e-12)


def test_several_outputs():
    bounds = [[0.0, 1.0], [0.0, 1.0]]
    X = design(bounds, 12, seed=0)
    f = lambda P: np.exp(np.sin(3 * P[:, 0]) + P[:, 1])  # noqa: E731
    one = GPSurrogate(bounds, n_restarts_optimizer=0).fit(X, f(X))
    w = lambda P: np.exp(-((P - 0.5) ** 2).sum(1) / 0.1)  # noqa: E731
    # two identical outputs: the summed variance ranks the candidates as one does
    np.testing.assert_array_equal(propose_points([one, one], 512, w, 5, seed=2), propose_points(one, 512, w, 5, seed=2))

    def two(x):
        return {"a": float(f(x[None])[0]), "b": float(1 + x[0])}

    seen = []

    def weight_from(surs):
        seen.append(len(surs))
        return lambda P: w(P) * surs[1].predict(P, return_std=False)

    res = refine(
        two,
        partial(GPSurrogate, bounds, n_restarts_optimizer=0),
        X,
        np.c_[f(X), 1 + X[:, 0]],
        weight_from,
        n_rounds=2,
        batch=3,
        seed=0,
        target=lambda r: (r["a"], r["b"]),
        progress=False,
    )
    assert res.y.shape == (18, 2) and seen == [2, 2] and len(res.surrogate) == 2
    np.testing.assert_allclose(res.y, np.c_[f(res.X), 1 + res.X[:, 0]])


def test_refinement_beats_a_one_shot_design_in_a_thin_curved_valley():
    """Valley 1/50 of the box wide, 2 inputs, N = 128 runs either way: a
    one-shot Sobol' design against 32 Sobol' points + 6 refinement rounds of
    16; the error is measured where the posterior has its mass (500 exact
    posterior draws)."""
    prob = CurvedValley(d=2, width=0.02)
    T = prob.sample_posterior(500, seed=12345)
    yT = prob.values(T)

    def factory():
        return GPSurrogate(prob.bounds, n_restarts_optimizer=2, seed=0)

    def median_error(sur):
        return np.median(np.abs(sur.predict(T, return_std=False) - yT) / yT)

    X = design(prob.bounds, 128, seed=0)
    one_shot = median_error(factory().fit(X, prob.values(X)))

    def weight_from(sur):  # the log posterior density on the surrogate
        return lambda P: -0.5 * (sur.predict(P, return_std=False) / prob.floor - 1)

    X0 = design(prob.bounds, 32, seed=0)
    res = refine(
        prob,
        factory,
        X0,
        prob.values(X0),
        weight_from,
        n_rounds=6,
        batch=16,
        executor=None,
        seed=0,
        log_weight=True,
        progress=False,
    )
    assert len(res.X) == 128 and [r["n_train"] for r in res.rounds] == list(range(32, 129, 16))
    np.testing.assert_array_equal(res.X[:32], X0)
    np.testing.assert_array_equal(res.y, prob.values(res.X))
    refined = median_error(res.surrogate)
    errors = [median_error(r["surrogate"]) for r in res.rounds]
    # where the new points went: within 3 widths of the valley floor
    in_valley = np.abs(res.X[32:, 1] - prob.curve(res.X[32:, 0])) < 3 * prob.width
    print(
        f"one-shot {one_shot:.4f}, refined {refined:.4f}, factor {one_shot / refined:.2f}; "
        f"per round {np.round(errors, 4).tolist()}; new points in the valley {in_valley.mean():.2f}"
    )
    assert one_shot > 0.3  # the one-shot surrogate is poor where it matters
    assert refined < 0.15
    assert one_shot / refined > 4.0
    assert in_valley.mean() > 0.5


def test_warm_started_rounds_end_in_a_full_fit_and_refine_as_well():
    """warm_start: the rounds' GPs start from the last round's hyperparameters without
    restarts; the final surrogate is the factory's own fit on all the points (equal to a
    fit made afresh), and it describes the valley as well as the cold refinement's."""
    prob = CurvedValley(d=2, width=0.02)
    T = prob.sample_posterior(500, seed=54321)
    yT = prob.values(T)

    def factory():
        return GPSurrogate(prob.bounds, n_restarts_optimizer=2, seed=0)

    def weight_from(sur):
        return lambda P: -0.5 * (sur.predict(P, return_std=False) / prob.floor - 1)

    X0 = design(prob.bounds, 32, seed=1)
    kw = dict(n_rounds=6, batch=16, executor=None, seed=1, log_weight=True, progress=False)
    warm = refine(prob, factory, X0, prob.values(X0), weight_from, warm_start=True, **kw)
    cold = refine(prob, factory, X0, prob.values(X0), weight_from, **kw)
    assert warm.rounds[1]["surrogate"].n_restarts_optimizer == 0  # a round: warm, no restarts
    assert warm.surrogate.n_restarts_optimizer == 2  # the end: the factory's fit
    fresh = factory().fit(warm.X, warm.y)
    np.testing.assert_allclose(
        warm.surrogate.predict(T, return_std=False), fresh.predict(T, return_std=False), rtol=1e-10, atol=0
    )
    err = {
        k: float(np.median(np.abs(r.surrogate.predict(T, return_std=False) - yT) / yT))
        for k, r in (("warm", warm), ("cold", cold))
    }
    print(err)
    assert err["warm"] < 0.15 and err["warm"] < 2 * err["cold"]


def _flaky(x):
    # NaN (a "failed run") in one corner
    return math.nan if x[0] > 0.9 and x[1] > 0.9 else float(1 + x[0] ** 2 + x[1])


def test_refine_through_an_executor_with_failed_runs_and_a_cache(tmp_path):
    bounds = [[0.0, 1.0], [0.0, 1.0]]
    X0 = np.vstack([design(bounds, 12, seed=0), [[0.95, 0.95]]])
    y0 = np.array([_flaky(x) for x in X0])
    cache = EvaluationCache(tmp_path, {"f": "flaky"})

    def as_dict(x):
        return {"v": _flaky(x)}

    # the corner is where the weight is: proposals land there, some fail
    corner = lambda s: lambda P: np.exp(10 * (P[:, 0] + P[:, 1]))  # noqa: E731
    with ThreadPoolExecutor(2) as ex:
        res = refine(
            as_dict,
            partial(GPSurrogate, bounds, n_restarts_optimizer=0),
            X0,
            y0,
            corner,
            n_rounds=2,
            batch=4,
            executor=ex,
            seed=3,
            target=lambda r: r["v"],
            evaluate=partial(cached_evaluate, cache=cache),
            progress=False,
        )
    assert len(res.X) == 21 and len(cache) == 8
    failed = ~np.isfinite(res.y)
    assert failed.sum() > 1
    assert res.rounds[-1]["n_failed"] == failed.sum() and res.rounds[-1]["n_train"] == 21 - failed.sum()
    for x, v in zip(res.X[13:], res.y[13:]):
        assert cache.get(x)["v"] == v or (math.isnan(v) and math.isnan(cache.get(x)["v"]))


def _slow_bowl(x):
    time.sleep(0.02)
    return float(np.sum((np.asarray(x) - 0.5) ** 2))


def test_refine_splits_its_wall_time_into_fits_runs_checks_and_proposals():
    """The model runs' time is counted as runs, not as the surrogates' fits (a design's
    "GP fit" time once held its runs and checks too): a function that sleeps 20 ms a point
    gives at least that much per point to ``runs``, and the parts sum to at most the wall time."""
    bounds = [[0.0, 1.0], [0.0, 1.0]]
    X0 = design(bounds, 8, seed=0)
    y0 = np.array([float(np.sum((x - 0.5) ** 2)) for x in X0])
    t0 = time.perf_counter()
    res = refine(
        _slow_bowl,
        partial(GPSurrogate, bounds, n_restarts_optimizer=0),
        X0,
        y0,
        lambda s: lambda P: np.ones(len(P)),
        n_rounds=3,
        batch=4,
        seed=1,
        progress=False,
        until=lambda sur, rounds: False,
    )
    wall = time.perf_counter() - t0
    assert set(res.seconds) == {"fit", "runs", "until", "propose"}
    assert res.seconds["runs"] >= 0.02 * 12 and res.seconds["fit"] > 0
    assert sum(res.seconds.values()) <= wall


# -- cache -----------------------------------------------------------------
def test_config_hash_is_canonical_and_stable():
    cfg = {"model": {"n_elements": 10, "substeps": 4}, "stages": ["linear", "nonlinear"], "tol": 1e-8}
    literal = '{"model":{"n_elements":10,"substeps":4},"stages":["linear","nonlinear"],"tol":1e-08}'
    assert config_hash(cfg) == hashlib.sha256(literal.encode()).hexdigest()
    reordered = {"tol": 1e-8, "stages": ("linear", "nonlinear"), "model": {"substeps": np.int64(4), "n_elements": 10}}
    assert config_hash(reordered) == config_hash(cfg)
    assert config_hash({**cfg, "tol": 1e-7}) != config_hash(cfg)
    with pytest.raises(TypeError, match="JSON-like"):
        config_hash({"f": object()})
    with pytest.raises(TypeError, match="keys"):
        config_hash({1: 2})


class _Counting:
    """Records the points it is called on; raises once it has run ``fail_after`` points."""

    def __init__(self, fail_after=None):
        self.calls, self.fail_after = [], fail_after

    def __call__(self, x):
        if self.fail_after is not None and len(self.calls) >= self.fail_after:
            raise RuntimeError("simulated crash")
        self.calls.append(np.array(x))
        if x[0] > 0.8:  # a model failure that returns (cached like any result)
            return {"e_lin": math.nan, "e_nlin": math.nan, "error": "BucklingError: beyond buckling"}
        return {"e_lin": float(np.sum(x**2)), "e_nlin": float(np.prod(x)), "error": None}


def _same(a, b):
    return a.keys() == b.keys() and all(
        a[k] == b[k] or (isinstance(a[k], float) and math.isnan(a[k]) and math.isnan(b[k])) for k in a
    )


def test_cache_resumes_an_interrupted_doe(tmp_path):
    cfg = {"model": "beam", "n_elements": 10}
    X = design([[0, 1], [0, 1], [0, 1]], 20, seed=0)
    X = np.vstack([X, X[3]])  # a duplicate point runs once
    clean = cached_evaluate(_Counting(), X, EvaluationCache(tmp_path / "clean", cfg), progress=False)
    assert any(r["error"] for r in clean) and len(clean) == 21

    crashing = _Counting(fail_after=11)
    with pytest.raises(RuntimeError, match="simulated crash"):
        cached_evaluate(crashing, X, EvaluationCache(tmp_path / "run", cfg), chunk_size=4, progress=False)
    cache = EvaluationCache(tmp_path / "run", cfg)  # a new process would reopen it
    assert len(cache) == 8  # two chunks of 4 saved; the third, interrupted, lost
    resumed = _Counting()
    out = cached_evaluate(resumed, X, cache, chunk_size=4, progress=False)
    np.testing.assert_array_equal(np.array(resumed.calls), X[8:20])  # only the missing points
    assert all(_same(a, b) for a, b in zip(out, clean))
    # a direct run gives the same
    assert all(_same(a, _Counting()(x)) for a, x in zip(out, X))
    # and a third call runs nothing
    again = _Counting()
    cached_evaluate(again, X, EvaluationCache(tmp_path / "run", cfg), progress=False)
    assert again.calls == []


def test_cache_never_mixes_configurations(tmp_path):
    X = design([[0, 1], [0, 1]], 6, seed=1)
    a = cached_evaluate(_Counting(), X, EvaluationCache(tmp_path, {"k_s": 1.0}), progress=False)
    other = _Counting()
    b = cached_evaluate(other, X, EvaluationCache(tmp_path, {"k_s": 2.0}), progress=False)
    assert len(other.calls) == 6 and all(_same(p, q) for p, q in zip(a, b))
    assert len(list(tmp_path.glob("*.nc"))) == 2
    with_threads = _Counting()
    with ThreadPoolExecutor(2) as ex:
        c = cached_evaluate(
            with_threads, np.vstack([X, [[0.5, 0.5]]]), EvaluationCache(tmp_path, {"k_s": 1.0}), ex, progress=False
        )
    assert len(with_threads.calls) == 1 and all(_same(p, q) for p, q in zip(a, c))
    # a file that claims this configuration's name but holds another: refused
    cache = EvaluationCache(tmp_path, {"k_s": 1.0})
    cache.file.replace(tmp_path / "moved.nc")
    EvaluationCache(tmp_path, {"k_s": 2.0}).file.replace(cache.file)
    with pytest.raises(ValueError, match="another configuration"):
        EvaluationCache(tmp_path, {"k_s": 1.0})


def test_cache_rejects_inconsistent_results(tmp_path):
    cache = EvaluationCache(tmp_path, {"c": 1})
    cache.add([[0.0, 1.0]], [{"a": 1.0, "error": None}])
    cache.add([[0.25, 1.0]], [{"error": None, "a": 2.0}])  # key order does not matter
    assert cache.get([0.25, 1.0]) == {"a": 2.0, "error": None}
    with pytest.raises(ValueError, match="same keys"):
        cache.add([[0.5, 1.0]], [{"b": 1.0, "error": None}])
    with pytest.raises(TypeError, match="real number"):
        cache.add([[0.5, 1.0]], [{"a": "x", "error": None}])
    with pytest.raises(ValueError, match="coordinates"):
        cache.add([[0.5, 1.0, 2.0]], [{"a": 1.0, "error": None}])
    with pytest.raises(ValueError, match="reserved"):
        EvaluationCache(tmp_path, {"c": 2}).add([[0.0]], [{"x": 1.0}])
    # -0.0 and 0.0 are one point
    assert cache.get([-0.0, 1.0]) == {"a": 1.0, "error": None}
    ds = cache.to_dataset()
    assert ds.attrs["config"] == '{"c":1}' and ds["x"].shape == (2, 2)
    assert cached_evaluate(_Counting(), np.empty((0, 2)), cache, progress=False) == []


# -- Dask ------------------------------------------------------------------
def test_dask_executor_gives_the_process_pool_results():
    distributed = pytest.importorskip("distributed")
    func = CurvedValley(d=3)  # picklable by reference
    X = design(func.bounds, 8, seed=2)
    with default_executor(2) as pool:
        expected = evaluate_many(func, list(X), pool, progress=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # dask's notes about ports and sizes
        with (
            distributed.LocalCluster(
                n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
            ) as cluster,
            distributed.Client(cluster) as client,
        ):
            got = evaluate_many(func, list(X), client.get_executor(), batch_size=2, progress=False)
    assert got == expected
    np.testing.assert_array_equal(got, func.values(X))


def _two_outputs(x):
    return np.array([1 + x[0] ** 2 + x[1], np.exp(-x[0]) + 0.5 * x[1] ** 2])


def test_parallel_fits_in_the_workers_give_the_same_surrogates():
    """parallel_fits: the outputs' GPs fitted in the executor's worker processes are the
    sequential fits (the same seeded optimisations): predictions equal to round-off."""
    from concurrent.futures import ProcessPoolExecutor

    bounds = [[0.0, 1.0], [0.0, 1.0]]
    X0 = design(bounds, 16, seed=3)
    y0 = np.array([_two_outputs(x) for x in X0])

    def factory():
        return GPSurrogate(bounds, n_restarts_optimizer=2, seed=0)

    def weight_from(surs):
        return lambda P: -sum(s.predict(P, return_std=False) for s in surs)

    kw = dict(n_rounds=2, batch=4, seed=2, log_weight=True, progress=False, target=lambda r: r, warm_start=True)
    with ProcessPoolExecutor(2) as pool:
        par = refine(_two_outputs, factory, X0, y0, weight_from, executor=pool, parallel_fits=True, **kw)
    seq = refine(_two_outputs, factory, X0, y0, weight_from, executor=None, **kw)
    P = design(bounds, 50, seed=9)
    np.testing.assert_array_equal(par.X, seq.X)
    for a, b in zip(par.surrogate, seq.surrogate):
        np.testing.assert_allclose(a.predict(P, return_std=False), b.predict(P, return_std=False), rtol=1e-12, atol=0)


class _Quadratic:
    """A picklable prior mean m(x) = a (x0 - 0.3)^2 (the GP's fits run in worker processes)."""

    def __init__(self, a):
        self.a = a

    def __call__(self, X):
        return self.a * (np.atleast_2d(X)[:, 0] - 0.3) ** 2


def test_a_prior_mean_is_what_the_gp_falls_back_on_away_from_its_points():
    """y = 40 (x - 0.3)^2 + 0.05 sin(6 x) on 7 points of [0, 0.6]: with the quadratic as its
    prior mean the GP models the small sine and predicts y on [0, 1] to about its amplitude;
    with a constant mean it misses the extrapolated part by far more.  The prior mean
    survives warm_from and the worker processes' pickling."""
    import pickle

    from surrogates import GPSurrogate

    def f(x):
        return 40.0 * (x[:, 0] - 0.3) ** 2 + 0.05 * np.sin(6.0 * x[:, 0])

    X = np.linspace(0.0, 0.6, 7)[:, None]
    Xt = np.linspace(0.0, 1.0, 101)[:, None]
    box = [[0.0, 1.0]]
    with_mean = GPSurrogate(box, transform="none", prior_mean=_Quadratic(40.0), seed=0).fit(X, f(X))
    constant = GPSurrogate(box, transform="none", seed=0).fit(X, f(X))
    err_mean = np.max(np.abs(with_mean.mean_transformed(Xt) - f(Xt)))
    err_const = np.max(np.abs(constant.mean_transformed(Xt) - f(Xt)))
    assert err_mean < 0.15 and err_const > 10 * err_mean, (err_mean, err_const)
    mu, _ = with_mean.predict_transformed(Xt)
    np.testing.assert_allclose(mu, with_mean.mean_transformed(Xt), rtol=0, atol=1e-9)
    warm = GPSurrogate(box, transform="none", prior_mean=_Quadratic(40.0), seed=0).warm_from(with_mean)
    again = pickle.loads(pickle.dumps(warm)).fit(X, f(X))
    np.testing.assert_allclose(again.mean_transformed(Xt), with_mean.mean_transformed(Xt), rtol=0, atol=1e-6)
    with pytest.raises(TypeError):
        GPSurrogate(box, prior_mean=3.0)


def test_executor_for_owns_only_the_pool_it_makes():
    from concurrent.futures import ThreadPoolExecutor

    from surrogates.evaluation import executor_for

    given = ThreadPoolExecutor(1)
    with executor_for(given, workers=4) as pool:
        assert pool is given
    assert given.submit(abs, -1).result() == 1  # the caller's pool is left running
    given.shutdown()
    with executor_for(None, workers=1) as pool:
        assert pool is None  # one worker: every run in this process
    with executor_for(None, workers=2) as pool:
        assert pool.submit(abs, -2).result() == 2
    with pytest.raises(RuntimeError):  # its own pool is shut down when the block ends
        pool.submit(abs, -3)
