"""The model at twice the sampling rate as the refinement of a model without ``refined()``
(bayes_update.core.refinement), checked against an exact solution: for a time-stepping
model its difference from the model is the model's own discretisation error."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from bayes_update.core.refinement import AtTwiceTheRate, twice_the_rate

FN_HZ, ZETA, FS_HZ = 23.0, 0.03, 230.0  # ten samples a period: RK4's error is well above round-off


def _force(n=4096, seed=3):
    """A random-phase multisine below fs / 8 (smooth between samples: the interpolation is exact enough)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS_HZ
    lines = np.arange(1, 29) * FS_HZ / 256
    return np.sum(np.sin(2 * np.pi * lines[:, None] * t + rng.uniform(0, 2 * np.pi, (lines.size, 1))), axis=0)


class RK4Oscillator:
    """x'' + 2 zeta w x' + w^2 x = f(t), one classical RK4 step per sample, f linear between samples."""

    parameters = ()

    def simulate(self, theta, force, fs):
        w, h = 2 * np.pi * FN_HZ, 1.0 / fs
        f = np.asarray(force, float)

        def rhs(s, u):
            return np.array([s[1], u - 2 * ZETA * w * s[1] - w * w * s[0]])

        s, out = np.zeros(2), np.zeros(f.size)
        for k in range(f.size - 1):
            um = 0.5 * (f[k] + f[k + 1])
            k1 = rhs(s, f[k])
            k2 = rhs(s + 0.5 * h * k1, um)
            k3 = rhs(s + 0.5 * h * k2, um)
            k4 = rhs(s + h * k3, f[k + 1])
            s = s + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            out[k + 1] = s[0]
        return out


def _exact(force, fs, dense=16):
    """The oscillator's response to the band-limited force the samples stand for: scipy's lsim on
    the force resampled 16x (exact for a force linear between those points, which it nearly is)."""
    w = 2 * np.pi * FN_HZ
    fine = signal.resample_poly(force, dense, 1)[: (len(force) - 1) * dense + 1]
    t = np.arange(fine.size) / (dense * fs)
    return signal.lsim(([1.0], [1.0, 2 * ZETA * w, w * w]), fine, t)[1][::dense]


def test_twice_the_rate_measures_a_time_steppers_discretisation_error():
    model, force = RK4Oscillator(), _force()
    refined, what = twice_the_rate(model, {}, force, FS_HZ)
    assert isinstance(refined, AtTwiceTheRate) and "twice the sampling rate" in what
    coarse = model.simulate({}, force, FS_HZ)
    estimate = np.linalg.norm(refined.simulate({}, force, FS_HZ) - coarse)
    error = np.linalg.norm(_exact(force, FS_HZ) - coarse)
    # the model's error: RK4's (half the step keeps 1/16 of it) and its linear interpolation of the
    # force (half the spacing keeps 1/4): the difference holds 3/4 to 15/16 of it
    assert error > 1e-3 * np.linalg.norm(coarse)
    assert 0.7 < estimate / error < 1.0, (estimate, error)


def test_a_model_of_the_samples_is_not_refined_by_another_rate():
    class FixedFilter:  # a discrete-time model: its coefficients ignore fs
        parameters = ()

        def simulate(self, theta, force, fs):
            return signal.lfilter([0.2, 0.1], [1.0, -1.6, 0.8], force)

    with pytest.warns(RuntimeWarning, match="give it a refined"):
        refined, why = twice_the_rate(FixedFilter(), {}, _force(), FS_HZ)
    assert refined is None and "a model of the samples" in why and "taken as 0" in why


def test_a_model_that_runs_at_its_own_rate_only_says_so():
    class OwnRate:
        parameters = ()

        def simulate(self, theta, force, fs):
            if fs != FS_HZ:
                raise ValueError(f"this model runs at {FS_HZ} Hz only")
            return np.cumsum(force) / fs

    refined, why = twice_the_rate(OwnRate(), {}, _force(), FS_HZ)
    assert refined is None and f"runs at {FS_HZ} Hz only" in why


@pytest.mark.parametrize("has_refined", [True, False])
def test_the_problem_takes_the_models_own_refined_first(has_refined):
    from test_user_model import Duffing, make_dataset

    from bayes_update.core.problem import Problem

    class NoRefined(Duffing):
        refined = property(lambda self: (_ for _ in ()).throw(AttributeError("refined")))

    model = Duffing() if has_refined else NoRefined()
    problem = Problem(make_dataset(seed=2, n=2048), model)
    refined = problem.refined_model()
    if has_refined:
        assert isinstance(refined, Duffing) and refined.substeps == 4 * model.substeps
        assert problem.refinement_source() == "Duffing.refined()"
    else:
        assert isinstance(refined, AtTwiceTheRate) and refined.model is model
        assert problem.refinement_source().startswith("NoRefined at twice the sampling rate")
