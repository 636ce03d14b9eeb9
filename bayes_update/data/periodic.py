"""Noise from the repeated periods of a periodic excitation.

A multisine generated with the acquisition's clock repeats exactly every
``N`` samples; after the structure's transient the response repeats too
(a mildly nonlinear structure included: its distortions are periodic).  What
differs from period to period is noise (Pintelon & Schoukens, System
Identification, 2012, sec. 2.4: the sample variance over the periods).

* :func:`find_periods`: where in a record the force repeats with a period
  ``N`` (declared, or detected from the force's autocorrelation), as a
  :class:`PeriodLayout`: the longest chain of consecutive periods whose
  period-to-period difference is at the force's noise level (each
  difference's mean over the period removed: a slow drift does not count).
* :func:`period_noise`: one channel's noise sd from the chain: the first
  period (the structure's transient) dropped, further leading periods
  dropped while their difference to the next is larger than the rest's (a
  transient not yet died out), then the deviations from the period mean
  with a linear trend removed per period (offsets and slow drifts differ
  from period to period), ``s^2 = RSS / ((P - 1)(N - 2))``: unbiased for
  noise whose correlation is short against the period.

Indices are samples; sd in the channel's unit per sample.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: a chain of periods is periodic where the period-to-period difference holds at most
#: this share of the force's energy (the repeating signal at least 20 dB above it) ...
MAX_REPEAT_RATIO = 0.01
#: ... and no more than this multiple of the best pair's share (so a period that runs
#: into a quiet section, or a transient of the force, breaks the chain)
REPEAT_TOLERANCE = 3.0
#: leading periods are dropped while their difference to the next one holds more
#: than this multiple of the median energy of the later differences
TRANSIENT_RATIO = 1.25
#: periods needed: one dropped (transient) and at least two compared
MIN_PERIODS = 3
#: autocorrelation peaks tried as period candidates when none is declared
N_CANDIDATES = 30
#: polynomial degree removed from each period's deviation (offsets, drifts)
DETREND_DEGREE = 1


@dataclass(frozen=True)
class PeriodLayout:
    """Where a record repeats: ``n_periods`` periods of ``period`` samples from sample
    ``start`` (the force repeats from each to the next); ``declared``: the period was
    given (``period_samples``), not detected; ``repeat_ratio``: the largest
    period-to-period difference of the force in the chain, as a share of its energy."""

    period: int
    start: int
    n_periods: int
    declared: bool
    repeat_ratio: float

    @property
    def stop(self) -> int:
        return self.start + self.period * self.n_periods


def _pair_ratios(f: np.ndarray, period: int) -> np.ndarray:
    """Q[k] (k = 0 .. n - 2N): the energy of the difference between the period
    starting at k and the next, over their energy, each with its mean over the
    period removed (so a slow drift, nearly constant over a period's
    difference, does not count)."""
    n, N = f.size, period
    m = n - 2 * N + 1
    if m < 1:
        return np.zeros(0)

    def window_sums(x):
        c = np.concatenate([[0.0], np.cumsum(x)])
        return c[N:N + m] - c[:m]

    e = f[N:] - f[:-N]
    num = window_sums(e * e) - window_sums(e) ** 2 / N
    den = (window_sums(f[:-N] ** 2) - window_sums(f[:-N]) ** 2 / N
           + window_sums(f[N:] ** 2) - window_sums(f[N:]) ** 2 / N)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, np.clip(num, 0.0, None) / den, np.inf)


def _best_chain(f: np.ndarray, period: int):
    """(start, n_periods, worst ratio) of the longest chain of repeating periods
    (ties: the smallest summed ratio), or None."""
    Q = _pair_ratios(f, period)
    if Q.size == 0 or not np.isfinite(Q).any():
        return None
    q_min = float(np.min(Q))
    if q_min > MAX_REPEAT_RATIO:
        return None
    thr = min(MAX_REPEAT_RATIO, REPEAT_TOLERANCE * q_min + 1e-15)
    rows = -(-Q.size // period)
    Q2 = np.full(rows * period, np.inf)
    Q2[:Q.size] = Q
    Q2 = Q2.reshape(rows, period)                    # column s: the pairs starting at s, s + N, ...
    good = Q2 <= thr
    csum = np.cumsum(np.where(good, Q2, 0.0), axis=0)
    run = np.zeros(period, int)
    length = np.zeros(period, int)
    end = np.zeros(period, int)
    for r in range(rows):
        run = np.where(good[r], run + 1, 0)
        longer = run > length
        length[longer], end[longer] = run[longer], r
    if length.max() == 0:
        return None
    cols = np.flatnonzero(length == length.max())
    first = end[cols] - length[cols] + 1
    total = csum[end[cols], cols] - np.where(first > 0, csum[np.maximum(first - 1, 0), cols], 0.0)
    k = int(np.argmin(total))
    s0, r0, n = int(cols[k]), int(first[k]), int(length[cols[k]])
    worst = float(np.max(Q2[r0:r0 + n, s0]))
    return s0 + r0 * period, n + 1, worst


def _candidates(f: np.ndarray, max_period: int) -> list:
    """Lags of the highest local maxima of the force's normalised autocorrelation,
    beyond its main lobe, up to ``max_period``."""
    n = f.size
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    F = np.fft.rfft(f, nfft)
    r = np.fft.irfft(np.abs(F) ** 2, nfft)[:n]
    c = np.cumsum(f ** 2)
    lags = np.arange(n)
    head = c[n - 1 - lags]                       # sum f[:n-L]^2
    tail = c[-1] - np.concatenate([[0.0], c[:-1]])[lags]   # sum f[L:]^2
    with np.errstate(divide="ignore", invalid="ignore"):
        rn = r / np.sqrt(head * tail)
    below = np.flatnonzero(rn < 0.5)
    if below.size == 0:
        return []
    lo = max(int(below[0]), 2)
    hi = min(max_period, n - 1)
    if hi <= lo + 1:
        return []
    seg = rn[lo:hi + 1]
    peaks = np.flatnonzero((seg[1:-1] > seg[:-2]) & (seg[1:-1] >= seg[2:]) & (seg[1:-1] > 0.2)) + 1 + lo
    return [int(p) for p in peaks[np.argsort(rn[peaks])[::-1][:N_CANDIDATES]]]


def find_periods(force, period_samples: int | None = None):
    """The :class:`PeriodLayout` of a record's force, or a sentence saying why there is none.

    ``period_samples``: the declared period [samples]; None looks for one in
    the force (peaks of its autocorrelation; the one whose periods repeat
    best, or an integer fraction of it that repeats as well).  Needs at least
    :data:`MIN_PERIODS` repeating periods.
    """
    f = np.asarray(force, float)
    t = np.linspace(-1.0, 1.0, f.size)
    f = f - np.polyval(np.polyfit(t, f, 2), t)           # offset and slow drift
    if period_samples is not None:
        period = int(period_samples)
        if f.size < MIN_PERIODS * period:
            return (f"the record holds {f.size / period:.1f} periods of {period} samples; "
                    f"at least {MIN_PERIODS} are needed (the first is a transient)")
        chain = _best_chain(f, period)
        if chain is None or chain[1] < MIN_PERIODS:
            found = "no two consecutive periods" if chain is None else f"only {chain[1]} consecutive periods"
            return (f"the force does not repeat with the declared period of {period} samples "
                    f"({found} agree to within {MAX_REPEAT_RATIO:.0%} of its energy; is the "
                    "generator clocked with the acquisition?)")
        return PeriodLayout(period, chain[0], chain[1], True, chain[2])
    found = []
    for lag in _candidates(f, f.size // MIN_PERIODS):
        chain = _best_chain(f, lag)
        if chain is not None and chain[1] >= MIN_PERIODS:
            found.append(PeriodLayout(lag, chain[0], chain[1], False, chain[2]))
    if not found:
        return "no period_samples declared and no period found in the force (no exact repetition)"
    best = min(found, key=lambda p: p.repeat_ratio)
    # a multiple of the period repeats as well as the period itself: prefer its divisor
    divisors = [p for p in found if best.period % p.period == 0
                and p.repeat_ratio <= 1.5 * best.repeat_ratio + 1e-15]
    return min(divisors, key=lambda p: p.period)


def _detrended(D: np.ndarray, degree: int) -> np.ndarray:
    """Each row minus its least-squares polynomial of ``degree`` in the sample index."""
    if degree < 0:
        return D
    t = np.linspace(-1.0, 1.0, D.shape[1])
    V = np.vander(t, degree + 1)
    coef, *_ = np.linalg.lstsq(V, D.T, rcond=None)
    return D - (V @ coef).T


def period_noise(x, layout: PeriodLayout, detrend: int = DETREND_DEGREE):
    """Noise sd of one channel from the periods of ``layout``:
    ``(sd, dof, detail, spans)`` with ``spans`` the sample range of the periods
    used, or a sentence saying why not (fewer than two
    periods left after the transient).  ``detrend``: degree of the polynomial
    removed from each period's deviation (-1: none)."""
    x = np.asarray(x, float)
    N = layout.period
    Y = x[layout.start:layout.stop].reshape(layout.n_periods, N)
    first = 1                                        # the structure's transient
    while layout.n_periods - first >= 3:
        d = _detrended(np.diff(Y[first:], axis=0), detrend)
        E = np.sum(d ** 2, axis=1)
        if E[0] > TRANSIENT_RATIO * np.median(E[1:]):
            first += 1
        else:
            break
    P = layout.n_periods - first
    if P < 2:
        return f"only {P} period(s) left after the transient"
    D = Y[first:] - Y[first:].mean(axis=0)
    R = _detrended(D, detrend)
    dof = (P - 1) * (N - (detrend + 1))
    sd = float(np.sqrt(np.sum(R ** 2) / dof))
    a = layout.start + first * N
    detail = (f"periods {first + 1}-{layout.n_periods} of {N} samples ({P} used from sample {a}"
              f"{', period detected in the force' if not layout.declared else ''}"
              f"{'' if detrend < 0 else ', a linear trend removed per period' if detrend == 1 else f', a degree-{detrend} trend removed per period'})")
    return sd, float(dof), detail, ((a, layout.stop),)
