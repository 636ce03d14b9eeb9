"""The search of the two-stage calibration: steps 1-4 of
:mod:`bayes_update.core.calibrate`'s docstring on a built problem.

The screen for the linear parameters (:func:`screen_linear`), stage 1 on the
linear test and stage 2 on both (:func:`two_stage`: Sobol' designs over the
prior, then least squares from their best points), and each stage's
identifiability check, all in internal coordinates.  Apart from
:mod:`~bayes_update.core.calibrate`, which builds the problem, chooses where the
other workflows start and reports the result with its sd, because this is the
search alone: it knows a problem and a prior, no data set and no report.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import qmc

from bayes_update.core.checks import test_disagreement
from bayes_update.core.identifiability import gauss_newton_covariance, unidentified_directions
from bayes_update.core.mode import FAILED_RESIDUAL, ResidualFunction, find_mode
from bayes_update.core.model import ModelSpecError, model_label
from bayes_update.core.problem import Problem
from bayes_update.core.spectral_start import GATE_HALF_WIDTHS, SpectralCost, measured_quantiles, spectral_start
from surrogates.evaluation import evaluate_many

__all__ = ["COARSE_TOLERANCE", "SCREEN_STEP", "SCREEN_THRESHOLD", "TwoStage", "screen_linear", "two_stage"]

#: a step of this fraction of a prior range probes the linear test's sensitivity
SCREEN_STEP = 0.05
#: a parameter is "linear" when its step moves y1 by at least this fraction of the largest move
SCREEN_THRESHOLD = 0.05


@dataclass(frozen=True)
class _PointMap:
    """Picklable x_free -> (model, theta): the free coordinates placed into ``base``."""

    space: object
    base: np.ndarray
    free: tuple

    def full(self, x_free) -> np.ndarray:
        x = self.base.copy()
        x[list(self.free)] = x_free
        return x

    def __call__(self, x_free):
        return None, self.space.to_parameters(self.full(np.asarray(x_free, float)))


@dataclass(frozen=True)
class _Cost:
    """Picklable x -> 1/2 ||r(x)||^2 (a scalar travels back from a worker, not a long vector);
    inf where the model raised ModelError (its entries are exactly FAILED_RESIDUAL, which a
    real residual never is), so that a design where every run failed is told as such."""

    fun: ResidualFunction

    def __call__(self, x) -> float:
        r = self.fun(x)
        return math.inf if np.any(r == FAILED_RESIDUAL) else 0.5 * float(r @ r)


def _residual(problem: Problem, stages, point_map, weighted: bool) -> ResidualFunction:
    """r = (ref - model) / s per stage: s = the test's noise (``weighted``) or ||ref||."""
    scales = []
    for st in stages:
        ref_norm = float(np.linalg.norm(problem.output(st, problem.reference_components(st))))
        scales.append(problem.noise_sd(st) / ref_norm if weighted else 1.0)
    return ResidualFunction(problem, tuple(stages), tuple(scales), point_map)


def screen_linear(problem: Problem, space, executor=None) -> tuple[list, dict, int]:
    """(linear parameter names, {name: sensitivity}, model runs): step 1 of
    :mod:`bayes_update.core.calibrate`'s docstring."""
    box = space.box()
    width = box[:, 1] - box[:, 0]
    x0 = space.to_internal(space.center())
    fun = _residual(problem, problem.stages_of("linear"), _PointMap(space, x0, tuple(range(len(x0)))), weighted=False)
    points = [x0] + [x0 + SCREEN_STEP * width[i] * np.eye(len(x0))[i] for i in range(len(x0))]
    r = evaluate_many(fun, points, executor, progress=False)
    move = np.array([np.linalg.norm(ri - r[0]) / SCREEN_STEP for ri in r[1:]])
    if not move.max() > 0:
        raise ModelSpecError(
            f"{model_label(problem.model)}: the linear test's compared output does not move with any parameter "
            f"at the middle of the prior (a step of {100 * SCREEN_STEP:g} % of each prior range changes "
            "nothing): check that simulate uses theta[name] of every declared parameter, and that each "
            "parameter's range and unit are those simulate expects"
        )
    names = [n for n, m in zip(space.names, move) if m >= SCREEN_THRESHOLD * move.max()]
    return names, dict(zip(space.names, move.tolist())), len(points)


def _noise_rows(problem: Problem, fun: ResidualFunction) -> np.ndarray:
    """Per-row factors turning ``fun``'s residual into noise units."""
    rows = []
    for st, s in zip(fun.stages, fun.scales):
        ref = problem.output(st, problem.reference_components(st))
        rows.append(np.full(ref.size, s * np.linalg.norm(ref) / problem.noise_sd(st)))
    return np.concatenate(rows)


