"""The posterior's run budget (the runs-per-posterior issue): the likelihood
scales' control variate, the design's stopping rule and the count of model
runs each step reports."""

import tempfile
from pathlib import Path

import numpy as np
import pytest

from bayes_update.core.likelihood import estimate_likelihood, likelihood_runs
from bayes_update.core.replicates import lti_response


class _Counting:
    """A model of the contract that counts its runs (around the Duffing oscillator of test_user_model)."""

    def __init__(self, inner):
        self.inner, self.parameters, self.runs = inner, inner.parameters, 0

    def simulate(self, theta, force, fs):
        self.runs += 1
        return self.inner.simulate(theta, force, fs)


@pytest.fixture(scope="module")
def linear_problem():
    """A linear oscillator (the Duffing of test_user_model with k2 = k3 = 0) and its data."""
    from test_user_model import Duffing, make_dataset

    from bayes_update.core.calibrate import problem_for

    data = make_dataset(seed=23, truth={"k2": 0.0, "k3": 0.0})
    model = _Counting(Duffing(("fn", "zeta"), fixed={"k2": 0.0, "k3": 0.0, "gain": 1.3}))
    return problem_for(data, model, None, None), model


def test_the_lti_estimate_is_the_linear_models_response(linear_problem):
    """For a linear model the probe's transfer function is the model's: the response to a
    fresh force noise record from it matches a model run to the window's leakage (an
    independent check: the model's own RK4 integration)."""
    problem, _ = linear_problem
    theta = {"fn": 41.3, "zeta": 0.021}
    stage = "linear"
    force = problem.tests[stage].force
    v0 = problem.simulate(theta, stage)
    sig = 0.01 * np.sqrt(np.mean(force**2))
    rng = np.random.default_rng(5)
    lti = lti_response(problem, theta, stage, v0, sig, rng)
    du = sig * rng.standard_normal(force.size)
    dv_model = problem.run(theta, force + du) - v0
    dv_lti = lti(du)
    # the metric sees the projection on the regressors: compare there
    out = [problem.output(stage, problem.components(stage, v)) for v in (dv_model, dv_lti)]
    assert np.linalg.norm(out[1] - out[0]) <= 0.01 * np.linalg.norm(out[0])  # measured: 0.1 %


def test_the_control_variate_counts_and_agrees_with_model_replicates(linear_problem):
    """The scales from 96 replicates run on the model and from the control variate
    (96 LTI replicates corrected by 16 model ones) agree within their Monte Carlo
    error (sd of s_n about 1/sqrt(2 K r) = 7 % for K = 96, r = 1-2 directions), and
    each takes the runs likelihood_runs says."""
    problem, model = linear_problem
    theta = {"fn": 41.3, "zeta": 0.021}
    space = problem.space
    got = {}
    for key, k in (("model", None), ("control_variate", 16)):
        model.runs = 0
        lik = estimate_likelihood(
            problem, theta, n_replicates=96, seed=3, space=space, model_replicates=k, model_error=False
        )
        assert model.runs == likelihood_runs(problem, 96, space, model_error=False, model_replicates=k)
        assert lik.n_model_runs == model.runs  # counted where they are made
        got[key] = {st: sc.noise_sd for st, sc in lik.scales.items()}
    for st in got["model"]:
        assert got["control_variate"][st] == pytest.approx(got["model"][st], rel=0.2), (st, got)


def test_the_design_stops_when_the_surrogate_posterior_stops_moving():
    """The stopping rule on a target that does not change stops at the third check
    (two quiet rounds in a row); a target that moves by 0.5 sd each round never stops."""
    from bayes_update.core.posterior.design import _Stability

    def weight_for(shift):
        return lambda X: -0.5 * np.sum((np.atleast_2d(X) - shift) ** 2, axis=1)

    still = _Stability(lambda s: weight_for(0.0), 2, 0.1, np.random.default_rng(0), lambda *a: None)
    assert [still(object()) for _ in range(3)] == [False, False, True]
    moving = _Stability(lambda s: weight_for(s), 2, 0.1, np.random.default_rng(0), lambda *a: None)
    assert not any(moving(0.5 * i) for i in range(5))


