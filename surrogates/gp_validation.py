"""Checks of a surrogate against data: well-formed points (:func:`check_X`) and
accuracy at held-out points (:func:`validation_metrics`, :func:`holdout_validation`).

Apart from :mod:`surrogates.gp` because they need no Gaussian process: any surrogate
with ``fit`` and ``score`` is validated the same way.
"""

from __future__ import annotations

import numpy as np

__all__ = ["check_X", "holdout_validation", "validation_metrics"]


def check_X(X, d=None, what="X") -> np.ndarray:
    """``X`` as a finite (n, d) float array (a 1-D array as one column when d is 1), else a ValueError."""
    X = np.asarray(X, dtype=float)
    if X.ndim == 1 and d is not None and d == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise ValueError(f"{what} must have shape (n, d), got shape {X.shape}")
    if d is not None and X.shape[1] != d:
        raise ValueError(f"{what} has {X.shape[1]} columns, the surrogate has {d} inputs")
    if not np.all(np.isfinite(X)):
        raise ValueError(f"{what} contains non-finite values")
    return X


def validation_metrics(y_true, y_pred, low, high) -> dict:
    """Accuracy of predictions against true values, all arrays (n,).

    Returns ``n``, ``median_rel_error`` and ``max_rel_error`` of
    ``|y_pred - y_true| / |y_true|``, and ``coverage``: the fraction of
    ``y_true`` inside ``[low, high]`` (about the band's level if the
    predictive sd is calibrated).
    """
    y_true, y_pred = np.asarray(y_true, float), np.asarray(y_pred, float)
    low, high = np.asarray(low, float), np.asarray(high, float)
    if not (y_true.shape == y_pred.shape == low.shape == high.shape) or y_true.ndim != 1:
        raise ValueError("y_true, y_pred, low and high must be 1-D arrays of one length")
    if y_true.size == 0:
        raise ValueError("no points to validate on")
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(y_pred - y_true) / np.abs(y_true)
    return {
        "n": int(y_true.size),
        "median_rel_error": float(np.median(rel)),
        "max_rel_error": float(np.max(rel)),
        "coverage": float(np.mean((y_true >= low) & (y_true <= high))),
    }


def holdout_validation(gp_factory, X, y, fraction: float = 0.25, seed=0, level: float = 0.95) -> dict:
    """Fit a fresh surrogate on a random part of ``(X, y)`` and score it on the rest.

    Parameters
    ----------
    gp_factory : callable with no argument returning an unfitted surrogate
        (e.g. ``lambda: GPSurrogate(bounds, seed=0)``).
    X, y : (n, d) points and (n,) values.
    fraction : share of points held out (at least one point each side).
    seed : seeds the split.
    level : level of the predictive band whose coverage is reported.

    Returns
    -------
    dict: ``n_train``, ``n_test``, ``median_rel_error``, ``max_rel_error``,
    ``coverage`` (fraction of held-out values inside the ``level`` band),
    ``level``, ``surrogate`` (the fitted one) and ``test_index``.
    """
    X = check_X(X)
    y = np.asarray(y, dtype=float)
    if y.shape != (len(X),):
        raise ValueError(f"y must have shape ({len(X)},), got {y.shape}")
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must be in (0, 1), got {fraction}")
    n_test = int(round(fraction * len(X)))
    if n_test < 1 or len(X) - n_test < 2:
        raise ValueError(f"fraction={fraction} of {len(X)} points leaves no test point or < 2 training points")
    perm = np.random.default_rng(seed).permutation(len(X))
    test, train = np.sort(perm[:n_test]), np.sort(perm[n_test:])
    sur = gp_factory().fit(X[train], y[train])
    return {
        "n_train": len(train),
        "n_test": n_test,
        **sur.score(X[test], y[test], level),
        "surrogate": sur,
        "test_index": test,
    }
