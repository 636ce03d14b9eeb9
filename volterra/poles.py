"""Pole selection for the Kautz basis.

* :func:`pole_from_modal`: from a natural frequency [Hz] and damping ratio
  (e.g. the FE model's modal analysis of the linearised structure).
* :func:`pole_from_frf`: from data, the peak and half-power width of an H1
  FRF estimate (:func:`estimate_h1`) of a low-level (essentially linear)
  record.
* :func:`refine_pole`: polish a pole by minimising the relative residual of
  a least-squares fit (Nelder-Mead on log frequency and log damping).

The pole matters most when J1 is small: on linear data a pole frequency off by
a quarter of the half-power half-width (0.25 zeta fn) costs 13-17 % of H1 near
resonance at J1 = 2, 2-2.5 % at J1 = 4 and 0.3-0.4 % at J1 = 8.  A refined
pole from a low-level record is accurate enough for J1 = 2.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.optimize import minimize
from scipy.signal import csd, welch

from ._validation import paired_records
from .basis import KautzBasis
from .kautz import KautzPole

__all__ = ["pole_from_modal", "estimate_h1", "pole_from_frf", "refine_pole"]


def pole_from_modal(freq_hz: float, damping_ratio: float, fs: float) -> KautzPole:
    """Kautz pole of a mode: natural frequency ``freq_hz`` [Hz], damping ratio
    ``damping_ratio`` [-], sampling rate ``fs`` [Hz]."""
    return KautzPole.from_modal(freq_hz, damping_ratio, fs)


def estimate_h1(u, y, fs: float, nperseg: int | None = None, window="boxcar",
                nfft: int | None = None):
    """H1 FRF estimate ``H1(f) = S_uy(f) / S_uu(f)`` (scipy.signal.csd / welch).

    Parameters
    ----------
    u, y : 1-D arrays or lists of records (input, output), sampled at ``fs`` Hz.
    nperseg : int, optional
        Segment length [samples].  Default: the whole record, which suits a
        transient test (chirp + free decay, starting and ending near rest)
        with the default rectangular window.  For stationary random
        excitation pass e.g. ``nperseg=1024, window="hann"``.
    window : str or tuple, default "boxcar"
    nfft : int, optional
        FFT length (zero padding); default 8x the next power of two of the
        segment, for a finely sampled curve around the peak.

    Returns
    -------
    f : ndarray  frequencies [Hz], 0 .. fs/2
    H : ndarray  complex FRF [y unit / u unit]
    """
    us, ys, _ = paired_records(u, y)
    seg = [int(nperseg) if nperseg is not None else r.size for r in us]
    for k, (r, n) in enumerate(zip(us, seg)):
        if n < 8 or n > r.size:
            raise ValueError(f"nperseg = {n} is not valid for record {k} of {r.size} samples")
    if nfft is None:
        nfft = 8 * (1 << int(math.ceil(math.log2(max(seg)))))
    Suy = 0.0
    Suu = 0.0
    for r_u, r_y, n in zip(us, ys, seg):
        f, puy = csd(r_u, r_y, fs=fs, window=window, nperseg=n, nfft=nfft, detrend=False)
        _, puu = welch(r_u, fs=fs, window=window, nperseg=n, nfft=nfft, detrend=False)
        Suy = Suy + puy
        Suu = Suu + puu
    with np.errstate(divide="ignore", invalid="ignore"):
        H = Suy / Suu
    return f, H


def _crossing(f, a, k_from, k_to, target):
    """Walk from k_from towards k_to until a < target; interpolate linearly."""
    step = 1 if k_to > k_from else -1
    for k in range(k_from, k_to + step, step):
        if a[k] < target:
            k0 = k - step
            t = (a[k0] - target) / (a[k0] - a[k])
            return f[k0] + t * (f[k] - f[k0])
    return None


def pole_from_frf(u, y, fs: float, f_range=None, nperseg: int | None = None, window="boxcar",
                  nfft: int | None = None, return_details: bool = False):
    """Pole from the peak and half-power width of an H1 FRF estimate.

    ``fn = f_peak``, ``zeta = (f_hi - f_lo) / (2 f_peak)`` where f_lo, f_hi are
    the half-power points (|H|^2 = |H_peak|^2 / 2).  Exact for the mobility
    (velocity output) of a single mode; for displacement output the peak is at
    ``fn sqrt(1 - 2 zeta^2)`` (negligible at light damping).  Use a low-level
    record; refine with :func:`refine_pole` if J1 = 2 is intended.

    Parameters
    ----------
    u, y, fs, nperseg, window, nfft : see :func:`estimate_h1`.
    f_range : (f_min, f_max) in Hz, optional
        Band that contains the resonance of interest (default: (0, fs/2)].
    return_details : bool
        Also return a dict with ``f``, ``H``, ``f_peak``, ``f_lo``, ``f_hi``.
    """
    f, H = estimate_h1(u, y, fs, nperseg=nperseg, window=window, nfft=nfft)
    lo, hi = (0.0, fs / 2) if f_range is None else (float(f_range[0]), float(f_range[1]))
    if not lo < hi:
        raise ValueError(f"f_range must be (f_min, f_max) with f_min < f_max, got {f_range!r}")
    band = np.flatnonzero((f > lo) & (f <= hi) & np.isfinite(H))
    if band.size < 3:
        raise ValueError(f"f_range {f_range!r} holds fewer than 3 frequency lines; widen it")
    a = np.abs(H)
    kp = band[np.argmax(a[band])]
    f_peak, a_peak = float(f[kp]), float(a[kp])
    if band[0] < kp < band[-1]:
        # parabolic interpolation of the peak between frequency lines
        am, a0, ap = a[kp - 1], a[kp], a[kp + 1]
        curv = am - 2.0 * a0 + ap
        if curv < 0:
            delta = 0.5 * (am - ap) / curv
            f_peak = float(f[kp] + delta * (f[kp + 1] - f[kp]))
            a_peak = float(a0 - 0.25 * (am - ap) * delta)
    target = a_peak / math.sqrt(2.0)
    f_lo = _crossing(f, a, kp, band[0], target)
    f_hi = _crossing(f, a, kp, band[-1], target)
    if f_lo is None or f_hi is None:
        raise ValueError(
            f"half-power points of the peak at {f[kp]:.3f} Hz not found inside f_range "
            f"({lo:g}, {hi:g}) Hz; widen f_range or use a record whose spectrum covers the resonance"
        )
    zeta = (f_hi - f_lo) / (2.0 * f_peak)
    pole = KautzPole.from_modal(f_peak, zeta, fs)
    if return_details:
        return pole, dict(f=f, H=H, f_peak=f_peak, f_lo=f_lo, f_hi=f_hi)
    return pole


def refine_pole(u, y, pole: KautzPole, n_functions=(2,), ridge: float = 0.0, orders=None,
                xatol: float = 1e-7, maxiter: int = 400) -> KautzPole:
    """Refine a (common) pole by minimising the relative fit residual.

    Nelder-Mead over ``(log f, log zeta)`` starting at ``pole``; each step
    fits :func:`volterra.fit_volterra` with ``KautzBasis(pole, n_functions)``.
    Default: a linear fit with J1 = 2, which is the most pole-sensitive and
    therefore the sharpest criterion; use a low-level record.

    Returns the refined KautzPole.
    """
    from .model import fit_volterra

    us, ys, _ = paired_records(u, y)
    fs = pole.fs
    x0 = np.array([math.log(pole.freq_hz), math.log(pole.damping_ratio)])

    def cost(x):
        f, z = math.exp(x[0]), math.exp(x[1])
        if not (0 < z < 1) or f >= fs / 2:
            return np.inf
        try:
            basis = KautzBasis(KautzPole.from_modal(f, z, fs), n_functions)
            return fit_volterra(us, ys, basis, ridge=ridge, orders=orders).info.relative_residual
        except ValueError:
            return np.inf

    zeta = pole.damping_ratio
    simplex = np.array([x0, x0 + [0.5 * zeta, 0.0], x0 + [0.0, 0.3]])
    res = minimize(cost, x0, method="Nelder-Mead",
                   options=dict(initial_simplex=simplex, xatol=xatol, fatol=1e-12, maxiter=maxiter))
    x = res.x if np.isfinite(res.fun) and res.fun <= cost(x0) else x0
    return KautzPole.from_modal(math.exp(x[0]), math.exp(x[1]), fs)