def test_refine_stops_when_asked():
    """surrogates.refine runs no round once ``until`` says so."""
    import surrogates

    box = np.array([[0.0, 1.0], [0.0, 1.0]])
    X = surrogates.design(box, 12, "sobol", seed=1)
    f = lambda x: float(np.sum((np.asarray(x) - 0.3) ** 2))  # noqa: E731
    y = np.array([f(x) for x in X])
    calls = []

    def until(sur, rounds):
        calls.append(len(rounds))
        return len(calls) >= 2

    ref = surrogates.refine(
        f,
        lambda: surrogates.GPSurrogate(box, transform="none"),
        X,
        y,
        lambda s: lambda Z: np.ones(len(Z)),
        n_rounds=5,
        batch=3,
        until=until,
        progress=False,
    )
    assert len(ref.rounds) == 2 and len(ref.X) == 15 and calls == [1, 2]
    # each round holds what the surrogate before it predicted at its points: an independent check, f itself
    last = ref.rounds[1]
    before = ref.rounds[0]["surrogate"]
    assert np.allclose(last["y_pred"], before.mean_transformed(last["X_new"]))
    assert np.allclose(last["y_new"], [f(x) for x in last["X_new"]])
    # an ``until`` of the surrogate alone (the older form) is asked the same way
    alone = []
    ref = surrogates.refine(
        f,
        lambda: surrogates.GPSurrogate(box, transform="none"),
        X,
        y,
        lambda s: lambda Z: np.ones(len(Z)),
        n_rounds=5,
        batch=3,
        until=lambda sur: alone.append(sur) or len(alone) >= 3,
        progress=False,
    )
    assert len(ref.rounds) == 3 and len(alone) == 3


def test_the_beams_coarse_start_finds_the_preload_of_the_paper_calibration():
    """The coarse start (no grid over c and k_s) puts eta and P_eff where the full
    two-stage calibration does (Table 3 of docs/beam_study.md: eta 3.007 MPa s,
    P_eff 74.03 N), from the low level alone, in six runs."""
    from bayes_update.models.beam.model import beam_model
    from bayes_update.models.beam.virtual_rig import load_default_dataset

    data = load_default_dataset()
    beam = beam_model(data, "rom")
    theta, runs = beam.start(data, coarse=True)
    p_eff = beam.to_internal(theta)[2]
    assert runs == 6
    assert abs(p_eff - 74.03) < 0.1 and abs(theta["eta"] - 3.007) < 0.05, theta


@pytest.mark.slow  # about 60 s; benchmarks/runs_per_posterior.py measures the budget against a direct chain
@pytest.mark.headline
def test_the_budget_posterior_of_a_user_model_covers_its_truth_in_few_runs():
    """The default sizes on the Duffing oscillator of test_user_model (fn, zeta, k3
    free): the truth inside every 94 % HDI, converged chains, and at most the README's bar of
    250 model runs in total (benchmarks/runs_per_posterior.py: 177-191)."""
    from test_user_model import TRUTH, Duffing, make_dataset

    from bayes_update.core.posterior import PosteriorSettings, sample

    free = ("fn", "zeta", "k3")
    model = Duffing(free, fixed={k: v for k, v in TRUTH.items() if k not in free})
    res = sample(make_dataset(seed=11), model, PosteriorSettings(), workers=2, progress=False, log=lambda *a: None)
    assert res.n_model_runs["total"] <= 250, res.n_model_runs
    for name in free:
        s = res.summary[name]
        assert s["hdi_3%"] <= TRUTH[name] <= s["hdi_97%"], (name, s)
        # a default posterior converges: R-hat < 1.01, bulk and tail ESS >= 400
        assert s["r_hat"] < 1.01 and min(s["ess_bulk"], s["ess_tail"]) >= 400, (name, s)


def test_the_thorough_and_quick_options_exclude_each_other(tmp_path, capsys):
    """`sample --thorough --quick` is refused in one line (status 2) before any model run."""
    from bayes_update.cli import main

    assert main(["sample", "--model", "rom", "--thorough", "--quick", "--out", str(tmp_path / "x")]) == 2
    assert "--thorough and --quick: choose one" in capsys.readouterr().err


