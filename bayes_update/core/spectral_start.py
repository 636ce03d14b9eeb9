"""A start for stage 1 of the two-stage search in the right valley of a lightly damped
structure: :func:`spectral_start` (used by the coarse start of ``sample`` and
``discrepancy``, :mod:`bayes_update.core.two_stage`).

Stage 1 fits the linear parameters on e_lin from the best point of a small Sobol'
design over the prior.  The output error of a lightly damped mode has a valley only
about one half-power half-width (zeta f) wide on each side in frequency: where no design point
falls inside it, the best point by e_lin is a wrong valley, and least squares from it
ends there (the portal frame's full rig: the sway mode at 11 Hz, zeta 3 %, 16 points
whose frequencies span 9-13 Hz; stage 1 ended at a cost of 2.0e5 where the right valley
has 4.3, and the posterior's MAP then climbed out in about 100 model runs).

The design's runs say more than their e_lin: where each puts the response's energy in
frequency.  The quantiles of the response's energy over the excited lines (the
frequency below which 5 %, 10 %, ..., 95 % of it lies) move smoothly with the
parameters, far beyond the valley: their logarithms are regressed linearly on the
design's internal coordinates, and the point whose predicted quantiles match the
measured ones (bounded least squares over the quantiles the regression explains, inside
the span of the nearest design points) is a start at the right frequencies.  Used only
where the design's best point is more than :data:`GATE_HALF_WIDTHS` half-power
half-widths from the measured quantiles (so the search is unchanged wherever the design
already found the valley) and when the point itself, run, is closer to them than that
best point; each such run joins the regression, at most three.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

__all__ = ["GATE_HALF_WIDTHS", "QUANTILES", "SpectralCost", "energy_quantiles", "spectral_start"]

#: the levels of the cumulative energy whose frequencies are compared
QUANTILES = np.linspace(0.05, 0.95, 19)
#: a quantile enters the match only where the linear regression explains this share of its
#: variance over the design (above the structure's modes, a quantile jumps from one mode to the
#: next as a parameter moves: the frame's upper quantiles had R^2 0.2-0.3, its lower 0.9-0.98)
MIN_R2 = 0.8
#: the spectral start is used where the design's best point misses the measured quantiles by
#: more than this many half-power half-widths (zeta of the measured modes, relative), rms in log
#: frequency: a search must start within about one half-width of a mode to end in its valley
#: (the frame's coarse start: its best point 0.059 off for zeta 0.031 ended in the wrong one)
GATE_HALF_WIDTHS = 1.0
#: lines whose force energy is at least this share of the largest line's are the excited ones
EXCITED_SHARE = 1e-3


def energy_quantiles(force, response, fs: float, weights=None) -> np.ndarray:
    """log f [log Hz] below which each share :data:`QUANTILES` of the response's energy lies,
    over the lines the force excites (its energy at least :data:`EXCITED_SHARE` of the
    largest line's).  ``response`` (n,) or (n, n_sensors); ``weights``: per sensor, e.g.
    1 / its noise sd, so that no sensor's unit outweighs another's."""
    u = np.asarray(force, float)
    y = np.asarray(response, float)
    y = y[:, None] if y.ndim == 1 else y
    w = np.ones(y.shape[1]) if weights is None else np.asarray(weights, float)
    U = np.abs(np.fft.rfft(u - u.mean())) ** 2
    Y = (np.abs(np.fft.rfft(y - y.mean(axis=0), axis=0)) ** 2) @ (w**2)
    f = np.fft.rfftfreq(u.size, 1.0 / fs)
    lines = (U >= EXCITED_SHARE * U.max()) & (f > 0)
    c = np.cumsum(Y[lines])
    if not c[-1] > 0:
        return np.full(QUANTILES.size, np.nan)
    return np.log(np.interp(QUANTILES, c / c[-1], f[lines]))


@dataclass(frozen=True)
class SpectralCost:
    """Picklable ``x -> (1/2 ||r(x)||^2, energy quantiles)`` of a stage-1 residual function
    (one linear test: its response's quantiles, :func:`energy_quantiles`); inf and NaN where
    the model raised ModelError."""

    fun: object  # a ResidualFunction on the linear stage(s)

    def __call__(self, x):
        fun = self.fun
        r, responses = fun.with_responses(x)
        if any(y is None for y in responses):
            return math.inf, np.full(QUANTILES.size, np.nan)
        problem, stage = fun.problem, fun.stages[0]
        weights = 1.0 / np.asarray(problem.sensor_noise(stage), float)
        q = energy_quantiles(problem.tests[stage].force, problem.compared_response(responses[0]), problem.fs, weights)
        return 0.5 * float(r @ r), q


def measured_quantiles(problem, stage: str) -> np.ndarray:
    """:func:`energy_quantiles` of the stage's recorded test."""
    test = problem.tests[stage]
    weights = 1.0 / np.asarray(problem.sensor_noise(stage), float)
    return energy_quantiles(test.force, test.response, problem.fs, weights)


def spectral_start(X, costs, quantiles, measured, lower, upper, half_width: float):
    """``(x or None, report)``: the point of the box [lower, upper] whose quantiles, by a linear
    regression of the design's (``X`` (n, d) internal coordinates, ``quantiles`` (n, 19)),
    match ``measured``, where the design's best point by cost misses them by more than
    :data:`GATE_HALF_WIDTHS` x ``half_width`` (zeta of the measured modes, rms in log f);
    None where it does not, or where the regression explains too few quantiles."""
    X, Q = np.asarray(X, float), np.asarray(quantiles, float)
    ok = np.isfinite(np.asarray(costs, float)) & np.all(np.isfinite(Q), axis=1)
    report = {}
    if ok.sum() < X.shape[1] + 3:
        return None, report
    X, Q, costs = X[ok], Q[ok], np.asarray(costs, float)[ok]
    best = int(np.argmin(costs))
    A = np.column_stack([np.ones(len(X)), X])
    res = Q - A @ np.linalg.lstsq(A, Q, rcond=None)[0]
    spread = np.sum((Q - Q.mean(axis=0)) ** 2, axis=0)
    r2 = 1.0 - np.sum(res**2, axis=0) / np.where(spread > 0, spread, np.inf)
    keep = r2 >= MIN_R2
    misses = np.sqrt(np.mean((Q[:, keep] - measured[keep]) ** 2, axis=1)) if keep.any() else np.zeros(len(X))
    report.update(keep=keep, best_miss=float(misses[best]), gate=GATE_HALF_WIDTHS * half_width)
    if keep.sum() < 3 or misses[best] <= GATE_HALF_WIDTHS * half_width:
        return None, report
    # the points near the measured quantiles weigh most (the quantiles are not linear in the
    # parameters over a whole prior: a joint in series with a member saturates), each quantile
    # by its regression's scatter; along directions the quantiles do not see (a stiffness and a
    # mass that trade in a frequency) the point stays nearest the best one, a pull of one scatter
    # per prior width
    rows = 1.0 / (misses + half_width)
    B = np.linalg.lstsq(A * rows[:, None], Q * rows[:, None], rcond=None)[0]
    w = 1.0 / np.sqrt(np.average((Q - A @ B)[:, keep] ** 2, axis=0, weights=rows**2) + 1e-12)
    width = np.asarray(upper, float) - np.asarray(lower, float)
    A_fit = np.vstack([B[1:, keep].T * w[:, None], np.diag(1.0 / width)])
    b_fit = np.concatenate([(measured[keep] - B[0, keep]) * w, X[best] / width])
    # no extrapolation: the point stays within the span of the design points nearest the
    # measured quantiles (the 2 d + 1 of least miss), where the regression has seen the model
    near = X[np.argsort(misses)[: 2 * X.shape[1] + 1]]
    lo = np.maximum(lower, near.min(axis=0))
    hi = np.minimum(upper, near.max(axis=0))
    return lsq_linear(A_fit, b_fit, bounds=(lo, hi)).x, report