def _design(worker, fun, space, free, n_start, seed, executor, progress, desc):
    """A scrambled Sobol' design over the prior (free coordinates) and ``worker``'s values at its
    points; raises where every run failed (``worker``'s value, or its first entry, inf)."""
    U = qmc.Sobol(len(space), scramble=True, seed=seed).random(n_start)
    X = np.array([space.to_internal(space.theta(space.from_unit(u))) for u in U])[:, list(free)]
    values = evaluate_many(worker, list(X), executor, progress=progress, desc=desc)
    cost = np.array([v[0] if isinstance(v, tuple) else v for v in values], float)
    if not np.any(np.isfinite(cost)):
        raise ModelSpecError(
            f"{model_label(fun.problem.model)} raised ModelError at all {n_start} points of the {desc} over the "
            "prior: it cannot run over (nearly) all of its prior; narrow the prior (the Parameter bounds, or "
            "--prior NAME=LO:HI) to where the model runs, or check when simulate raises ModelError"
        )
    return X, cost, values


def _starts(fun, space, free, n_start, n_best, seed, executor, progress, desc, costs: bool = False):
    """The ``n_best`` best points of a scrambled Sobol' design over the prior (free
    coordinates) and the design's size; ``costs``: their costs as well."""
    X, cost, _ = _design(_Cost(fun), fun, space, free, n_start, seed, executor, progress, desc)
    order = np.argsort(np.where(np.isfinite(cost), cost, np.inf))[:n_best]
    if costs:
        return [X[i] for i in order], len(X), [float(cost[i]) for i in order]
    return [X[i] for i in order], len(X)


def _spectral_starts(fun, space, free, n_start, n_best, seed, executor, progress, log):
    """Stage 1's starts: the ``n_best`` best points of its design, led by the spectral start
    (:mod:`bayes_update.core.spectral_start`) where the best of them misses the measured
    energy quantiles by more than its gate; and the runs taken."""
    X, cost, values = _design(SpectralCost(fun), fun, space, free, n_start, seed, executor, progress, "stage 1 design")
    order = np.argsort(np.where(np.isfinite(cost), cost, np.inf))[:n_best]
    starts, n_design = [X[i] for i in order], len(X)
    problem, stage = fun.problem, fun.stages[0]
    zeta = [m.damping_ratio for m in problem.basis.modes(1)]
    half_width = float(np.median(zeta)) if zeta else 0.0
    box = space.box()[list(free)]
    measured = measured_quantiles(problem, stage)
    gate = GATE_HALF_WIDTHS * half_width
    quantiles, found, n, first_miss = [v[1] for v in values], None, 0, None
    # each spectral start is run (its cost and quantiles) and joins the regression: at most
    # SPECTRAL_RUNS, until one lies within the gate
    for _ in range(SPECTRAL_RUNS):
        x, report = spectral_start(X, cost, quantiles, measured, box[:, 0], box[:, 1], half_width)
        if x is None:
            break
        c, q = SpectralCost(fun)(x)
        n += 1
        miss = float(np.sqrt(np.mean((q[report["keep"]] - measured[report["keep"]]) ** 2)))
        first_miss = report["best_miss"] if first_miss is None else first_miss
        if math.isfinite(c) and miss < (found[1] if found else first_miss):  # NaN (a failed run) compares False
            found = (x, miss)
        X, cost, quantiles = np.vstack([X, x]), np.append(cost, c), [*quantiles, q]
        if miss <= gate:
            break
    if n:
        log(
            f"stage 1: the design's best point misses the response's energy quantiles by {first_miss:.3f} in log f "
            f"(gate {gate:.3f}); "
            + (f"the spectral start by {found[1]:.3f} ({n} runs): the search starts there" if found else "not used")
        )
    if found is not None:
        starts = [found[0]] + starts[:-1]
    return starts, n_design + n


@dataclass
class TwoStage:
    """What :func:`two_stage` found (internal coordinates)."""

    x1: np.ndarray  # after stage 1
    x: np.ndarray  # after stage 2
    unidentified: dict  # stage -> directions (:func:`unidentified_directions`)
    n_model_runs: int
    disagreement: list = field(default_factory=list)  # :func:`bayes_update.core.checks.test_disagreement`
    covariance: np.ndarray | None = None  # Gauss-Newton covariance of x at the end of stage 2 (noise units)


#: spectral starts run at most (:func:`_spectral_starts`)
SPECTRAL_RUNS = 3