def test_a_forward_difference_mode_reuses_the_searchs_last_jacobian():
    # a nonlinear least-squares problem with a known minimum: the Jacobian handed back (the
    # search's own at its end point) equals a fresh forward-difference one there, at d + 1 fewer runs
    from bayes_update.core.mode import _jacobian, find_mode

    t = np.linspace(0.0, 1.0, 40)
    truth = np.array([1.3, -0.7, 2.1])
    y = truth[0] * np.exp(truth[1] * t) + truth[2] * t**2

    def fun(x):
        return (x[0] * np.exp(x[1] * t) + x[2] * t**2 - y) / 0.01

    lower, upper = np.array([0.0, -3.0, 0.0]), np.array([3.0, 1.0, 4.0])
    steps = 1e-4 * (upper - lower)
    fwd = find_mode(fun, [np.array([1.0, 0.0, 1.0])], lower, upper, steps, central=False)
    J, n = _jacobian(fun, fwd.x, fun(fwd.x), steps, lower, upper, None, central=False)
    np.testing.assert_allclose(fwd.jacobian, J, rtol=1e-12, atol=0)
    np.testing.assert_allclose(fwd.residual, fun(fwd.x), rtol=0, atol=1e-12)
    np.testing.assert_allclose(fwd.x, truth, rtol=1e-5)
    cen = find_mode(fun, [np.array([1.0, 0.0, 1.0])], lower, upper, steps, central=True)
    # same search, then central differences (2d runs) and the point itself, against none
    assert cen.n_evaluations - fwd.n_evaluations == 1 + 2 * len(truth)


@pytest.mark.slow  # 1-3 minutes (a 5 ms model, some 300-450 runs)
def test_a_posterior_on_lab_records_covers_the_truth_without_a_refined_model():
    """The lab records of test_measured_records (drifting sensors, coloured noise, a noisy
    force; the user's chain has no refined()): the default posterior covers the truth.  (Here
    the misfit at the MAP is within the noise's chance, so the model error stays 0; on the
    records with a damper and k2 and the damper free, d = 6, it did not, and noise-only scales
    put the truth 10-55 sd away: benchmarks/runs_per_posterior.py, chain6.)"""
    import test_measured_records as lab_chain

    from bayes_update.core.posterior import PosteriorSettings, sample

    data = lab_chain.read_back(lab_chain.lab_tests(), Path(tempfile.mkdtemp()) / "lab")
    res = sample(data, lab_chain.LabChain(), PosteriorSettings(), workers=2, progress=False, log=lambda *a: None)
    for name, truth in lab_chain.TRUTH.items():
        s = res.summary[name]
        assert s["hdi_3%"] <= truth <= s["hdi_97%"], (name, truth, s)
    print({st: (sc.model_error, sc.model_error_source) for st, sc in res.likelihood.scales.items()})


@pytest.mark.slow  # 2-5 minutes: two ROM posteriors
@pytest.mark.parametrize(
    "truth",
    [
        # two SBC truths with k_s near its upper bound: the coarse start (c and k_s at the prior's
        # centre) missed the high level by 55-73 % there, and a search from the best start ended at k_s = 0
        {"eta": 1.0735, "c": 25.909, "F": 94.342, "k_s": 574.33},
        {"eta": 3.3999, "c": 6.9712, "F": 88.066, "k_s": 554.12},
    ],
)
def test_the_default_posterior_finds_the_valley_near_the_k_s_bound(truth):
    import fe
    from bayes_update.core.posterior import PosteriorSettings, sample
    from bayes_update.data import signals
    from bayes_update.data.dataset import Dataset, Record
    from bayes_update.models.beam.model import Beam
    from bayes_update.models.beam.virtual_rig import PAPER_EQUIVALENT_RIG

    model = Beam(fe.ModalROM(PAPER_EQUIVALENT_RIG))
    rng = np.random.default_rng(2718)
    tests = []
    for name, amp, role in (("chirp_low", 0.02, "linear"), ("chirp_high", 0.2, "nonlinear")):
        f = signals.chirp(amp)
        v = model.simulate(truth, f, 1024.0)
        tests.append(
            Record(
                f"{name}.csv",
                "chirp",
                name.split("_")[1],
                role,
                np.arange(f.size) / 1024.0,
                signals.add_noise(f, 40.0, rng),
                signals.add_noise(v, 40.0, rng),
            )
        )
    data = Dataset("near-bound", 1024.0, model.rig, tests)
    res = sample(
        data, model, PosteriorSettings(n_linear=0, model_error=False), workers=2, progress=False, log=lambda *a: None
    )
    for name in ("eta", "c", "F", "k_s"):
        s = res.summary[name]
        assert s["hdi_3%"] <= truth[name] <= s["hdi_97%"], (name, truth[name], s)
    print(res.n_model_runs)  # 271-371 measured (a second search where the first ends on a bound)


