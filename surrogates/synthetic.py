"""Synthetic test problems with a known answer, for tests and benchmarks.

:class:`CurvedValley` mimics the metrics the surrogates are built for: a
positive, valley-shaped relative error spanning decades, whose posterior
(``exp(-(e/e_min - 1)/2)``) is a thin curved band, here with a known closed
form to sample from.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["CurvedValley"]


@dataclass(frozen=True)
class CurvedValley:
    """``e(x) = floor * (1 + r^2 + q^2 + sum_j s_j^2)`` on the unit box [0, 1]^d, d >= 2.

    * ``r = (x1 - c(x0)) / width``, across a valley that follows the curve
      ``c(x0) = 0.5 + amplitude * sin(2 pi (x0 - 0.5))``;
    * ``q = (x0 - x0_opt) / length``, along it;
    * ``s_j = (x_j - 0.5) / spread`` for the remaining inputs j >= 2.

    The minimum ``floor`` is at ``x0 = x0_opt`` on the curve; far from the
    valley ``e`` is ``(1 / width)^2`` times larger (3.4 decades for the
    default width 1/50).  The density ``exp(-(e/floor - 1)/2)`` restricted to
    the box (:meth:`log_weight`) is Gaussian in (q, r, s), so
    :meth:`sample_posterior` draws from it exactly.  Instances are picklable
    (they can be sent to process pools).
    """

    d: int = 2
    width: float = 0.02
    amplitude: float = 0.25
    x0_opt: float = 0.6
    length: float = 0.15
    spread: float = 0.25
    floor: float = 0.01

    def __post_init__(self):
        if int(self.d) != self.d or self.d < 2:
            raise ValueError(f"d must be an integer >= 2, got {self.d!r}")
        for name in ("width", "length", "spread", "floor"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")

    @property
    def bounds(self) -> np.ndarray:
        """The unit box, (d, 2)."""
        return np.tile([0.0, 1.0], (self.d, 1))

    def curve(self, x0):
        return 0.5 + self.amplitude * np.sin(2 * np.pi * (np.asarray(x0, float) - 0.5))

    def _reduced(self, X):
        X = np.atleast_2d(np.asarray(X, float))
        if X.shape[-1] != self.d:
            raise ValueError(f"points must have {self.d} coordinates, got shape {X.shape}")
        r = (X[:, 1] - self.curve(X[:, 0])) / self.width
        q = (X[:, 0] - self.x0_opt) / self.length
        s = (X[:, 2:] - 0.5) / self.spread
        return r**2 + q**2 + np.sum(s**2, axis=1)

    def values(self, X) -> np.ndarray:
        """e at points X (n, d): array (n,)."""
        return self.floor * (1.0 + self._reduced(X))

    def __call__(self, x) -> float:
        """e at one point x (d,)."""
        return float(self.values(np.asarray(x, float)[None, :])[0])

    def log_weight(self, X) -> np.ndarray:
        """log of the (unnormalized) density ``exp(-(e/floor - 1)/2)`` in the box, -inf outside."""
        X = np.atleast_2d(np.asarray(X, float))
        inside = np.all((X >= 0) & (X <= 1), axis=1)
        return np.where(inside, -0.5 * self._reduced(X), -np.inf)

    def sample_posterior(self, n: int, seed=None) -> np.ndarray:
        """n exact draws (n, d) from the density of :meth:`log_weight` (rejection to the box)."""
        rng = np.random.default_rng(seed)
        out = np.empty((0, self.d))
        while len(out) < n:
            m = 2 * (n - len(out)) + 16
            x = np.empty((m, self.d))
            x[:, 0] = self.x0_opt + self.length * rng.standard_normal(m)
            x[:, 1] = self.curve(x[:, 0]) + self.width * rng.standard_normal(m)
            x[:, 2:] = 0.5 + self.spread * rng.standard_normal((m, self.d - 2))
            out = np.vstack([out, x[np.all((x >= 0) & (x <= 1), axis=1)]])
        return out[:n]
