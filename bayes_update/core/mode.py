"""The posterior mode by nonlinear least squares on the metrics' residual vectors.

Both metrics are lengths of residual vectors, ``e = ||r||`` with
``r = (y_ref - y_mod(x)) / ||y_ref||`` (the stage's Volterra components, see
:mod:`bayes_update.core.problem`), so ``-log L = 1/2 sum_stage ||r_stage / s_stage||^2``
is a sum of squares and the mode is a least-squares problem.  A
Gauss-Newton method (scipy's trust-region-reflective ``least_squares``, with
the prior box as bounds) uses the residuals' Jacobian, which a simplex on
the scalar ``-log L`` never sees: on a valley 1e-4 wide in P_eff and a
c-k_s band 100 times longer than wide, Nelder-Mead stopped hundreds of log
units short of the mode in 5 of 50 SBC truths; least squares from the same
starts reaches it.  The Jacobian's d columns are independent model runs,
computed in parallel through the executor, and ``J^T J`` at the mode is the
Laplace (Gauss-Newton) precision without another model run.

Each evaluation is a picklable :class:`ResidualFunction`; what a point means
(which model, which parameters) is a ``point_map``, so the same code finds
the mode of the baseline model and of a model extended by an effect
(:mod:`bayes_update.core.discrepancy`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from bayes_update.core.identifiability import gauss_newton_covariance
from bayes_update.core.problem import Problem
from surrogates.evaluation import evaluate_many

#: residual value (per entry, scaled) standing in for a failed model run
FAILED_RESIDUAL = 1e3


@dataclass
class SpacePoint:
    """Picklable point map ``x -> (model, space.to_parameters(x))``: the internal
    coordinates of a parameter space, on a fixed model (None: the problem's)."""

    space: object
    model: object = None

    def __call__(self, x):
        return self.model, self.space.to_parameters(x)


@dataclass
class ResidualFunction:
    """Picklable ``x -> r(x)``: the stages' scaled residual vectors, concatenated.

    ``point_map(x) -> (model, params)``; ``scales[i]`` is the
    likelihood scale s of ``stages[i]``, so ``-log L = 1/2 ||r||^2``.  A
    failed run (buckling, divergence) gives a vector of
    :data:`FAILED_RESIDUAL` entries: a least-squares step into it is rejected.
    """

    problem: Problem
    stages: tuple
    scales: tuple
    point_map: object

    def __call__(self, x) -> np.ndarray:
        return self.with_responses(x)[0]

    def with_responses(self, x) -> tuple[np.ndarray, list]:
        """``(r(x), [each stage's model response, None where the run failed]``)."""
        model, params = self.point_map(np.asarray(x, float))
        out, responses = [], []
        for stage, s in zip(self.stages, self.scales):
            test = self.problem.tests[stage]
            try:
                v = self.problem.run(params, test.force, model=model)
            except self.problem.failures:
                n = self.problem.output(stage, self.problem.reference_components(stage)).size
                out.append(np.full(n, FAILED_RESIDUAL))
                responses.append(None)
                continue
            out.append(self.scaled(stage, s, self.problem.output(stage, self.problem.components(stage, v)))[0])
            responses.append(v)
        return np.concatenate(out), responses

    def scaled(self, stage: str, s: float, output) -> tuple[np.ndarray, float]:
        """``(r, ||ref|| s)``: the stage's residual ``(ref - output) / (||ref|| s)`` for a compared
        ``output`` and its divisor (a derivative of the output maps to one of r by ``-1 / divisor``)."""
        ref = self.problem.output(stage, self.problem.reference_components(stage))
        divisor = float(np.linalg.norm(ref)) * s
        return (ref - output) / divisor, divisor


@dataclass
class ModeResult:
    x: np.ndarray  # the mode
    cost: float  # -log L at the mode (1/2 ||r||^2)
    jacobian: np.ndarray  # dr/dx at the mode (central differences)
    residual: np.ndarray  # r at the mode
    n_evaluations: int
    starts: list  # [(x0, x_end, cost)] of every start

    @property
    def precision(self) -> np.ndarray:
        """Gauss-Newton precision J^T J of -log L at the mode."""
        return self.jacobian.T @ self.jacobian

    def covariance(self, scale=None, floor: float = 1e-10) -> np.ndarray:
        """Laplace covariance (J^T J)^-1.  The inverse is taken in coordinates
        divided by ``scale`` (e.g. the prior widths; default the Jacobian's
        column norms), where an eigenvalue below ``floor`` times the largest
        (a direction the data do not constrain) is raised to it: that
        direction comes out very wide, not infinite or negative."""
        J = self.jacobian
        if scale is None:
            scale = np.linalg.norm(J, axis=0)
            scale = np.where(scale > 0, 1.0 / np.maximum(scale, 1e-300), 1.0)
        return gauss_newton_covariance(J, scale, floor)


def _jacobian(fun, x, r0, h, lower, upper, executor, central: bool) -> tuple[np.ndarray, int]:
    """Finite-difference Jacobian with steps ``h`` kept inside [lower, upper];
    its 2d (central) or d (forward) runs go through the executor."""
    d = len(x)
    pts, signs = [], []
    for i in range(d):
        for s in (1.0, -1.0) if central else (1.0,):
            step = s * h[i]
            if not lower[i] <= x[i] + step <= upper[i]:
                step = -step  # at a bound: step inwards
            p = x.copy()
            p[i] += step
            pts.append(p)
            signs.append((i, step))
    vals = evaluate_many(fun, pts, executor, progress=False)
    J = np.zeros((len(r0), d))
    if central:
        for i in range(d):
            (_, a), (_, b) = signs[2 * i], signs[2 * i + 1]
            if a == -b:
                J[:, i] = (vals[2 * i] - vals[2 * i + 1]) / (a - b)
            else:  # both steps went inwards: forward difference
                J[:, i] = (vals[2 * i] - r0) / a
    else:
        for i, (_, step) in enumerate(signs):
            J[:, i] = (vals[i] - r0) / step
    return J, len(pts)


@dataclass
class _OneStage:
    """Picklable ``(i, x) -> fun``'s residual of its i-th stage alone."""

    fun: ResidualFunction

    def __call__(self, task) -> np.ndarray:
        i, x = task
        f = self.fun
        return ResidualFunction(f.problem, (f.stages[i],), (f.scales[i],), f.point_map)(x)


def _residual(fun: ResidualFunction, x, executor) -> np.ndarray:
    """``fun(x)``, its stages' runs in parallel through ``executor`` (a search's steps
    are serial: one point at a time, its stages side by side)."""
    if executor is None or len(fun.stages) < 2:
        return fun(x)
    parts = evaluate_many(
        _OneStage(fun), [(i, x) for i in range(len(fun.stages))], executor, batch_size=1, progress=False
    )
    return np.concatenate(parts)


def find_mode(
    fun: ResidualFunction,
    starts,
    lower,
    upper,
    steps,
    executor=None,
    max_iterations: int = 40,
    cost_tolerance: float | None = None,
    central: bool = True,
    first_inside: bool = False,
    known=None,
) -> ModeResult:
    """Minimise ``1/2 ||fun(x)||^2`` in the box [lower, upper] from each start.

    Parameters
    ----------
    steps : finite-difference step per coordinate (same units as x), about a
        thousandth of the prior width (smaller for a coordinate pinned
        tightly, such as P_eff).
    max_iterations : least-squares iterations per start.
    cost_tolerance : stop a start when an iteration lowers ``-log L`` by less than
        this (absolute, in log-likelihood units; default: by less than 1e-6 of
        itself).  A posterior needs its mode to a small fraction of one log unit,
        not to 1e-6 of a cost of several hundred.
    central : the Jacobian at the mode by central differences (2d runs), else
        forward ones (d runs; enough for a Laplace covariance, whose
        finite-difference error is of the step's order, 1e-4 of the range).
    first_inside : go on to the next start only while the searches end on a
        bound of the box (a search that ends inside has found a valley; one
        on a bound may be in the wrong one).
    known : ``(x, r, J)``, the residual and its forward-difference Jacobian (these
        ``steps``) at a point already run, e.g. the likelihood's sensitivity span
        at the start (:func:`known_point`): a search through ``x`` takes them
        instead of 1 + d runs.

    Returns the best end point with its Jacobian.
    """
    lower, upper, steps = (np.asarray(a, float) for a in (lower, upper, steps))
    if not np.all(steps > 0):
        raise ValueError("finite-difference steps must be positive")
    count = [0]
    cache = {}
    known_key = None if known is None else np.asarray(known[0], float).tobytes()

    def f(x):
        key = np.asarray(x, float).tobytes()
        if key == known_key:
            return known[1]
        if key not in cache:
            count[0] += 1
            cache.clear()
            cache[key] = _residual(fun, np.array(x), executor)
        return cache[key]

    def jac(x):
        if np.asarray(x, float).tobytes() == known_key:
            return known[2].copy()
        J, n = _jacobian(fun, np.array(x), f(x), steps, lower, upper, executor, central=False)
        count[0] += n
        return J

    runs = []
    best = None
    scale = upper - lower
    for x0 in starts:
        x0 = np.clip(np.asarray(x0, float), lower, upper)
        ftol, stop = 1e-6, None
        if cost_tolerance is not None:  # the callback stops it (scipy's ftol would stop no earlier)
            r0 = f(x0)
            ftol, stop = 1e-10, _AbsoluteTolerance(0.5 * float(r0 @ r0), cost_tolerance)
        opt = least_squares(
            f,
            x0,
            jac=jac,
            bounds=(lower, upper),
            method="trf",
            x_scale=scale,
            max_nfev=max_iterations,
            xtol=1e-6,
            ftol=ftol,
            gtol=1e-8,
            callback=stop,
        )
        runs.append((x0, opt.x.copy(), float(opt.cost)))
        if best is None or opt.cost < best.cost:
            best = opt
        if first_inside and not on_bound(opt.x, lower, upper):
            break
    x = best.x.copy()
    if central:
        r = _residual(fun, x, executor)
        count[0] += 1
        J, n = _jacobian(fun, x, r, steps, lower, upper, executor, central=True)
        count[0] += n
    else:
        # trf leaves the residual and the forward-difference Jacobian (our jac) at its end point:
        # the same numbers a new evaluation would give, without its d + 1 runs
        r, J = np.asarray(best.fun, float).copy(), np.asarray(best.jac, float).copy()
    return ModeResult(x=x, cost=0.5 * float(r @ r), jacobian=J, residual=r, n_evaluations=count[0], starts=runs)


def known_point(fun: ResidualFunction, sensitivities: dict | None, x0, steps):
    """``(x0, r, J)`` of ``fun`` from the stages' :class:`~bayes_update.core.span.Sensitivity`
    at ``x0`` (the output and its derivative the likelihood's span took there), or None
    when they were taken elsewhere, with other steps, on other stages or on another model."""
    pm = fun.point_map
    if not sensitivities or type(pm) is not SpacePoint or (pm.model is not None and pm.model is not fun.problem.model):
        return None
    x0, steps = np.asarray(x0, float), np.asarray(steps, float)
    r, J = [], []
    for stage, s in zip(fun.stages, fun.scales):
        sens = sensitivities.get(stage)
        if (
            sens is None
            or sens.x.shape != x0.shape
            or not np.array_equal(sens.x, x0)
            or not np.allclose(sens.steps, steps, rtol=1e-12, atol=0.0)
        ):
            return None
        r0, divisor = fun.scaled(stage, s, sens.output)
        r.append(r0)
        J.append(-sens.derivative / divisor)
    return x0.copy(), np.concatenate(r), np.vstack(J)


class _AbsoluteTolerance:
    """least_squares' callback: stop after an iteration that lowers the cost by less
    than ``tolerance`` (absolute).  scipy's ``ftol`` is relative to the current cost,
    which falls by orders of magnitude from a far start (7e5 to 1.1 on a portal
    frame's stage 1): set from the first cost it stops late, from the last it
    cannot be set in advance."""

    def __init__(self, cost: float, tolerance: float):
        self.cost, self.tolerance = cost, float(tolerance)

    def __call__(self, intermediate_result):
        gain, self.cost = self.cost - float(intermediate_result.cost), float(intermediate_result.cost)
        if 0.0 <= gain < self.tolerance:
            raise StopIteration


def on_bound(x, lower, upper, rtol: float = 1e-6) -> bool:
    """Whether ``x`` lies on a face of the box [lower, upper] (within rtol of its width)."""
    x, lower, upper = (np.asarray(a, float) for a in (x, lower, upper))
    width = upper - lower
    return bool(np.any((x - lower < rtol * width) | (upper - x < rtol * width)))


def laplace_log_evidence(mode: ModeResult, log_prior_density: float, widths) -> float:
    """log p(data) by Laplace for a uniform prior box of ``widths``.

    log Z = -cost + log prior + 1/2 log det(2 pi (H + D)^-1), H = J^T J and
    D = diag(2 pi / width^2).  D makes the Gaussian integral of a direction
    the data do not constrain equal to its prior width (the Occam factor of
    such a parameter is 1, not the ratio of an infinite posterior width to
    the prior's); where the data constrain a parameter, H >> D and this is
    the textbook Laplace evidence.  ``log_prior_density`` is the prior's log
    density at the mode (minus the log of the box's volume)."""
    widths = np.asarray(widths, float)
    P = mode.precision + np.diag(2.0 * math.pi / widths**2)
    sign, logdet = np.linalg.slogdet(P)
    if sign <= 0:
        return -math.inf
    d = len(widths)
    return -mode.cost + log_prior_density + 0.5 * d * math.log(2 * math.pi) - 0.5 * logdet
