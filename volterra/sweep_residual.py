"""What a sweep's record holds beyond its linear response, and where its noise went.

:func:`linear_response`: the record's own impulse response, deconvolved over the swept band
and kept over the lags a linear response has (a sweep's harmonics never land there), convolved
with the force; :func:`near_passage`: the frames whose noise went with that response (those
within the kept lags of the sweep's passage of a frequency), and, for a sweep down, those where
the modes it passed still ring.  What :func:`volterra.sweep_distortion` reads harmonics on.

Frequencies Hz, times and lags s, rates Hz/s.
"""

from __future__ import annotations

import numpy as np

__all__ = ["linear_response", "near_passage"]


def linear_response(u, y, fs: float, f0, rate) -> tuple[np.ndarray, float, float, float]:
    """The record's linear response, the lags [s] before and after its impulse response that
    were kept, and how long the impulse response rings [s] (where its envelope falls to 10x
    its floor, kept or not).

    The impulse response is read by deconvolution of the whole record over the swept band
    (``Y conj(U) / (abs(U)^2 + eps)``, zero-padded to twice its length), kept over the lags a linear
    structure's response has, then convolved with ``u``.  Deconvolved, a sweep's harmonics do
    not land where the linear impulse response is (Farina 2000): harmonic k at frequency f
    was made when the sweep was at f / k, so it shows at a lag of t(f) - t(f / k), at least
    ``f0_min / rate`` for a linear sweep (``rate`` [Hz/s] from the track ``f0`` [Hz]): at
    negative lags for a sweep up, at positive ones for a sweep down.  Kept: lags from -1 % of
    the record (filters' pre-ringing) to where the envelope has fallen to 10x its floor (the
    noise, spread over every lag: the noise the kept lags hold goes with the response, at
    frequency f over the times the sweep is within those lags of f, which
    :func:`volterra.sweep_distortion` leaves out of its noise), at most half the record, and for a sweep down
    0.8 f0_min / rate."""
    n = u.size
    nfft = 2 * n
    U, Yf = np.fft.rfft(u, nfft), np.fft.rfft(y, nfft)
    eps = 1e-6 * np.max(np.abs(U) ** 2)
    # the swept band only, faded over 5 % beyond it: outside it the force holds its noise alone,
    # and Y / U there is noise over noise, which the lags kept would spread in time
    freqs = np.fft.rfftfreq(nfft, 1.0 / fs)
    lo, hi = np.min(f0), np.max(f0)
    edge = 0.05 * lo, 0.05 * hi
    rise = np.clip((freqs - (lo - edge[0])) / edge[0], 0.0, 1.0)
    fall = np.clip(((hi + edge[1]) - freqs) / edge[1], 0.0, 1.0)
    band = (0.5 - 0.5 * np.cos(np.pi * rise)) * (0.5 - 0.5 * np.cos(np.pi * fall))
    h = np.fft.irfft(band * Yf * np.conj(U) / (np.abs(U) ** 2 + eps), nfft)
    pre = max(n // 100, 1)
    post = n // 2
    if np.median(rate) < 0:  # a sweep down: its harmonics at positive lags
        post = int(min(post, 0.8 * np.min(f0) / max(np.median(np.abs(rate)), 1e-12) * fs))
    # the envelope (a moving mean of h^2 over 1 % of the record) against its floor far out
    env = np.convolve(h[: post + 1] ** 2, np.ones(pre) / pre, mode="same")
    floor = np.median(h[n // 2 : nfft - n // 2] ** 2)
    above = np.flatnonzero(env > 10 * floor)
    ring = int(1.2 * (above[-1] + pre)) if above.size else pre
    post = min(post, ring)
    keep = np.zeros(nfft)
    keep[: post + 1] = 1.0
    keep[nfft - pre :] = 1.0
    return np.fft.irfft(np.fft.rfft(h * keep) * U, nfft)[:n], pre / fs, post / fs, ring / fs


def near_passage(f, times, f0, before: float, after: float) -> np.ndarray:
    """(bins, frames): frame ``times`` [s] from ``before`` s before to ``after`` s after the
    sweep (its track ``f0`` [Hz] at those times) passed each bin's frequency ``f`` [Hz]
    (bins outside the swept band: never)."""
    order = np.argsort(f0)
    inside = (f >= f0.min()) & (f <= f0.max())
    passed = np.interp(f, f0[order], times[order])
    lag = times[None, :] - passed[:, None]
    return inside[:, None] & (lag >= -before) & (lag <= after)