def _rosenbrock(x):
    """Residual of the Rosenbrock valley (minimum 0 at (1, 1)), shifted by a constant
    residual so the minimum cost is 50 (a misfit, as a data set's noise leaves)."""
    return np.array([10.0 * (x[1] - x[0] ** 2), 1.0 - x[0], 10.0])


def test_an_absolute_cost_tolerance_stops_the_search_within_it():
    """scipy's ftol is relative to the current cost: set from a far start's cost it stops
    late.  With cost_tolerance the search stops at the first iteration that gains less
    than it: its cost is within a few tolerances of the converged one (measured against
    the search run to its end), and it took fewer evaluations."""
    from bayes_update.core.mode import find_mode

    lower, upper, steps = np.array([-2.0, -1.0]), np.array([2.0, 3.0]), np.array([1e-7, 1e-7])
    start = [np.array([-1.5, 2.5])]
    full = find_mode(_rosenbrock, start, lower, upper, steps, max_iterations=200, central=False)
    assert full.cost == pytest.approx(50.0, abs=1e-8)  # the closed-form minimum
    for tol in (1e-1, 1e-3):
        frugal = find_mode(
            _rosenbrock, start, lower, upper, steps, max_iterations=200, cost_tolerance=tol, central=False
        )
        print(tol, frugal.cost - full.cost, frugal.n_evaluations, full.n_evaluations)
        assert frugal.cost - full.cost < 10 * tol
        assert frugal.n_evaluations < full.n_evaluations


def test_first_inside_searches_from_the_next_start_only_after_a_bound():
    """Two starts: when the first search ends inside the box the second is not run
    (fewer evaluations, one entry in ``starts``); when the box's upper bound cuts the
    valley (x0 <= 0.5) the first ends on it and the second is searched too."""
    from bayes_update.core.mode import find_mode, on_bound

    steps = np.array([1e-7, 1e-7])
    starts = [np.array([1.6, 2.0]), np.array([-1.5, 2.5])]
    inside = find_mode(
        _rosenbrock,
        starts,
        np.array([-2.0, -1.0]),
        np.array([2.0, 3.0]),
        steps,
        cost_tolerance=1e-3,
        central=False,
        first_inside=True,
    )
    assert len(inside.starts) == 1 and not on_bound(inside.x, [-2.0, -1.0], [2.0, 3.0])
    both = find_mode(
        _rosenbrock,
        starts,
        np.array([-2.0, -1.0]),
        np.array([0.5, 3.0]),
        steps,
        cost_tolerance=1e-3,
        central=False,
        first_inside=True,
    )
    assert len(both.starts) == 2 and on_bound(both.x, [-2.0, -1.0], [0.5, 3.0])
    assert on_bound([0.5, 1.0], [0.0, 0.0], [0.5, 2.0]) and not on_bound([0.25, 1.0], [0.0, 0.0], [0.5, 2.0])


