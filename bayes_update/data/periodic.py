"""Noise from the repeated periods of a periodic excitation.

A multisine generated with the acquisition's clock repeats exactly every
``N`` samples; after the structure's transient the response repeats too
(a mildly nonlinear structure included: its distortions are periodic).  What
differs from period to period is noise (Pintelon & Schoukens, System
Identification, 2012, sec. 2.4: the sample variance over the periods).

* :func:`find_periods` (:mod:`volterra.periods`, re-exported: the one period
  finder, which :func:`volterra.estimate_modes` uses too): where in a record
  the force repeats with a period ``N``, as a :class:`PeriodLayout`.
* :func:`period_noise`: one channel's noise sd from the chain: the periods
  the channel has settled in (:func:`volterra.periods.steady_periods`: the
  first, the structure's transient, dropped, and leading or trailing ones
  that still differ from the rest), then the deviations from the period mean
  with a linear trend removed per period (offsets and slow drifts differ
  from period to period), ``s^2 = RSS / ((P - 1)(N - 2))``: unbiased for
  noise whose correlation is short against the period.

Indices are samples; sd in the channel's unit per sample.
"""

from __future__ import annotations

import numpy as np

from volterra.periods import (
    DETREND_DEGREE,
    MAX_REPEAT_RATIO,
    MIN_PERIODS,
    PeriodLayout,
    detrended_rows,
    find_periods,
    steady_periods,
)

__all__ = ["PeriodLayout", "find_periods", "period_noise", "MIN_PERIODS", "MAX_REPEAT_RATIO"]


def period_noise(x, layout: PeriodLayout, detrend: int = DETREND_DEGREE):
    """Noise sd of one channel from the periods of ``layout``:
    ``(sd, dof, detail, spans)`` with ``spans`` the sample range of the periods
    used, or a sentence saying why not (fewer than two
    periods left after the transient).  ``detrend``: degree of the polynomial
    removed from each period's deviation (-1: none)."""
    x = np.asarray(x, float)
    N = layout.period
    Y = x[layout.start : layout.stop].reshape(layout.n_periods, N)
    first, last = steady_periods(x, layout, detrend)
    P = last - first
    if P < 2:
        return f"only {P} period(s) left after the transient"
    D = Y[first:last] - Y[first:last].mean(axis=0)
    R = detrended_rows(D, detrend)
    dof = (P - 1) * (N - (detrend + 1))
    sd = float(np.sqrt(np.sum(R**2) / dof))
    a = layout.start + first * N
    b = layout.start + last * N
    detail = (
        f"periods {first + 1}-{last} of {N} samples ({P} used from sample {a}"
        f"{', period detected in the force' if not layout.declared else ''}"
        f"{_trend_note(detrend)})"
    )
    return sd, float(dof), detail, ((a, b),)


def _trend_note(detrend: int) -> str:
    """How a period's trend was removed, for the estimate's detail."""
    if detrend < 0:
        return ""
    return ", a linear trend removed per period" if detrend == 1 else f", a degree-{detrend} trend removed per period"
