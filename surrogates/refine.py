"""Sequential refinement of a surrogate where it matters.

A one-shot design spends most runs where the posterior has no mass; when the
posterior is a thin valley, few or none of them land in it, and the surrogate
is worst exactly where the likelihood reads it.  Refinement adds points in
batches where ``weight(x) * sd(x)`` is large: ``weight`` is what the caller
cares about (typically the unnormalized posterior density computed from the
current surrogate) and ``sd`` the surrogate's predictive sd in its
*transformed* space, the space the likelihood is written in.

This module holds the loop (fit, propose, run, append: :func:`refine`); which
points a round adds, and why that criterion, is :mod:`surrogates.proposal`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .evaluation import evaluate_many
from .proposal import as_list, propose_points

__all__ = ["RefinementResult", "propose_points", "refine"]


@dataclass
class RefinementResult:
    """What :func:`refine` did.

    X, y : all points (n, d) and values, (n,) or (n, k), in the order run
        (the initial design first); failed runs have non-finite y.
    surrogate : the final surrogate (or list, one per output), fitted on the
        finite rows of (X, y).
    rounds : one dict per round, round 0 being the initial fit: ``round``,
        ``n_train`` (points fitted), ``n_failed`` (non-finite rows left out),
        ``X_new``, ``y_new``, ``y_pred`` (the previous surrogate's transformed mean
        at ``X_new``, before they were run; not in round 0), ``results`` (raw
        outputs of func), ``surrogate``.
    seconds : wall time [s] by part: ``fit`` (the surrogates' fits), ``runs`` (evaluating
        func), ``until`` (the stopping rule's checks), ``propose`` (candidates and the
        points chosen among them).
    """

    X: np.ndarray
    y: np.ndarray
    surrogate: object
    rounds: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)


def _n_positional(func) -> int:
    """How many positional arguments ``func`` takes (a large number for ``*args``)."""
    import inspect

    try:
        params = inspect.signature(func).parameters.values()
    except (TypeError, ValueError):
        return 1
    if any(p.kind is p.VAR_POSITIONAL for p in params):
        return 99
    return sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) for p in params)


def _fit_one(job):
    """Fit one unfitted surrogate: ``job`` = (surrogate, X, y) (a worker's task)."""
    sur, X, y = job
    return sur.fit(X, y)


def _fit(surrogate_factory, X, y, previous=None, executor=None):
    """Fit one surrogate per output on the finite rows; with ``previous`` (the last
    round's, same layout) each starts from it (``warm_from``) where it can; with
    ``executor`` several outputs' fits run in its workers (the same seeded fits, so
    the same surrogates: a GP fit is mostly Python-level work that one process does
    one at a time)."""
    ok = np.all(np.isfinite(y.reshape(len(y), -1)), axis=1)
    if ok.sum() < 2:
        raise ValueError(f"only {ok.sum()} finite values to fit the surrogate on")

    def one(prev, k=0):
        sur = surrogate_factory()
        if isinstance(sur, (list, tuple)):  # one surrogate per output (e.g. each its own prior mean)
            sur = sur[k]
        if prev is not None and hasattr(sur, "warm_from"):
            sur = sur.warm_from(prev)
        return sur

    if y.ndim == 1:
        return one(previous).fit(X[ok], y[ok]), int(ok.sum())
    prev = previous if previous is not None else [None] * y.shape[1]
    jobs = [(one(prev[k], k), X[ok], y[ok, k]) for k in range(y.shape[1])]
    if executor is not None and len(jobs) > 1:
        return list(executor.map(_fit_one, jobs)), int(ok.sum())
    return [_fit_one(job) for job in jobs], int(ok.sum())


def refine(
    func,
    surrogate_factory,
    X,
    y,
    weight_from_surrogate,
    n_rounds: int,
    batch: int,
    executor=None,
    seed=None,
    *,
    candidates=4096,
    target=None,
    min_distance: float = 0.01,
    log_weight: bool = False,
    power: float = 0.5,
    evaluate=evaluate_many,
    progress: bool = True,
    until=None,
    warm_start: bool = False,
    parallel_fits: bool = False,
) -> RefinementResult:
    """Refine a surrogate by at most ``n_rounds`` batches of ``batch`` new model runs.

    Each round: fit ``surrogate_factory()`` to the finite rows of (X, y); build
    ``weight = weight_from_surrogate(surrogate)``; propose ``batch`` points
    with :func:`propose_points`; run ``func`` on them through
    ``evaluate(func, points, executor=executor, progress=progress)``
    (default :func:`surrogates.evaluation.evaluate_many`; pass e.g.
    ``functools.partial(cached_evaluate, cache=cache)`` to cache them); append.

    Parameters
    ----------
    func : picklable callable of one point (d,) returning a float, or
        anything that ``target`` turns into a float (or k floats).
    surrogate_factory : callable with no argument returning an unfitted
        surrogate (called once per output and round), or a list of them, the
        k-th for output k.
    X, y : the initial design (n0, d) and its values, (n0,) for one output
        or (n0, k) for k outputs (one surrogate each; weight_from_surrogate then
        receives the list).
    weight_from_surrogate : callable ``(surrogate) -> weight`` where ``weight``
        is as in :func:`propose_points` (e.g. the surrogate posterior density).
    n_rounds, batch : rounds and points per round.
    executor : any ``concurrent.futures.Executor`` or None (serial).
    seed : int or None; seeds the Sobol' candidates of every round.
    candidates : int (Sobol' candidates per round), an (m, d) array, or a
        callable ``(surrogate, rng) -> (m, d)`` (e.g. MCMC draws on the current
        surrogate posterior).
    target : callable ``result -> float or k floats`` applied to func's
        outputs (default: ``float``), e.g. ``lambda r: r["e_lin"]``.
    min_distance, log_weight, power : as in :func:`propose_points`.
    parallel_fits : the outputs' surrogates fitted in ``executor``'s workers
        (they must be picklable; the fits are the same).
    until : callable ``(surrogate, rounds) -> bool`` (or ``(surrogate) -> bool``) or None: asked before every
        round (after the initial fit and after each round's) with the current
        surrogate and the rounds so far (each round's ``y_pred``: what the
        surrogate before it predicted, in its transformed space, at the points it
        then ran: a held-out check of the surrogate the rule may read); True
        ends the refinement there (e.g. when what the surrogate is for no longer
        moves and predicted the last round's runs).

    Returns
    -------
    :class:`RefinementResult`.
    """
    X = np.array(X, dtype=float)
    y = np.array(y, dtype=float)
    if X.ndim != 2 or y.ndim not in (1, 2) or len(y) != len(X):
        raise ValueError(f"X must be (n, d) and y (n,) or (n, k) of the same n; got {X.shape}, {y.shape}")
    for name, v in (("n_rounds", n_rounds), ("batch", batch)):
        if isinstance(v, bool) or int(v) != v or v < (0 if name == "n_rounds" else 1):
            raise ValueError(
                f"{name} must be a {'non-negative' if name == 'n_rounds' else 'positive'} integer, got {v!r}"
            )
    target = target or float
    takes_rounds = until is not None and _n_positional(until) >= 2  # (surrogate) alone: the older form
    seeds = np.random.SeedSequence(seed).spawn(int(n_rounds))
    fit_pool = executor if parallel_fits else None
    seconds = {"fit": 0.0, "runs": 0.0, "until": 0.0, "propose": 0.0}
    clock = time.perf_counter()

    def lap(part):
        nonlocal clock
        now = time.perf_counter()
        seconds[part] += now - clock
        clock = now

    sur, n_ok = _fit(surrogate_factory, X, y, executor=fit_pool)
    lap("fit")
    rounds = [
        {
            "round": 0,
            "n_train": n_ok,
            "n_failed": len(X) - n_ok,
            "X_new": X.copy(),
            "y_new": y.copy(),
            "results": None,
            "surrogate": sur,
        }
    ]
    for r in range(1, int(n_rounds) + 1):
        stop = until is not None and (until(sur, rounds) if takes_rounds else until(sur))
        lap("until")
        if stop:
            break
        rng = np.random.default_rng(seeds[r - 1])
        cand = candidates(sur, rng) if callable(candidates) else candidates
        cand_seed = int(rng.integers(2**63)) if isinstance(cand, (int, np.integer)) else None
        X_new = propose_points(
            sur,
            cand,
            weight_from_surrogate(sur),
            int(batch),
            seed=cand_seed,
            min_distance=min_distance,
            log_weight=log_weight,
            power=power,
        )
        lap("propose")
        results = evaluate(func, list(X_new), executor=executor, progress=progress)
        lap("runs")
        y_new = np.array([target(res) for res in results], dtype=float)
        y_pred = np.column_stack([s.mean_transformed(X_new) for s in as_list(sur)])
        if y_new.shape[1:] != y.shape[1:]:
            raise ValueError(f"target gave values of shape {y_new.shape[1:]}, y has {y.shape[1:]}")
        X, y = np.vstack([X, X_new]), np.concatenate([y, y_new])
        sur, n_ok = _fit(surrogate_factory, X, y, previous=sur if warm_start else None, executor=fit_pool)
        lap("fit")
        rounds.append(
            {
                "round": r,
                "n_train": n_ok,
                "n_failed": len(X) - n_ok,
                "X_new": X_new,
                "y_new": y_new,
                "y_pred": y_pred if y.ndim == 2 else y_pred[:, 0],
                "results": results,
                "surrogate": sur,
            }
        )
    if warm_start and len(rounds) > 1:
        sur, _ = _fit(surrogate_factory, X, y, executor=fit_pool)
        rounds[-1]["surrogate"] = sur
        lap("fit")
    return RefinementResult(X=X, y=y, surrogate=sur, rounds=rounds, seconds=seconds)