def test_the_map_search_takes_the_likelihoods_span_at_the_start_as_its_first_jacobian():
    """The likelihood's sensitivity span at the start is the same forward difference the
    mode search takes there first (steps 1e-4 of the prior box): the search reuses it.
    Same mode (to the search's tolerance) and Laplace covariance, 1 + d evaluations fewer,
    and the known Jacobian equals a fresh one of the residual function to rounding."""
    import dataclasses

    from test_user_model import TRUTH, Duffing, make_dataset

    from bayes_update.core.calibrate import problem_for
    from bayes_update.core.mode import ResidualFunction, SpacePoint, _jacobian, known_point
    from bayes_update.core.posterior.laplace import find_map
    from bayes_update.core.posterior.target import Evaluate

    free = ("fn", "zeta", "k3")
    data = make_dataset(seed=29)
    model = Duffing(free, fixed={k: v for k, v in TRUTH.items() if k not in free})
    problem = problem_for(data, model, None, None)
    space = problem.default_space()
    start = {"fn": 1.03 * TRUTH["fn"], "zeta": 0.8 * TRUTH["zeta"], "k3": 0.6 * TRUTH["k3"]}
    lik = estimate_likelihood(problem, start, n_replicates=16, model_replicates=4, space=space)
    x0 = space.to_internal(start)
    box = space.box()
    steps = 1e-4 * (box[:, 1] - box[:, 0])
    fun = ResidualFunction(
        problem, problem.stages, tuple(lik.scales[s].sd for s in problem.stages), SpacePoint(space, problem.model)
    )
    x, r, J = known_point(fun, lik.sensitivities, x0, steps)
    J_fresh, _ = _jacobian(fun, x0, fun(x0), steps, box[:, 0], box[:, 1], None, central=False)
    np.testing.assert_allclose(r, fun(x0), rtol=0, atol=1e-12 * np.abs(r).max())
    np.testing.assert_allclose(J, J_fresh, rtol=0, atol=1e-9 * np.abs(J_fresh).max())
    # elsewhere, with other steps or another model: nothing known
    assert known_point(fun, lik.sensitivities, x0 + steps, steps) is None
    assert known_point(fun, lik.sensitivities, x0, 2 * steps) is None
    assert (
        known_point(dataclasses.replace(fun, point_map=SpacePoint(space, Duffing(free))), lik.sensitivities, x0, steps)
        is None
    )

    ev = Evaluate(problem, space, problem.stages)
    with_known = find_map(ev, lik, x0, frugal=True)
    without = find_map(ev, dataclasses.replace(lik, sensitivities=None), x0, frugal=True)
    assert without.n_evaluations - with_known.n_evaluations == 1 + len(free)
    sd = np.sqrt(np.diag(without.covariance))
    np.testing.assert_allclose(with_known.x, without.x, rtol=0, atol=0.01 * sd.min())
    np.testing.assert_allclose(np.sqrt(np.diag(with_known.covariance)), sd, rtol=1e-3)


@pytest.mark.parametrize("model_replicates", [None, 4])
def test_the_scales_runs_in_worker_processes_give_the_same_numbers(linear_problem, model_replicates):
    """The replicates' and the span's runs go through the executor: every random draw is
    made in the caller, in the same order, so the scales equal the serial ones."""
    from surrogates.evaluation import default_executor

    problem, _ = linear_problem
    theta = {"fn": 41.1, "zeta": 0.019}
    kw = dict(n_replicates=8, model_replicates=model_replicates, seed=3, space=problem.default_space())
    serial = estimate_likelihood(problem, theta, **kw)
    with default_executor(2) as pool:
        parallel = estimate_likelihood(problem, theta, executor=pool, **kw)
    for st in problem.stages:
        a, b = serial.scales[st], parallel.scales[st]
        assert a.noise_sd == pytest.approx(b.noise_sd, rel=1e-12) and a.sd == pytest.approx(b.sd, rel=1e-12)
        # a forward difference over a step of 1e-4 of the box turns the runs' last-digit
        # differences between processes (their BLAS threads) into ~1e-7 of the derivative,
        # 1000 times below its truncation error
        J = serial.sensitivities[st].derivative
        np.testing.assert_allclose(parallel.sensitivities[st].derivative, J, rtol=0, atol=1e-6 * np.abs(J).max())
        np.testing.assert_allclose(
            parallel.noise_residuals[st][0], serial.noise_residuals[st][0], rtol=1e-12, atol=1e-15
        )


def test_the_gauss_newton_mean_is_exact_for_a_linear_residual():
    """For r(x) = r0 + J (x - x0), z = log(1 + |r|^2) everywhere: the Gauss-Newton mean,
    a quadratic written in the whitened coordinates, must give it at any u (closed form)."""
    from bayes_update.core.posterior.design import GaussNewtonMean
    from bayes_update.core.posterior.target import Whitening

    rng = np.random.default_rng(8)
    d, n = 4, 30
    J, r0, x0 = rng.standard_normal((n, d)), 0.3 * rng.standard_normal(n), rng.standard_normal(d)
    A = rng.standard_normal((d, d))
    whitening = Whitening.from_covariance(x0 + 0.2 * rng.standard_normal(d), A @ A.T + 0.1 * np.eye(d))
    mean = GaussNewtonMean.at_mode(r0, J, x0, whitening)
    U = 3.0 * rng.standard_normal((50, d))
    r = r0 + (whitening.to_x(U) - x0) @ J.T
    np.testing.assert_allclose(mean(U), np.log1p(np.sum(r**2, axis=1)), rtol=1e-10)
