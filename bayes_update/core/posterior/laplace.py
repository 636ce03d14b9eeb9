"""The MAP by least squares (:mod:`bayes_update.core.mode`), its Laplace covariance, and the
local box the surrogates are built in."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bayes_update.core.likelihood import Likelihood
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior.target import Evaluate
from surrogates.evaluation import evaluate_many

# ------------------------------------------------------------------ MAP, box
#: a frugal search stops when an iteration gains less than this in log L: Gauss-Newton's gains
#: fall some 15-20 fold an iteration near the mode (a portal frame: 3.3, 0.22, 0.012, 0.0006),
#: so its end point is then within some 0.1 sd of the mode, which the design in the box around
#: it absorbs (the surrogate posterior, not the MAP, is the answer); 0.01 took one more
#: iteration (d + 1 runs per test) for a gain of 0.0006
FRUGAL_TOLERANCE = 0.05


@dataclass
class MapResult:
    x: np.ndarray
    value: float
    steps: np.ndarray
    covariance: np.ndarray
    n_evaluations: int
    mode: object = field(default=None, repr=False)


def find_map(
    evaluate: Evaluate,
    lik: Likelihood,
    x0,
    executor=None,
    max_evaluations: int = 600,
    progress: bool = False,
    frugal: bool = False,
) -> MapResult:
    """MAP by least squares on the residual vectors (:mod:`bayes_update.core.mode`)
    and its Gauss-Newton Laplace covariance.

    Starts: ``x0`` and the two best of the model's ``extra_starts(x0)`` when it
    offers them (the beam: a 3 x 3 grid on the (c, k_s) band at x0's
    (eta, P_eff): the low level pins eta and P_eff, and along the band the
    nonlinear misfit can have more than one valley).  ``frugal``: one search,
    from the best of ``x0`` and those starts (stopping when an iteration gains
    less than FRUGAL_TOLERANCE in log L, forward differences at the mode), and a second from
    the next best only where the first ends on a bound of the prior.  The prior's density in
    the internal coordinates is left out of the mode (the beam's
    (K_b + k_s) / K_b varies by < 1 % over its posterior) and kept in ``value``."""
    from bayes_update.core.mode import ResidualFunction, SpacePoint, find_mode, known_point, on_bound

    space = evaluate.space
    stages = tuple(evaluate.stages)
    fun = ResidualFunction(
        evaluate.problem, stages, tuple(lik.scales[s].sd for s in stages), SpacePoint(space, evaluate.problem.model)
    )
    box = space.box()
    x0 = np.clip(np.asarray(x0, float), box[:, 0], box[:, 1])
    steps = 1e-4 * (box[:, 1] - box[:, 0])
    # the likelihood's sensitivity span was taken at the start with these steps: the search
    # from there takes its residual and Jacobian (1 + d evaluations fewer)
    known = known_point(fun, lik.sensitivities, x0, steps)
    extra = getattr(evaluate.problem.model, "extra_starts", None)
    if not frugal:
        starts = [x0]
        grid = [np.asarray(g, float) for g in extra(x0)] if callable(extra) else []
        if grid and len(stages) > 1:
            cost = [0.5 * float(np.sum(r**2)) for r in evaluate_many(fun, grid, executor, progress=False)]
            starts += [grid[i] for i in np.argsort(cost)[:2]]
        iterations = max(5, int(max_evaluations) // (len(starts) * (len(x0) + 1)))
        mode = find_mode(fun, starts, box[:, 0], box[:, 1], steps, executor, max_iterations=iterations, known=known)
        return map_result(mode, space, box, mode.n_evaluations + len(grid))
    iterations = max(5, int(max_evaluations) // (3 * (len(x0) + 1)))
    grid = [np.asarray(g, float) for g in extra(x0)] if callable(extra) and len(stages) > 1 else []
    start, n_evaluations = x0, 0
    if grid:
        # the model's other starts at x0's pinned coordinates, before the one search: from a
        # coarse start (the beam: c and k_s at the prior's centre) the best of them is in the
        # right valley where x0 may not be (SBC truths near the k_s bound: 55-73 % misfit at x0)
        cands = [x0] + grid
        first = [known[1]] if known is not None else []
        cost = [
            0.5 * float(np.sum(r**2))
            for r in first + list(evaluate_many(fun, cands[len(first) :], executor, progress=False))
        ]
        n_evaluations += len(cands) - len(first)
        order = np.argsort(cost)
        start = cands[order[0]]
    mode = find_mode(
        fun,
        [start],
        box[:, 0],
        box[:, 1],
        steps,
        executor,
        max_iterations=iterations,
        cost_tolerance=FRUGAL_TOLERANCE,
        central=False,
        known=known,
    )
    n_evaluations += mode.n_evaluations
    if grid and on_bound(mode.x, box[:, 0], box[:, 1]):
        # a mode on the prior's bound may be the wrong valley of the band (an SBC truth at
        # k_s = 554 N/mm: the search from the best start ended at k_s = 0): the next best start too
        other = find_mode(
            fun,
            [cands[order[1]]],
            box[:, 0],
            box[:, 1],
            steps,
            executor,
            max_iterations=iterations,
            cost_tolerance=FRUGAL_TOLERANCE,
            central=False,
        )
        n_evaluations += other.n_evaluations
        mode = other if other.cost < mode.cost else mode
    return map_result(mode, space, box, n_evaluations)


def map_result(mode, space, box, n_evaluations: int) -> MapResult:
    cov = mode.covariance(scale=box[:, 1] - box[:, 0])
    value = mode.cost - float(space.log_prior(mode.x)[0])
    return MapResult(
        x=mode.x,
        value=value,
        steps=np.sqrt(1.0 / np.diag(mode.precision).clip(1e-300)),
        covariance=cov,
        n_evaluations=n_evaluations,
        mode=mode,
    )


def capped_covariance(cov, space: ParameterSet, box_sd: float) -> np.ndarray:
    """``cov`` with the prior's width added as information: precision
    cov^-1 + diag((box_sd / width)^2), so that box_sd sd is at most about the
    prior's width in any coordinate.  A direction the data hardly constrain
    (k_s along the band when the nonlinear level says little) would otherwise
    give a whitened box mostly outside the prior.  The cap is the whole width
    on either side (not half of it) so that a box centred anywhere in the
    prior still reaches both bounds: a cap at half the width cut 3 % of the
    default data set's posterior at the k_s bounds, however often the box
    was re-centred."""
    width = np.diff(space.box(), axis=1)[:, 0]
    P = np.linalg.inv(cov) + np.diag((box_sd / width) ** 2)
    return np.linalg.inv(P)


def local_box(space: ParameterSet, x_map, cov, box_sd: float, free=()) -> np.ndarray:
    """MAP +- box_sd marginal sd, clipped to the prior's bounding box; the
    coordinates named in ``free`` span the prior."""
    prior = space.box()
    sd = np.sqrt(np.diag(cov))
    box = np.column_stack([x_map - box_sd * sd, x_map + box_sd * sd])
    box[:, 0] = np.maximum(box[:, 0], prior[:, 0])
    box[:, 1] = np.minimum(box[:, 1], prior[:, 1])
    for name in free:
        i = space.coordinate_names.index(name)
        box[i] = prior[i]
    return box
