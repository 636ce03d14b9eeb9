"""Where a record repeats: the period of a periodic excitation, found in the input.

A multisine generated with the acquisition's clock repeats exactly every
``N`` samples; after the structure's transient the response repeats too (a
mildly nonlinear structure included: its distortions are periodic).  Both
the data layer (the noise from the period-to-period scatter) and
:func:`volterra.estimate_modes` (period-synchronous spectra) read a record
through this one finder.

* :func:`find_periods`: where a record's input repeats with a period ``N``
  (declared, or detected from the input's autocorrelation), as a
  :class:`PeriodLayout`: the longest chain of consecutive periods whose
  period-to-period difference is at most 5 % of their energy (each
  difference's mean over the period removed: a slow drift does not count),
  holding at least half of the input's energy (a sweep's or a sine step's
  few similar cycles are not a periodic excitation).
* :func:`steady_periods`: which periods of the chain a channel has settled
  in: leading periods are dropped while their difference to the next one
  holds more energy than the others' (the structure's transient), trailing
  ones likewise (a record cut as the excitation stops).

Indices are samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["PeriodLayout", "find_periods", "steady_periods", "MIN_PERIODS"]

#: a chain of periods is periodic where the period-to-period difference holds at most this
#: share of the input's energy: an input with 13 dB of noise still repeats (a force at 20 dB
#: repeats to 1 %; a random input differs by about 100 % from any lag) ...
MAX_REPEAT_RATIO = 0.05
#: ... and no more than this multiple of the best pair's share (so a period that runs
#: into a quiet section, or a transient of the input, breaks the chain)
REPEAT_TOLERANCE = 3.0
#: the chain holds at least this share of the input's energy (its offset and slow
#: drift removed): the excitation repeats, not a few cycles of it
MIN_ENERGY_SHARE = 0.5
#: leading (trailing) periods are dropped while their difference to the next (previous)
#: one holds more than this multiple of the median energy of the other differences
TRANSIENT_RATIO = 1.25
#: periods needed: one dropped (transient) and at least two compared
MIN_PERIODS = 3
#: autocorrelation peaks tried as period candidates when none is declared
N_CANDIDATES = 30
#: polynomial degree removed from each period's difference when judging steadiness
DETREND_DEGREE = 1


@dataclass(frozen=True)
class PeriodLayout:
    """Where a record repeats: ``n_periods`` periods of ``period`` samples from sample
    ``start`` (the input repeats from each to the next); ``declared``: the period was
    given (``period_samples``), not detected; ``repeat_ratio``: the largest
    period-to-period difference of the input in the chain, as a share of its energy."""

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
        return c[N : N + m] - c[:m]

    e = f[N:] - f[:-N]
    num = window_sums(e * e) - window_sums(e) ** 2 / N
    den = (
        window_sums(f[:-N] ** 2) - window_sums(f[:-N]) ** 2 / N + window_sums(f[N:] ** 2) - window_sums(f[N:]) ** 2 / N
    )
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
    Q2[: Q.size] = Q
    Q2 = Q2.reshape(rows, period)  # column s: the pairs starting at s, s + N, ...
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
    worst = float(np.max(Q2[r0 : r0 + n, s0]))
    return s0 + r0 * period, n + 1, worst


def _with_leading(f: np.ndarray, period: int, chain):
    """``chain`` with the period before it joined as its first, when the chain is one
    period short of :data:`MIN_PERIODS` and that period repeats within
    :data:`MAX_REPEAT_RATIO`: a record of three periods from rest, whose first
    holds the input's own start-up (an anti-alias filter's, a generator's) and so
    differs more than :data:`REPEAT_TOLERANCE` x the others, is still periodic; its
    first period is the transient :func:`steady_periods` drops anyway.  The
    ratio reported is the steady pair's."""
    if chain is None or chain[1] != MIN_PERIODS - 1:
        return chain
    # the start, at most a period before the chain's, where the first pair (the start-up) and the
    # second (steady) repeat best together: a lead of zero force or a trailing rest stays outside
    Q = _pair_ratios(f, period)
    k = np.arange(max(0, chain[0] - period), min(chain[0], Q.size - 1 - period) + 1)
    if k.size == 0:
        return chain
    ok = (Q[k] <= MAX_REPEAT_RATIO) & (Q[k + period] <= MAX_REPEAT_RATIO)
    if not ok.any():
        return chain
    start = int(k[ok][np.argmin((Q[k] + Q[k + period])[ok])])
    return start, MIN_PERIODS, float(Q[start + period])


