"""A start for ``sample`` from the runs another command kept: :func:`kept_start`.

``calibrate`` on the same data and model, given the same run cache
(:mod:`bayes_update.core.runs`), has run the model on both estimation tests at
many points and ended at its best; ``sample`` then needs no start search of its
own: the best of those points by calibrate's own objective is its start, and the
runs there are read, not made.
"""

from __future__ import annotations

import numpy as np

__all__ = ["kept_start"]


def _cost(problem, stages, responses) -> float:
    """Calibrate's objective at a point: 1/2 sum of the squared residuals of the stages'
    compared outputs, each divided by its test's noise sd (the ``full`` metric set) or by
    its reference's norm (``paper``), as :mod:`bayes_update.core.calibrate` weighs them."""
    cost = 0.0
    for st, y in zip(stages, responses):
        ref = problem.output(st, problem.reference_components(st))
        diff = ref - problem.output(st, problem.components(st, y))
        scale = problem.noise_sd(st) if problem.metrics == "full" else float(np.linalg.norm(ref))
        cost += 0.5 * float(np.sum((diff / scale) ** 2))
    return cost


def kept_start(problem) -> tuple[dict, int] | None:
    """(theta, number of points considered): the best point, by calibrate's objective, of
    the runs the problem's run store holds from *other* commands on every estimation test,
    inside the problem's prior; None without a store or without such points.

    The order of the store's entries is fixed, and ties keep the first, so that the same
    cache gives the same start (and the same posterior) on every rerun."""
    store, space = problem.run_store, problem.space
    if store is None:
        return None
    stages = problem.stages
    found = store.points(
        problem.model, [problem.tests[st].force for st in stages], problem.fs, exclude_source=store.source
    )
    best, best_cost, n = None, np.inf, 0
    for theta, responses in found:
        try:
            x = space.to_internal(theta)
        except (KeyError, ValueError):  # another prior's parameters
            continue
        if not np.isfinite(space.log_prior(x)[0]):
            continue
        n += 1
        c = _cost(problem, stages, responses)
        if c < best_cost:
            best, best_cost = theta, c
    if best is None:
        return None
    # the theta as it was run (to the bit): the runs there are found again
    return dict(best), n
