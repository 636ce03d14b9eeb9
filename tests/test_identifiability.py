"""bayes_update.core.identifiability against closed forms."""

import numpy as np

from bayes_update.core.identifiability import gauss_newton_covariance, parameter_sd, unidentified_directions
from bayes_update.core.parameters import Parameter, ParameterSet


def test_a_ridge_is_the_one_unidentified_direction_with_its_sd():
    """J = [a, a] (two parameters that only move the residual through their sum,
    prior ranges w1, w2): in prior-range units J w = [a w1, a w2], singular values
    |a| sqrt(w1^2 + w2^2) along (w1, w2) and 0 across it; with |a| small the
    direction (w2, -w1) / norm is unidentified with sd/range 1/0 = inf, and a
    third, well-pinned parameter is not."""
    w = np.array([2.0, 0.5, 1.0])
    J = np.zeros((5, 3))
    J[:, 0] = J[:, 1] = 0.3 * np.arange(1, 6) / np.sqrt(55.0)  # column norm 0.3
    J[:, 2] = 40.0 * np.array([2, -1, 0, 0, 0]) / np.sqrt(5.0)  # column norm 40, orthogonal to the others
    out = unidentified_directions(J, w, ["a", "b", "c"])
    assert len(out) == 2  # the ridge and the sum's weak direction
    along = np.array([w[0], w[1], 0.0]) / np.hypot(w[0], w[1])
    across = np.array([w[1], -w[0], 0.0]) / np.hypot(w[0], w[1])
    got = [np.array([d["direction"][n] for n in "abc"]) for d in out]
    sds = sorted(d["sd_over_range"] for d in out)
    # the sum: singular value 0.3 * |(w1, w2)|; the difference: 0 (sd infinite)
    np.testing.assert_allclose(sds[0], 1.0 / (0.3 * np.hypot(w[0], w[1])), rtol=1e-9)
    assert np.isinf(sds[1]) or sds[1] > 1e12
    assert any(abs(abs(g @ along) - 1) < 1e-4 for g in got) and any(abs(abs(g @ across) - 1) < 1e-4 for g in got)
    # rows in other units: scaling them by 100 pins the sum (singular value 90 > 2)
    assert len(unidentified_directions(J, w, ["a", "b", "c"], rows_to_noise=np.full(5, 100.0))) == 1


def test_the_gauss_newton_covariance_is_the_inverse_of_jtj_and_wide_where_nothing_pins():
    """(J^T J)^-1 where J has full rank, whatever the units (inverted in range units);
    a column of zeros (a parameter no output moves) comes out wide (sd above 10^4
    ranges), not of zero width as a pseudo-inverse would make it."""
    rng = np.random.default_rng(5)
    J = rng.normal(size=(12, 3)) * np.array([1e-2, 1.0, 1e2])
    widths = np.array([10.0, 1.0, 0.01])
    np.testing.assert_allclose(gauss_newton_covariance(J, widths), np.linalg.inv(J.T @ J), rtol=1e-9)
    J[:, 1] = 0.0
    cov = gauss_newton_covariance(J, widths)
    assert np.sqrt(cov[1, 1]) > 1e4 * widths[1]
    keep = [0, 2]
    np.testing.assert_allclose(cov[np.ix_(keep, keep)], np.linalg.inv(J[:, keep].T @ J[:, keep]), rtol=1e-6)


def test_parameter_sds_through_a_log_coordinate_are_the_delta_method():
    """A log-scale parameter: sd(theta) = theta sd(log theta); a linear one: its own sd."""
    space = ParameterSet([Parameter("k", 10.0, 1000.0, log=True), Parameter("m", 0.5, 2.0)])
    x = np.array([np.log(200.0), 1.2])
    cov = np.array([[0.01**2, 0.0], [0.0, 0.05**2]])
    sd = parameter_sd(space, x, cov)
    np.testing.assert_allclose(sd["k"], 200.0 * 0.01, rtol=1e-6)
    np.testing.assert_allclose(sd["m"], 0.05, rtol=1e-9)
