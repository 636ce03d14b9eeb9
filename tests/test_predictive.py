"""The pieces of the honest predictive and of the pointwise log-likelihood, against
closed forms: the bands' coverage of records drawn from the predictive itself, the
model-form error's power law in the level, and the observations' basis."""

import math
from dataclasses import dataclass

import numpy as np
import pytest

from bayes_update.core.error_model import carried_error
from bayes_update.core.posterior.predictive import band_coverage


def test_a_record_drawn_from_the_predictive_is_covered_at_the_nominal_rates():
    rng = np.random.default_rng(0)
    m, n, tau, sigma = 200, 20000, 0.7, 0.4
    Y = tau * rng.standard_normal((m, n))  # the model at m draws (parameter uncertainty)
    y = math.hypot(tau, sigma) * rng.standard_normal(n)  # a record: the same spread plus its errors
    cov = band_coverage(Y, y, sigma)
    assert cov["50"] == pytest.approx(0.50, abs=0.015) and cov["90"] == pytest.approx(0.90, abs=0.01), cov
    # a record twice as far off as the bands say is covered far less
    wide = band_coverage(Y, 2.0 * y, sigma)
    assert wide["90"] < 0.65 and wide["50"] < 0.3, wide


def test_the_model_form_error_is_carried_in_level_by_a_flat_and_a_growing_part():
    # (level, share of the rms, rms) of the estimation tests, one sensor
    low, high = (1.0, np.array([0.01]), np.array([1.0])), (10.0, np.array([0.1]), np.array([10.0]))
    flat, share, how = carried_error(10**0.5, [low, high])
    assert flat[0] == pytest.approx(0.01)  # the lowest test's excess, absolute
    growing = math.sqrt(1.0 - 0.01**2) / 10.0  # the high test's beyond it, relative
    r = 10**0.5 / 10.0  # one growing point: p uniform in [0, 2]
    mean_power = (r**4 - 1.0) / (4.0 * math.log(r))  # mean of r^(2p)
    assert share[0] == pytest.approx(growing * math.sqrt(mean_power), rel=1e-12)
    assert how.startswith("interpolated")
    # two tests with a growing part: its exponent fitted (here p = 2), held within [0, 2]
    tests = [
        (1.0, np.array([0.001]), np.array([1.0])),
        (2.0, np.array([math.hypot(0.001, 0.04) / 2.0]), np.array([2.0])),
        (4.0, np.array([math.hypot(0.001, 0.32) / 4.0]), np.array([4.0])),
    ]
    flat, share, how = carried_error(8.0, tests)
    assert flat[0] == pytest.approx(0.001) and share[0] == pytest.approx(0.08 * 2.0**2, rel=1e-9)
    assert how.startswith("extrapolated")
    assert carried_error(3.0, tests)[1][0] == pytest.approx(0.02 * 1.5**2, rel=1e-9)
    # no test beyond the noise: nothing carried
    none = carried_error(5.0, [(1.0, np.zeros(1), np.ones(1)), (9.0, np.zeros(1), np.ones(1))])
    assert none[0][0] == 0.0 and none[1][0] == 0.0


@pytest.fixture(scope="module")
def spring_problem():
    from new_user_kit import Spring, make_dataset

    from bayes_update.core.problem import Problem

    return Problem(make_dataset(), Spring(), metrics="full")


def test_the_observations_are_an_orthonormal_basis_of_the_compared_output(spring_problem):
    from bayes_update.core.posterior.pointwise import observation_basis

    p = spring_problem
    rng = np.random.default_rng(3)
    for stage in p.stages:
        Q = observation_basis(p, stage)
        assert np.allclose(Q.T @ Q, np.eye(Q.shape[1]), atol=1e-10)
        assert Q.shape[1] == p.n_regressors(stage)
        out = p.output(stage, p.components(stage, rng.standard_normal(p.tests[stage].force.size)))
        assert np.linalg.norm(out - Q @ (Q.T @ out)) < 1e-9 * np.linalg.norm(out)


def test_pointwise_values_sum_to_the_stages_log_likelihood(spring_problem):
    from bayes_update.core.likelihood import Likelihood, StageScale
    from bayes_update.core.posterior.pointwise import observation_basis, pointwise_log_likelihood

    p = spring_problem
    rng = np.random.default_rng(4)
    scales = {
        st: StageScale(st, 1.0, 1.0, 0.0, p.n_regressors(st), 16, span_variance=(0.01 + 0.01 * i) ** 2)
        for i, st in enumerate(p.stages)
    }
    lik = Likelihood(scales)
    rows, jac = [], []
    for st in p.stages:
        Q = observation_basis(p, st)
        rows.append(Q @ rng.standard_normal(Q.shape[1]))  # a residual in the output's space
        jac.append(Q @ rng.standard_normal((Q.shape[1], 3)))

    @dataclass
    class Mode:
        x: np.ndarray
        residual: np.ndarray
        jacobian: np.ndarray

    mode = Mode(np.zeros(3), np.concatenate(rows), np.vstack(jac))
    X = rng.standard_normal((5, 3))
    pw = pointwise_log_likelihood(p, lik, mode, X)
    for st, r, J in zip(p.stages, rows, jac):
        ref_norm = np.linalg.norm(p.output(st, p.reference_components(st)))
        norm = -math.log(scales[st].sd * ref_norm) - 0.5 * math.log(2 * math.pi)
        expected = -0.5 * np.sum((r[None] + X @ J.T) ** 2, axis=1) + pw[st].shape[1] * norm
        np.testing.assert_allclose(pw[st].astype(float).sum(axis=1), expected, rtol=1e-5)
