"""A sine sweep read frame by frame: the frames (Hann, half overlapping), the frequency f0
of each that holds one sine and the sweep's rate, the frame length under which its
harmonics can be read, and the window's correlation between bins (the noise's variance
over a window of bins).  What :func:`volterra.sweep_distortion` reads the harmonics on.

Frequencies Hz, times s, rates Hz/s, frame lengths in samples (powers of two).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import get_window, stft

from .distortion import TOP_SHARE

__all__ = [
    "LOBE",
    "MIN_FRAMES",
    "WINDOW",
    "best_frame",
    "bin_covariance",
    "first_frame",
    "frame_length",
    "frame_times",
    "frames_of",
    "readable",
    "spectra",
    "track",
]

#: a frame is a sine's when the input's peak (its main lobe) holds at least this share of its power
SINE_SHARE = 0.8
#: at least this many such frames, or the record is not a sweep
MIN_FRAMES = 8
#: and the frames at least this many cycles of their median f0 long
MIN_CYCLES = 8
#: the frames' window (a Blackman-Harris's 92 dB side lobes cost a main lobe twice as wide, which
#: at a GVT's 50 Hz left no third harmonic readable; with the linear response taken away in time
#: the fundamental's leakage is gone from the sensors)
WINDOW = "hann"
#: half-width of a harmonic's window in bins beyond its drift: a sine's Hann spectrum holds at least
#: 96 % of its power within one bin of its nearest (100 % on a bin, 97 % half-way)
LOBE = 1


def readable(f0, rate, T, k, fs):
    """Where harmonic ``k`` can be read with frames of ``T`` s: its window (the main lobe and
    the drift of k f0 over half a frame, w bins each side) half an f0 clear of the fundamental
    and the other harmonics (f0 at least 4 w + 2 bins: what the linear response leaves of the
    fundamental leaks a few bins; closer, a fast sweep over sharp modes read as harmonics),
    and below :data:`TOP_SHARE` of the sampling rate."""
    df = 1.0 / T
    w = LOBE + np.ceil(k * np.abs(rate) * T * T / 2)
    return ((k + 0.5) * f0 + (w + 1) * df < TOP_SHARE * fs) & (f0 / df >= 4 * w + 2)


def first_frame(u, fs: float) -> int:
    """The power-of-two frame under which the most of ``u``'s frames hold one sine (the longer
    of equals): a first look at a sweep of any rate, slow or fast."""
    sizes = sorted({frame_length(fs, u.size, 2.0**e / fs) for e in range(6, 24)})
    share = []
    for m in sizes:
        f0, _, _ = track(u, fs, m)
        # a frame of a few cycles resolves so little that band-limited noise reads as one sine
        sine = f0.size >= MIN_FRAMES and np.median(f0) * m / fs >= MIN_CYCLES
        share.append(f0.size * (m // 2) / u.size if sine else 0.0)
    return sizes[len(share) - 1 - int(np.argmax(share[::-1]))]


def best_frame(f0, rate, fs: float, n: int, weight) -> int:
    """The power-of-two frame under which harmonic 3 can be read where the response is
    largest (``f0``, ``rate``: a first track; ``weight``: the output's power at f0 there):
    long frames resolve the low f0, short ones follow a fast sweep."""
    sizes = sorted({frame_length(fs, n, 2.0**e / fs) for e in range(6, 24)})
    share = [np.sum(weight * readable(f0, rate, m / fs, 3, fs)) for m in sizes]
    return sizes[int(np.argmax(share))]


def frame_length(fs: float, n: int, seconds: float) -> int:
    """A power-of-two frame near ``seconds``, between 64 samples and an eighth of the record."""
    nper = 2 ** int(np.round(np.log2(max(seconds * fs, 64))))
    return int(min(max(nper, 64), 2 ** int(np.log2(max(n // 8, 64)))))


def frames_of(x, fs: float, nper: int):
    """(frequencies [Hz], (bins, frames)) of ``x``: frames of ``nper`` samples, half overlapping."""
    kw = dict(nperseg=nper, noverlap=nper // 2, boundary=None, padded=False, detrend=False)
    f, _, X = stft(x, fs=fs, window=WINDOW, **kw)
    return f, X


def frame_times(n_frames: int, nper: int, fs: float) -> np.ndarray:
    """The centre of each frame of :func:`_stft` [s]."""
    return (np.arange(n_frames) * (nper // 2) + nper / 2) / fs


def spectra(u, Y, fs, nper):
    f, U = frames_of(u, fs, nper)
    return f, U, [frames_of(Y[:, j], fs, nper)[1] for j in range(Y.shape[1])]


def bin_covariance(nper: int, m: int) -> float:
    """Var(sum of m adjacent bins' power) / (m mu^2) for white noise of mean bin power mu:
    ``(1/m) sum_{a, b} abs(rho(a - b))^2``, rho the window's correlation between bins l apart
    (``sum w^2 e^{-2 pi i l n / N} / sum w^2``)."""
    w2 = get_window(WINDOW, nper) ** 2
    lags = np.arange(-(m - 1), m)
    rho = np.abs(np.exp(-2j * np.pi * np.outer(lags, np.arange(nper)) / nper) @ w2) / w2.sum()
    return float(np.sum((m - np.abs(lags)) * rho**2) / m)


def track(u, fs, nper, spectra=None):
    """f0 [Hz] of the frames that hold one sine, their indices, and the sweep's rate [Hz/s]."""
    if spectra is None:
        f, U = frames_of(u, fs, nper)
    else:
        f, U = spectra
    P = np.abs(U) ** 2
    total = P[1:].sum(axis=0)
    peak = np.argmax(P[1:], axis=0) + 1
    lobe = np.array([P[max(p - LOBE, 1) : p + LOBE + 1, i].sum() for i, p in enumerate(peak)])
    loud = total > 1e-3 * np.median(total[total > 0]) if np.any(total > 0) else np.zeros_like(total, bool)
    keep = np.flatnonzero(loud & (lobe >= SINE_SHARE * np.where(total > 0, total, np.inf)) & (peak > LOBE))
    keep = keep[peak[keep] < P.shape[0] - LOBE - 1]
    if keep.size == 0:
        return np.zeros(0), keep, np.zeros(0)
    # the peak refined by a parabola through the log powers of its bin and neighbours
    p = peak[keep]
    a, b, c = (np.log(P[p + s, keep] + 1e-300) for s in (-1, 0, 1))
    den = a - 2 * b + c
    shift = np.where(den < 0, 0.5 * (a - c) / np.where(den < 0, den, -1.0), 0.0)
    f0 = (p + np.clip(shift, -0.5, 0.5)) * (f[1] - f[0])
    hop = (nper // 2) / fs
    rate = np.gradient(f0, keep * hop) if f0.size > 1 else np.zeros(1)
    return f0, keep, rate
