"""What emcee and the surrogates evaluate: picklable log posteriors on model runs or on the
GP surrogates, in the internal coordinates or whitened by the Laplace covariance."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bayes_update.core.adjustment import CurvatureAdjustment
from bayes_update.core.likelihood import Likelihood
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.problem import Problem


# ------------------------------------------------------------ model callables
@dataclass
class Evaluate:
    """Picklable ``x (internal coordinates) -> metrics dict`` on the model."""

    problem: Problem
    space: ParameterSet
    stages: tuple

    def __call__(self, x):
        return self.problem.evaluate(self.space.to_parameters(np.asarray(x, float)), self.stages)


@dataclass
class DirectLogPosterior:
    """Picklable log posterior on direct model runs (emcee's ``log_prob_fn``)."""

    evaluate: Evaluate
    likelihood: Likelihood
    adjustment: CurvatureAdjustment | None = None

    def __call__(self, x):
        """(log posterior, per-stage log likelihood): emcee keeps the second as blobs."""
        stages = self.likelihood.stages
        lp = float(self.evaluate.space.log_prior(x)[0])
        if not np.isfinite(lp):
            return -np.inf, np.full(len(stages), -np.inf)
        if self.adjustment is not None:
            # the likelihood's argument, kept in the bounding box the model is run in (near a
            # bound it may step outside; a -inf there would cut the posterior at the bound)
            box = self.evaluate.space.box()
            x = np.clip(self.adjustment(x)[0], box[:, 0], box[:, 1])
        metrics = self.evaluate(x)
        per_stage = np.array([Likelihood({st: self.likelihood.scales[st]}).log_likelihood(metrics) for st in stages])
        return lp + float(np.sum(per_stage)), per_stage


class ExecutorPool:
    """The ``map`` emcee wants, on a concurrent.futures executor."""

    def __init__(self, executor, chunks_per_worker: int = 1):
        self.executor = executor
        self.workers = getattr(executor, "_max_workers", None) or 2
        self.chunks = chunks_per_worker

    def map(self, func, iterable):
        items = list(iterable)
        chunk = max(1, math.ceil(len(items) / (self.workers * self.chunks)))
        try:
            return list(self.executor.map(func, items, chunksize=chunk))
        except TypeError:  # executors without chunksize
            return list(self.executor.map(func, items))


@dataclass
class SurrogateLogPosterior:
    """Vectorised log posterior from GP means of z per stage (restricted to ``box``)."""

    gps: dict  # stage -> fitted GPSurrogate of z
    space: ParameterSet
    box: np.ndarray

    def __call__(self, X):
        X = np.atleast_2d(X)
        lp = self.space.log_prior(X)
        inside = np.all((X >= self.box[:, 0]) & (X <= self.box[:, 1]), axis=1) & np.isfinite(lp)
        out = np.full(len(X), -np.inf)
        if inside.any():
            z = {st: gp.mean_transformed(X[inside]) for st, gp in self.gps.items()}
            out[inside] = lp[inside] + Likelihood.log_likelihood_from_z(z)
        return out


@dataclass(frozen=True)
class Whitening:
    """Affine map x = center + L u from coordinates u in which the Laplace
    approximation is a standard normal.  The GPs live in u: the posterior's
    valleys are diagonal in x (c and k_s trade off, correlation -0.96 on the
    default data), and an axis-aligned kernel fits a diagonal valley badly
    (measured: median error of e_nlin at posterior draws 25 % in x, 4 % in u,
    same 256 runs)."""

    center: np.ndarray
    L: np.ndarray

    @classmethod
    def from_covariance(cls, center, cov) -> "Whitening":
        w, V = np.linalg.eigh(cov)
        return cls(np.asarray(center, float), V * np.sqrt(np.maximum(w, 1e-300)))

    def to_x(self, U):
        return self.center + np.atleast_2d(U) @ self.L.T

    def to_u(self, X):
        return np.linalg.solve(self.L, (np.atleast_2d(X) - self.center).T).T


@dataclass
class WhitenedEvaluate:
    """``u -> metrics`` for the surrogate stage; points outside the prior are
    not run (NaN metrics), since they carry no posterior mass."""

    evaluate: Evaluate
    whitening: Whitening

    def __call__(self, u):
        x = self.whitening.to_x(np.asarray(u, float))[0]
        if not np.isfinite(self.evaluate.space.log_prior(x)[0]):
            out = {Likelihood.key(st): math.nan for st in self.evaluate.stages}
            out["error"] = "outside the prior box"
            return out
        return self.evaluate(x)


@dataclass
class WhitenedLogPosterior:
    """Vectorised log posterior on u from GP means of z per stage (restricted
    to the u ``box`` and the prior)."""

    gps: dict
    space: ParameterSet
    box: np.ndarray
    whitening: Whitening
    adjustment: CurvatureAdjustment | None = None

    def gp_points(self, U) -> np.ndarray:
        """Where the GPs are read for the parameters U: U itself, or the
        adjusted likelihood's argument (an affine map of U: x(u), the adjustment
        and u(x) are each affine, so it is folded into one matrix and offset)."""
        U = np.atleast_2d(U)
        if self.adjustment is None:
            return U
        if getattr(self, "_affine", None) is None:

            def composed(V):
                return self.whitening.to_u(self.adjustment(self.whitening.to_x(V)))

            offset = composed(np.zeros((1, U.shape[1])))[0]
            self._affine = (composed(np.eye(U.shape[1])) - offset, offset)  # rows: images of the unit vectors
        M, offset = self._affine
        return U @ M + offset

    def __call__(self, U):
        U = np.atleast_2d(U)
        lp = self.space.log_prior(self.whitening.to_x(U))
        G = self.gp_points(U)
        # the GPs are read where they were trained (the u box); the adjusted argument G
        # may lie a little outside the prior near a bound, where the GP is still smooth
        inside = np.all((G >= self.box[:, 0]) & (G <= self.box[:, 1]), axis=1) & np.isfinite(lp)
        if inside.all():  # the usual step: no copies of the walkers inside
            return lp + Likelihood.log_likelihood_from_z({st: gp.mean_transformed(G) for st, gp in self.gps.items()})
        out = np.full(len(U), -np.inf)
        if inside.any():
            z = {st: gp.mean_transformed(G[inside]) for st, gp in self.gps.items()}
            out[inside] = lp[inside] + Likelihood.log_likelihood_from_z(z)
        return out
