"""One pole for the Kautz basis (the previous estimator, kept for single-mode use).

:meth:`volterra.KautzBasis.from_data` now estimates every mode of a record
with :func:`volterra.estimate_modes` (:mod:`volterra.modes`); this module
keeps the one-pole tools:

* :func:`pole_from_modal`: from a natural frequency [Hz] and damping ratio
  (e.g. the FE model's modal analysis of the linearised structure).
* :func:`pole_from_frf`: from data, the peak and half-power width of an
  averaged H1 FRF estimate (:func:`volterra.estimate_h1`) of a low-level
  (essentially linear) record, searched only where the input has energy and
  the coherence is meaningful.
* :func:`refine_pole`: polish a pole by minimising the relative residual of
  a least-squares fit (bounded Nelder-Mead on log frequency and log damping,
  inside a stated neighbourhood of the start).

Both estimators remove each record's mean first, so offsets of the sensors do
not pull the pole to DC.  What they cannot return a usable pole for (a peak or
a refined pole at DC or Nyquist, a damping ratio at its bound, a linear fit
that explains too little of the record) raises :class:`PoleEstimationError`
saying what to check.

The pole matters most when J1 is small: on linear data a pole frequency off by
a quarter of the half-power half-width (0.25 zeta fn) costs 13-17 % of H1 near
resonance at J1 = 2, 2-2.5 % at J1 = 4 and 0.3-0.4 % at J1 = 8.  A refined
pole from a low-level record is accurate enough for J1 = 2.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize

from ._validation import paired_records
from .basis import KautzBasis
from .fit import fit_volterra
from .frf import _segment_lengths, estimate_h1, excited_band
from .kautz import KautzPole
from .modes import PoleEstimationError

__all__ = ["PoleEstimationError", "pole_from_modal", "pole_from_frf", "refine_pole"]

#: Default lowest coherence of the lines an FRF peak is searched on.
MIN_COHERENCE = 0.3
#: Default largest relative residual ||y - y_fit|| / ||y|| of a refined linear fit.
MAX_RESIDUAL = 0.5
#: A usable pole has at least this many periods in the record ...
MIN_PERIODS = 3.0
#: ... and a frequency below this fraction of the sampling rate.
MAX_FREQ_FRACTION = 0.45
#: refine_pole's neighbourhood: frequency within f0 (1 +- max(FREQ_SPAN_ZETAS zeta0, MIN_FREQ_SPAN)) ...
FREQ_SPAN_ZETAS = 4.0
MIN_FREQ_SPAN = 0.05
#: ... and damping ratio within [zeta0 / DAMPING_FACTOR, min(zeta0 DAMPING_FACTOR, MAX_DAMPING)].
DAMPING_FACTOR = 10.0
MAX_DAMPING = 0.95


def pole_from_modal(freq_hz: float, damping_ratio: float, fs: float) -> KautzPole:
    """Kautz pole of a mode: natural frequency ``freq_hz`` [Hz], damping ratio
    ``damping_ratio`` [-], sampling rate ``fs`` [Hz]."""
    return KautzPole.from_modal(freq_hz, damping_ratio, fs)


def _centred(u, y):
    us, ys, _ = paired_records(u, y)
    return [r - r.mean() for r in us], [r - r.mean() for r in ys]


def _check_usable(freq_hz: float, zeta: float, fs: float, n_samples: int, what: str) -> None:
    """Raise if a pole is at DC or Nyquist for this record, or (nearly) critically damped."""
    if freq_hz * n_samples / fs < MIN_PERIODS:
        raise PoleEstimationError(
            f"{what} at {freq_hz:.4g} Hz: fewer than {MIN_PERIODS:g} periods in the record "
            f"({n_samples / fs:.4g} s), i.e. at DC. Check the output for an offset or a slow drift "
            "(remove it), and give f_range around the resonance."
        )
    if freq_hz > MAX_FREQ_FRACTION * fs:
        raise PoleEstimationError(
            f"{what} at {freq_hz:.4g} Hz, above {MAX_FREQ_FRACTION:g} fs = {MAX_FREQ_FRACTION * fs:.4g} Hz "
            "(Nyquist). Check that the input excites the resonance and give f_range around it."
        )
    if zeta >= MAX_DAMPING:
        raise PoleEstimationError(
            f"{what} at {freq_hz:.4g} Hz has a damping ratio of {zeta:.3g} (>= {MAX_DAMPING:g}): no "
            "resonance there. Check f_range and that the record excites a mode."
        )


def _check_resolved(width_hz: float, f_peak: float, resolution_hz: float) -> None:
    """Raise if a peak is narrower than the FRF's frequency resolution: the
    window broadens every spectral feature to at least about one line spacing
    fs / nperseg (a resonance in a leakage-free transient estimate is wider
    still), so a narrower peak is a noise spike of the ratio S_uy / S_uu."""
    if width_hz < resolution_hz:
        raise PoleEstimationError(
            f"the H1 peak at {f_peak:.4g} Hz is {width_hz:.3g} Hz wide, narrower than the frequency "
            f"resolution {resolution_hz:.3g} Hz: a noise spike, not a resonance. Check that y is the "
            "response to u, the noise level, and f_range."
        )


def _crossing(f, a, k_from, k_to, target):
    """Walk from k_from towards k_to until a < target; interpolate linearly."""
    step = 1 if k_to > k_from else -1
    for k in range(k_from, k_to + step, step):
        if a[k] < target:
            k0 = k - step
            t = (a[k0] - target) / (a[k0] - a[k])
            return f[k0] + t * (f[k] - f[k0])
    return None


def _peak(f, a, band, kp):
    """(f_peak, a_peak): parabolic interpolation between frequency lines."""
    f_peak, a_peak = float(f[kp]), float(a[kp])
    if band[0] < kp < band[-1]:
        am, a0, ap = a[kp - 1], a[kp], a[kp + 1]
        curv = am - 2.0 * a0 + ap
        if curv < 0:
            delta = 0.5 * (am - ap) / curv
            f_peak = float(f[kp] + delta * (f[kp + 1] - f[kp]))
            a_peak = float(a0 - 0.25 * (am - ap) * delta)
    return f_peak, a_peak


def _search_band(f_range, us, fs, nperseg):
    if f_range is None:
        return excited_band(us, fs, nperseg=nperseg)
    lo, hi = float(f_range[0]), float(f_range[1])
    if not lo < hi:
        raise ValueError(f"f_range must be (f_min, f_max) with f_min < f_max, got {f_range!r}")
    return lo, hi


def pole_from_frf(
    u,
    y,
    fs: float,
    f_range=None,
    nperseg: int | None = None,
    window="hann",
    nfft: int | None = None,
    min_coherence: float = MIN_COHERENCE,
    return_details: bool = False,
):
    """Pole from the peak and half-power width of an averaged H1 FRF estimate.

    ``fn = f_peak``, ``zeta = (f_hi - f_lo) / (2 f_peak)`` where f_lo, f_hi are
    the half-power points (``|H|^2 = |H_peak|^2 / 2``).  Exact for the mobility
    (velocity output) of a single mode; for displacement output the peak is at
    ``fn sqrt(1 - 2 zeta^2)`` (negligible at light damping).  Each record's
    mean is removed first.  The window and the segment length broaden the
    peak: the damping ratio is biased high when a segment is not much longer
    than the decay time ``1 / (2 pi zeta fn)`` (by 70-150 % on a 4 s chirp
    record at 1.3-2 % damping with the default segments).  Use a low-level
    record and :func:`refine_pole` (as :meth:`KautzBasis.from_data` does).

    Parameters
    ----------
    u, y, fs, nperseg, window, nfft : see :func:`volterra.estimate_h1`.
    f_range : (f_min, f_max) in Hz, optional
        Band that contains the resonance of interest.  Default: the band where
        the input has energy, :func:`volterra.excited_band` (robust to an input
        offset; the whole 0 .. fs/2 for white noise).
    min_coherence : float
        The peak is searched only on lines of the band whose coherence is at
        least this (default 0.3; pure output noise averages about
        1 / (number of segments) = 0.14 with the default segments).  The
        half-power points may lie on any line of the band.
    return_details : bool
        Also return a dict with ``f``, ``H``, ``coherence``, ``band``,
        ``f_peak``, ``f_lo``, ``f_hi``.

    Raises
    ------
    PoleEstimationError
        No line of the band has the coherence, the half-power points are not
        inside the band, the peak is narrower than the frequency resolution
        (a noise spike), or it is at DC or Nyquist.
    """
    us, ys = _centred(u, y)
    f, H, coh = estimate_h1(us, ys, fs, nperseg=nperseg, window=window, nfft=nfft, return_coherence=True)
    lo, hi = _search_band(f_range, us, fs, nperseg)
    band = np.flatnonzero((f > lo) & (f <= hi) & np.isfinite(H))
    if band.size < 3:
        raise ValueError(f"f_range {(lo, hi)!r} Hz holds fewer than 3 frequency lines; widen it")
    coherent = band[coh[band] >= min_coherence]
    if coherent.size == 0:
        raise PoleEstimationError(
            f"no frequency line in ({lo:.4g}, {hi:.4g}) Hz has a coherence of {min_coherence:g} or more "
            f"(largest {coh[band].max():.3g}): the output does not follow the input there. Check that "
            "y is the response to u (channels, units, synchronisation), the noise level, and f_range."
        )
    a = np.abs(H)
    kp = int(coherent[np.argmax(a[coherent])])
    f_peak, a_peak = _peak(f, a, band, kp)
    target = a_peak / math.sqrt(2.0)
    f_lo = _crossing(f, a, kp, band[0], target)
    f_hi = _crossing(f, a, kp, band[-1], target)
    if f_lo is None or f_hi is None:
        raise PoleEstimationError(
            f"half-power points of the peak at {f[kp]:.3f} Hz not found inside the band "
            f"({lo:g}, {hi:g}) Hz; widen f_range or use a record whose spectrum covers the resonance "
            "(a peak at the band's low edge: check y for a slow drift)"
        )
    _check_resolved(f_hi - f_lo, f_peak, fs / max(_segment_lengths(us, nperseg)))
    zeta = (f_hi - f_lo) / (2.0 * f_peak)
    _check_usable(f_peak, zeta, fs, min(r.size for r in us), "the H1 peak")
    pole = KautzPole.from_modal(f_peak, zeta, fs)
    if return_details:
        return pole, dict(f=f, H=H, coherence=coh, band=(lo, hi), f_peak=f_peak, f_lo=f_lo, f_hi=f_hi)
    return pole


def refine_bounds(pole: KautzPole) -> tuple[tuple[float, float], tuple[float, float]]:
    """The neighbourhood :func:`refine_pole` searches around ``pole``:
    ``((f_min, f_max) [Hz], (zeta_min, zeta_max))`` with
    ``f0 / (1 + s) <= f <= f0 (1 + s)``, ``s = max(4 zeta0, 0.05)``, and
    ``zeta0 / 10 <= zeta <= min(10 zeta0, 0.95)``.

    Wide enough for the start errors of :func:`pole_from_frf` (a fraction of
    the half-power width in frequency; a damping ratio broadened by the
    window), narrow enough that the search cannot run to DC or Nyquist."""
    f0, z0 = pole.freq_hz, pole.damping_ratio
    span = max(FREQ_SPAN_ZETAS * z0, MIN_FREQ_SPAN)
    f_hi = min(f0 * (1.0 + span), MAX_FREQ_FRACTION * pole.fs)
    return (f0 / (1.0 + span), f_hi), (z0 / DAMPING_FACTOR, min(z0 * DAMPING_FACTOR, MAX_DAMPING))


def _at_bound(x, lo, hi, tol=5e-3):
    """'lower' / 'upper' if x is within tol (relative to the box width) of a bound."""
    w = hi - lo
    if x - lo <= tol * w:
        return "lower"
    if hi - x <= tol * w:
        return "upper"
    return None


def refine_pole(
    u,
    y,
    pole: KautzPole,
    n_functions=(2,),
    ridge: float = 0.0,
    orders=None,
    xatol: float = 1e-7,
    maxiter: int = 400,
    max_residual: float = MAX_RESIDUAL,
    feedthrough: bool = True,
) -> KautzPole:
    """Refine a (common) pole by minimising the relative fit residual.

    Bounded Nelder-Mead over ``(log f, log zeta)`` inside the neighbourhood
    :func:`refine_bounds` of ``pole``; each step fits
    :func:`volterra.fit_volterra` (with h0) with ``KautzBasis(pole,
    n_functions)`` to the records with their means removed.  Default: a
    linear fit with J1 = 2, which is the most pole-sensitive and therefore the
    sharpest criterion; use a low-level record.

    Parameters
    ----------
    u, y : 1-D arrays or lists of records; sampled at ``pole.fs`` [Hz].
    pole : KautzPole
        Start, e.g. from :func:`pole_from_frf`.
    n_functions, ridge, orders, feedthrough : as :class:`KautzBasis` /
        :func:`volterra.fit_volterra`.
    xatol, maxiter : Nelder-Mead options (xatol on log f and log zeta).
    max_residual : float
        Largest acceptable relative residual ``||y - y_fit|| / ||y||`` of the
        refined fit (default 0.5: the fit must explain 75 % of the energy).

    Returns the refined KautzPole.

    Raises
    ------
    PoleEstimationError
        The start is at DC or Nyquist; the refined pole is at an edge of the
        neighbourhood (frequency or damping ratio: the start is not near this
        record's resonance, or the record is not linear enough), at DC or
        Nyquist, or its fit leaves more than ``max_residual`` of the record
        unexplained.
    """
    us, ys = _centred(u, y)
    fs = pole.fs
    n_samples = min(r.size for r in us)
    _check_usable(pole.freq_hz, pole.damping_ratio, fs, n_samples, "refine_pole: the start")
    (f_min, f_max), (z_min, z_max) = refine_bounds(pole)
    bounds = np.log([[f_min, f_max], [z_min, z_max]])
    x0 = np.log([pole.freq_hz, pole.damping_ratio])

    def residual(x):
        basis = KautzBasis(KautzPole.from_modal(math.exp(x[0]), math.exp(x[1]), fs), n_functions, feedthrough)
        return fit_volterra(us, ys, basis, ridge=ridge, orders=orders).info.relative_residual

    def cost(x):
        try:
            return residual(x)
        except ValueError:
            return np.inf

    # first steps: half a half-power half-width in frequency, x1.35 in damping
    simplex = _initial_simplex(x0, bounds, (0.5 * pole.damping_ratio, 0.3))
    res = minimize(
        cost,
        x0,
        method="Nelder-Mead",
        bounds=bounds,
        options=dict(initial_simplex=simplex, xatol=xatol, fatol=1e-12, maxiter=maxiter),
    )
    x = res.x if np.isfinite(res.fun) and res.fun <= cost(x0) else x0
    refined = KautzPole.from_modal(math.exp(x[0]), math.exp(x[1]), fs)
    _check_refined(refined, pole, x, bounds, residual(x), max_residual, n_samples)
    return refined


def _initial_simplex(x0, bounds, steps):
    """Nelder-Mead start: x0 and one step along each axis, towards the inside of the bounds."""
    simplex = [x0]
    for k, step in enumerate(steps):
        x = x0.copy()
        x[k] += step if x0[k] + step <= bounds[k][1] else -step
        simplex.append(x)
    return np.array(simplex)


def _check_refined(refined, start, x, bounds, resid, max_residual, n_samples):
    """Raise unless the refined pole is inside its neighbourhood, usable, and explains the record."""
    for k, what in enumerate(("frequency", "damping ratio")):
        edge = _at_bound(x[k], *bounds[k])
        if edge is not None:
            lo, hi = (math.exp(b) for b in bounds[k])
            raise PoleEstimationError(
                f"refine_pole: the {what} ran to the {edge} edge of its search range "
                f"({lo:.4g} .. {hi:.4g}) around the start {start}: the start is not near this "
                "record's resonance, or the record is not essentially linear. Check f_range, offsets "
                "and slow drifts in u and y, that the record is low-level, and that one mode "
                "dominates the band."
            )
    _check_usable(refined.freq_hz, refined.damping_ratio, refined.fs, n_samples, "refine_pole: the refined pole")
    if not resid <= max_residual:
        raise PoleEstimationError(
            f"refine_pole: the refined linear fit leaves {100 * resid:.3g} % of ||y|| unexplained "
            f"(more than {100 * max_residual:.3g} %) with the pole {refined}: y does not follow u "
            "linearly. Check that y is the response to u, the noise level, slow drifts of y, that the "
            "record is low-level (not strongly nonlinear) and that one mode dominates (else narrow "
            "f_range or raise J1)."
        )