#: the coarse start's linear stage stops when an iteration gains less than this in log L: its
#: point only places the nonlinear stage's design and the MAP's search, which goes on from it
#: (a portal frame: the gains 37, 7.8, 1.1, then an iteration of 7 runs for 0.0007)
COARSE_TOLERANCE = 2.0


def two_stage(
    problem: Problem,
    space,
    linear_names,
    *,
    n_start: int = 64,
    n_best: int = 3,
    max_iterations: int = 40,
    seed: int = 0,
    executor=None,
    progress: bool = True,
    polish: bool = True,
    log=lambda *a: None,
) -> TwoStage:
    """Stages 2-4 of :mod:`bayes_update.core.calibrate`'s docstring on a built problem; without ``polish`` (a start
    for the posterior's MAP) stage 2 ends at the best of its starts."""
    box = space.box()
    lower, upper = box[:, 0], box[:, 1]
    steps = 1e-3 * (upper - lower)
    weighted = problem.metrics == "full"
    runs = 0
    # stage 1: the linear parameters on e_lin (every linear test; the others at the prior's centre)
    free1 = tuple(space.names.index(n) for n in linear_names)
    map1 = _PointMap(space, space.to_internal(space.center()), free1)
    fun1 = _residual(problem, problem.stages_of("linear"), map1, weighted)
    # the spectral start where the design is a coarse start's (16 points over the prior: its best point
    # can miss a lightly damped mode's valley); calibrate's 64-point design searches from its 3 best
    if polish:
        starts, n = _starts(fun1, space, free1, n_start, n_best, seed, executor, progress, "stage 1 design")
    else:
        starts, n = _spectral_starts(fun1, space, free1, n_start, n_best, seed, executor, progress, log)
    # without polish (a start for the posterior's search) stage 1 stops when an iteration gains
    # less than COARSE_TOLERANCE in log L, forward differences, and searches from the next best
    # start only while a search ends on a bound
    mode1 = find_mode(
        fun1,
        starts,
        lower[list(free1)],
        upper[list(free1)],
        steps[list(free1)],
        executor,
        max_iterations,
        **({} if polish else {"cost_tolerance": COARSE_TOLERANCE, "central": False, "first_inside": True}),
    )
    runs += n + mode1.n_evaluations
    x1 = map1.full(mode1.x)
    unident = {
        "linear": unidentified_directions(
            mode1.jacobian, (upper - lower)[list(free1)], linear_names, _noise_rows(problem, fun1)
        )
    }
    # stage 2: everything on both tests, from stage 1's point and the best points of a design over
    # the other parameters at stage 1's values (the paper's second grid: the nonlinear misfit can be
    # a narrow valley in them, which a design over all parameters would miss)
    free2 = tuple(range(len(space)))
    map2 = _PointMap(space, x1, free2)
    fun2 = _residual(problem, problem.stages, map2, weighted)
    rest = tuple(i for i in free2 if i not in free1) or free2
    map_rest = _PointMap(space, x1, rest)
    # without polish half the design (over the parameters the linear test leaves free)
    starts, n, start_costs = _starts(
        _residual(problem, problem.stages, map_rest, weighted),
        space,
        rest,
        n_start if polish else max(4, n_start // 2),
        n_best - 1,
        seed + 1,
        executor,
        progress,
        "stage 2 design",
        costs=True,
    )
    starts = [map_rest.full(x) for x in starts]
    if not polish:
        # the design's points are fun2's own (the same residual at the same full point): only x1 is run
        cost = [_Cost(fun2)(x1)] + start_costs
        runs += n + 2
        return TwoStage(x1=x1, x=([x1] + starts)[int(np.argmin(cost))], unidentified=unident, n_model_runs=runs)
    mode2 = find_mode(fun2, [x1] + starts, lower, upper, steps, executor, max_iterations)
    runs += n + mode2.n_evaluations
    rows = _noise_rows(problem, fun2)
    unident["nonlinear"] = unidentified_directions(mode2.jacobian, upper - lower, space.names, rows)
    blocks = {problem.tests[st].name: rows_of for st, rows_of in problem.stage_rows().items()}
    # each test's independent directions (its compared regressors per sensor): its own misfit beyond
    # the noise widens its sd (bayes_update.core.checks.test_disagreement)
    dof = {problem.tests[st].name: problem.n_regressors(st) * len(problem.sensors) for st in problem.stages}
    disagree = test_disagreement(
        mode2.jacobian * rows[:, None], mode2.residual * rows, blocks, space.names, upper - lower, dof
    )
    return TwoStage(
        x1=x1,
        x=mode2.x,
        unidentified=unident,
        n_model_runs=runs,
        disagreement=disagree,
        covariance=gauss_newton_covariance(mode2.jacobian * rows[:, None], upper - lower),
    )