def _candidates(f: np.ndarray, max_period: int) -> list:
    """Lags of the highest local maxima of the input's normalised autocorrelation,
    beyond its main lobe, up to ``max_period`` (inclusive: a record of exactly
    three periods has its period there)."""
    n = f.size
    nfft = 1 << int(np.ceil(np.log2(2 * n)))
    F = np.fft.rfft(f, nfft)
    r = np.fft.irfft(np.abs(F) ** 2, nfft)[:n]
    c = np.cumsum(f**2)
    lags = np.arange(n)
    head = c[n - 1 - lags]  # sum f[:n-L]^2
    tail = c[-1] - np.concatenate([[0.0], c[:-1]])[lags]  # sum f[L:]^2
    with np.errstate(divide="ignore", invalid="ignore"):
        rn = r / np.sqrt(head * tail)
    below = np.flatnonzero(rn < 0.5)
    if below.size == 0:
        return []
    lo = max(int(below[0]), 2)
    hi = min(max_period, n - 2)
    if hi <= lo:
        return []
    seg = rn[lo - 1 : hi + 2]  # one lag either side: the ends may be maxima
    peaks = np.flatnonzero((seg[1:-1] > seg[:-2]) & (seg[1:-1] >= seg[2:]) & (seg[1:-1] > 0.2)) + lo
    return [int(p) for p in peaks[np.argsort(rn[peaks])[::-1][:N_CANDIDATES]]]


def _share(f: np.ndarray, start: int, stop: int) -> float:
    total = float(np.sum(f * f))
    return float(np.sum(f[start:stop] ** 2)) / total if total > 0 else 0.0


def find_periods(u, period_samples: int | None = None):
    """The :class:`PeriodLayout` of a record's input ``u``, or a sentence saying why there is none.

    ``period_samples``: the declared period [samples]; None looks for one in
    the input (peaks of its autocorrelation; the one whose periods repeat
    best, or an integer fraction of it that repeats as well).  Needs at least
    :data:`MIN_PERIODS` repeating periods holding :data:`MIN_ENERGY_SHARE`
    of the input's energy.
    """
    f = np.asarray(u, float)
    t = np.linspace(-1.0, 1.0, f.size)
    f = f - np.polyval(np.polyfit(t, f, 2), t)  # offset and slow drift
    if period_samples is not None:
        period = int(period_samples)
        if f.size < MIN_PERIODS * period:
            return (
                f"the record holds {f.size / period:.1f} periods of {period} samples; "
                f"at least {MIN_PERIODS} are needed (the first is a transient)"
            )
        chain = _with_leading(f, period, _best_chain(f, period))
        if chain is None or chain[1] < MIN_PERIODS:
            found = "no two consecutive periods" if chain is None else f"only {chain[1]} consecutive periods"
            return (
                f"the force does not repeat with the declared period of {period} samples "
                f"({found} agree to within {MAX_REPEAT_RATIO:.0%} of its energy; is the "
                "generator clocked with the acquisition?)"
            )
        return PeriodLayout(period, chain[0], chain[1], True, chain[2])
    found = []
    for lag in _candidates(f, f.size // MIN_PERIODS):
        chain = _with_leading(f, lag, _best_chain(f, lag))
        if (
            chain is not None
            and chain[1] >= MIN_PERIODS
            and _share(f, chain[0], chain[0] + lag * chain[1]) >= MIN_ENERGY_SHARE
        ):
            found.append(PeriodLayout(lag, chain[0], chain[1], False, chain[2]))
    if not found:
        return "no period_samples declared and no period found in the force (no exact repetition)"
    best = min(found, key=lambda p: p.repeat_ratio)
    # a multiple of the period repeats as well as the period itself: prefer its divisor
    divisors = [p for p in found if best.period % p.period == 0 and p.repeat_ratio <= 1.5 * best.repeat_ratio + 1e-15]
    return min(divisors, key=lambda p: p.period)


def detrended_rows(D: np.ndarray, degree: int) -> np.ndarray:
    """Each row minus its least-squares polynomial of ``degree`` in the sample index."""
    if degree < 0:
        return D
    t = np.linspace(-1.0, 1.0, D.shape[1])
    V = np.vander(t, degree + 1)
    coef, *_ = np.linalg.lstsq(V, D.T, rcond=None)
    return D - (V @ coef).T


def steady_periods(x, layout: PeriodLayout, detrend: int = DETREND_DEGREE) -> tuple[int, int]:
    """``(first, last)``: the periods ``first .. last - 1`` of ``layout`` (0-based) in
    which channel ``x`` (1-D, or (n, S): every column) has settled: period 0 (the
    structure's transient) always dropped, further leading periods dropped while
    their difference to the next holds more than :data:`TRANSIENT_RATIO` x the
    median energy of the later differences, trailing periods likewise (each
    difference with a polynomial of ``detrend`` removed: offsets and slow drifts
    differ from period to period).  ``last - first`` may be below 2."""
    x = np.asarray(x, float)
    x = x[:, None] if x.ndim == 1 else x
    N, P = layout.period, layout.n_periods
    Y = x[layout.start : layout.stop].T.reshape(x.shape[1], P, N)
    E = np.sum(
        [
            np.sum(detrended_rows(np.diff(Yc, axis=0), detrend) ** 2, axis=1) / max(float(np.sum(Yc**2)), 1e-300)
            for Yc in Y
        ],
        axis=0,
    )  # (P - 1,): pair j = j, j + 1
    first, last = 1, P
    while last - first >= 3 and E[first] > TRANSIENT_RATIO * np.median(E[first + 1 : last - 1]):
        first += 1
    while last - first >= 3 and E[last - 2] > TRANSIENT_RATIO * np.median(E[first : last - 2]):
        last -= 1
    return first, last
