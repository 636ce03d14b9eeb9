"""Space-filling designs of experiments in a box.

A box is given as ``bounds``, an array-like of shape (d, 2) whose rows are
``(low, high)`` in the caller's units.  Designs come back in those units; a
log-scaled or otherwise transformed axis is the caller's business (design in
the transformed coordinates, then map back).
"""

from __future__ import annotations

import inspect
import warnings

import numpy as np
from scipy.stats import qmc

__all__ = ["DESIGN_METHODS", "check_bounds", "design", "from_unit", "to_unit"]

DESIGN_METHODS = ("sobol", "lhs", "random")


def check_bounds(bounds) -> np.ndarray:
    """``bounds`` as a float array of shape (d, 2), rows ``(low, high)``,
    finite and with ``low < high``; raises ``ValueError`` otherwise."""
    b = np.array(bounds, dtype=float)  # a copy: callers may mutate theirs
    if b.ndim != 2 or b.shape[1] != 2 or b.shape[0] == 0:
        raise ValueError(f"bounds must have shape (d, 2) with rows (low, high), got shape {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError("bounds must be finite")
    bad = np.flatnonzero(~(b[:, 0] < b[:, 1]))
    if bad.size:
        raise ValueError(f"bounds need low < high; violated on axes {bad.tolist()}: {b[bad].tolist()}")
    return b


def to_unit(X, bounds) -> np.ndarray:
    """Map points (n, d) from the box to the unit cube [0, 1]^d."""
    b = check_bounds(bounds)
    X = np.asarray(X, dtype=float)
    return (X - b[:, 0]) / (b[:, 1] - b[:, 0])


def from_unit(U, bounds) -> np.ndarray:
    """Map points (n, d) from the unit cube [0, 1]^d to the box."""
    b = check_bounds(bounds)
    U = np.asarray(U, dtype=float)
    return b[:, 0] + U * (b[:, 1] - b[:, 0])


def _qmc_engine(cls, d, rng, **kw):
    # scipy >= 1.15 calls the seed argument ``rng``; older versions ``seed``
    key = "rng" if "rng" in inspect.signature(cls.__init__).parameters else "seed"
    return cls(d, **kw, **{key: rng})


def design(bounds, n: int, method: str = "sobol", seed=None) -> np.ndarray:
    """A space-filling design of ``n`` points in the box ``bounds``.

    Parameters
    ----------
    bounds : array-like (d, 2), rows ``(low, high)`` in the caller's units.
    n : number of points (>= 1).
    method : ``"sobol"`` (scrambled Sobol' sequence, the default: the best
        uniformity for a given n, and a design of n points is the start of the
        one of 2n points, so a DOE can be extended), ``"lhs"`` (Latin
        hypercube: exactly one point in each of n slices of every axis), or
        ``"random"`` (independent uniform points; a baseline for comparisons).
    seed : int, ``numpy.random.Generator`` or None.  The same int gives the
        same points; None draws fresh entropy.

    Returns
    -------
    ndarray (n, d) in the units of ``bounds``.

    Notes
    -----
    Sobol' points are best balanced when ``n`` is a power of two; other ``n``
    are allowed (the first ``n`` points of the sequence) and scipy's warning
    about it is silenced.
    """
    b = check_bounds(bounds)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    n, d = int(n), b.shape[0]
    if method == "sobol":
        eng = _qmc_engine(qmc.Sobol, d, seed, scramble=True)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*balance properties of Sobol.*")
            u = eng.random(n)
    elif method == "lhs":
        u = _qmc_engine(qmc.LatinHypercube, d, seed).random(n)
    elif method == "random":
        u = np.random.default_rng(seed).random((n, d))
    else:
        raise ValueError(f"method must be one of {DESIGN_METHODS}, got {method!r}")
    return from_unit(u, b)
