"""Averaged FRF estimate and the band in which it means something.

* :func:`estimate_h1`: ``H1(f) = S_uy(f) / S_uu(f)`` and the magnitude-squared
  coherence ``|S_uy|^2 / (S_uu S_yy)`` from Welch averages (Hann window, half
  overlapping segments, each segment's mean removed).  A single-segment ratio
  Y/U is never the default: on random excitation it peaks wherever the input
  spectrum of that one segment has a near-zero.
* :func:`excited_band`: the band where the input has energy, from the input's
  averaged PSD with its mean removed (so that a DC offset of the input sensor
  does not become the "peak" that collapses the band to 0 Hz).
* :func:`periodic_h1`: H1 of a periodic excitation (multisine) from
  period-synchronous FFTs, the transient first period dropped: no window, no
  leakage on the excited lines.

Frequencies in Hz.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.signal import csd, welch

from ._validation import as_record_list, paired_records

__all__ = ["estimate_h1", "excited_band", "default_nperseg", "periodic_h1"]

#: a sweep's power spectrum crosses this share of its level (half its amplitude) at its first and
#: last frequencies (the Fresnel edge): the level to which :func:`excited_band` widens Welch's band
SWEEP_EDGE = 0.25
#: Default number of half-overlapping segments a record is cut into (Welch).
DEFAULT_SEGMENTS = 7


def default_nperseg(n_samples: int) -> int:
    """Default Welch segment length [samples] for a record of ``n_samples``:
    the record cut into :data:`DEFAULT_SEGMENTS` half-overlapping segments
    (``2 N / (K + 1)``), at least 8 samples."""
    return max(8, (2 * int(n_samples)) // (DEFAULT_SEGMENTS + 1))


def _segment_lengths(records, nperseg):
    seg = [default_nperseg(r.size) if nperseg is None else int(nperseg) for r in records]
    for k, (r, n) in enumerate(zip(records, seg)):
        if n < 8 or n > r.size:
            raise ValueError(f"nperseg = {n} is not valid for record {k} of {r.size} samples")
    return seg


def _welch_kw(fs, window, n, nfft):
    # detrend="constant": every segment's mean is removed (offsets, slow drifts)
    return dict(fs=fs, window=window, nperseg=n, noverlap=n // 2, nfft=nfft, detrend="constant")


def estimate_h1(
    u, y, fs: float, nperseg: int | None = None, window="hann", nfft: int | None = None, return_coherence: bool = False
):
    """H1 FRF estimate ``H1(f) = S_uy(f) / S_uu(f)`` from Welch averages.

    Parameters
    ----------
    u, y : 1-D arrays or lists of records (input, output), sampled at ``fs`` Hz.
        Spectra of several records are averaged together.
    fs : float
        Sampling rate [Hz].
    nperseg : int, optional
        Segment length [samples]; segments overlap by half and each has its
        mean removed.  Default :func:`default_nperseg` (7 segments per
        record).  Longer segments resolve a sharper peak but average less;
        ``nperseg = len(u)`` with ``window="boxcar"`` is the single-segment
        estimate, leakage free only for a transient test that starts and ends
        at rest.
    window : str or tuple, default "hann"
    nfft : int, optional
        FFT length (zero padding); default 8x the next power of two of the
        segment, for a finely sampled curve around the peak.
    return_coherence : bool
        Also return the magnitude-squared coherence.

    Returns
    -------
    f : ndarray  frequencies [Hz], 0 .. fs/2
    H : ndarray  complex FRF [y unit / u unit] (NaN where S_uu = 0)
    coherence : ndarray  [-], only if ``return_coherence``
    """
    us, ys, _ = paired_records(u, y)
    seg = _segment_lengths(us, nperseg)
    if nfft is None:
        nfft = 8 * (1 << int(math.ceil(math.log2(max(seg)))))
    Suy = Suu = Syy = 0.0
    for r_u, r_y, n in zip(us, ys, seg):
        kw = _welch_kw(fs, window, n, nfft)
        f, puy = csd(r_u, r_y, **kw)
        Suy = Suy + puy
        Suu = Suu + welch(r_u, **kw)[1]
        Syy = Syy + welch(r_y, **kw)[1]
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.where(Suu > 0, Suy / Suu, np.nan)
        coh = np.where((Suu > 0) & (Syy > 0), np.abs(Suy) ** 2 / (Suu * Syy), 0.0)
    if return_coherence:
        return f, H, np.clip(coh, 0.0, 1.0)
    return f, H


def excited_band(u, fs: float, level: float = 0.01, nperseg: int | None = None) -> tuple[float, float]:
    """(f_min, f_max) [Hz]: where the input's PSD exceeds ``level`` x its peak.

    The PSD is a Welch average (Hann, half-overlapping segments of
    ``nperseg`` samples, default :func:`default_nperseg`) of the input with
    every segment's linear trend removed, and the two lowest resolved lines
    (below ``2 fs / nperseg``, inside the window's main lobe around DC) are
    left out: an input offset, however large, does not move the band, nor
    does a slow drift of the input sensor.  The window tapers the record's
    first and last half segment, which for a sweep are its first and last
    frequencies: the band is widened on each side over the lines next to it
    where the whole record's periodogram stays above :data:`SWEEP_EDGE` of
    its peak (a chirp 20 -> 60 Hz that starts at full amplitude at t = 0
    and stops abruptly: (20.2, 64.8) Hz, Welch's alone (21.6, 64.8)); for broadband noise it
    can be the whole 0 .. fs/2 (then the coherence, see
    :func:`volterra.pole_from_frf`, is what restricts an FRF peak search).

    Parameters
    ----------
    u : 1-D array or list of records (PSDs averaged), sampled at ``fs`` [Hz].
    level : float
        Fraction of the PSD peak (0 < level < 1), default 1 % (-20 dB).
    nperseg : int, optional
        Segment length [samples].
    """
    if not 0 < level < 1:
        raise ValueError(f"level must be in (0, 1), got {level!r}")
    records, _ = as_record_list(u, "u")
    seg = _segment_lengths(records, nperseg)
    n = max(seg)
    total = 0.0
    for r, m in zip(records, seg):
        # a slow drift of the input sensor puts its power into the lowest lines, at any level
        # against the excitation's: each segment's linear trend removed, not only its mean
        f, p = welch(r, **{**_welch_kw(fs, "hann", m, n), "detrend": "linear"})
        total = total + p
    resolved = f >= 2.0 * fs / n
    if not np.any(total[resolved] > 0):
        raise ValueError("the input has no energy above DC (is u constant?)")
    band = f[resolved & (total >= level * total[resolved].max())]
    lo, hi = float(band.min()), float(band.max())
    for r, m in zip(records, seg):
        # Welch's window tapers the record's first and last half segment: a sweep's first and last
        # frequencies lose their weight (a 5.1 -> 56.6 Hz sweep of 37 s read from 6.67 Hz, its 7 Hz
        # mode then outside the band). The whole record's periodogram, its mean over Welch's main
        # lobe, weighs every sample alike: the band is widened over the lines next to it where that
        # stays above SWEEP_EDGE of its peak (only next to it: an input sensor's drift fills the
        # lowest lines; not down to ``level``: a fast sweep's abrupt start spreads below its first
        # frequency)
        lo, hi = _widened(r, fs, m, lo, hi)
    return lo, hi


def _widened(r, fs, nperseg, lo, hi):
    """(lo, hi) [Hz] widened on each side over the contiguous lines where the whole record's
    periodogram (linear trend removed), its running mean over the lines of a Hann main
    lobe of ``nperseg`` samples, exceeds :data:`SWEEP_EDGE` x its peak (at 2 fs / nperseg
    and above).  The mean, not the median: a periodic multisine of P periods puts its power
    on every P-th line of the record's periodogram, and a median over such a comb is the
    noise between its teeth, as low inside the band as outside it (a GVT multisine of nine
    periods at 400 Hz, its band 2-12 Hz, read as 0.5-200 Hz)."""
    x = np.arange(r.size)
    p = np.abs(np.fft.rfft(r - np.polyval(np.polyfit(x, r, 1), x))) ** 2
    f = np.fft.rfftfreq(r.size, 1.0 / fs)
    p = uniform_filter1d(p, size=max(1, int(round(4 * r.size / nperseg))) | 1, mode="nearest")
    resolved = f >= 2.0 * fs / nperseg
    above = resolved & (p >= SWEEP_EDGE * p[resolved].max())
    k = int(np.searchsorted(f, lo))
    while k > 0 and above[k - 1]:
        k -= 1
    j = int(np.searchsorted(f, hi, side="right")) - 1
    while j < f.size - 1 and above[j + 1]:
        j += 1
    return min(lo, float(f[k])), max(hi, float(f[j]))


def periodic_h1(u, y, fs: float, period_samples: int, skip_periods: int = 1):
    """H1 of a periodic excitation from period-synchronous spectra.

    Every record is cut into whole periods of ``period_samples`` samples; the
    first ``skip_periods`` (the transient) are dropped, each remaining period
    is Fourier transformed without a window (a steady-state periodic
    response has no leakage on the period's lines) and
    ``H1(f_k) = sum_p Y_p(k) conj U_p(k) / sum_p |U_p(k)|^2``, with the
    coherence ``|sum Y conj U|^2 / (sum |U|^2 sum |Y|^2)`` over the periods.

    Parameters
    ----------
    u : 1-D array or list of records (the input), sampled at ``fs`` [Hz].
    y : matching records, each (n,) or (n, n_sensors).
    period_samples : int
        Period of the excitation [samples].
    skip_periods : int
        Leading periods dropped (default 1).

    Returns
    -------
    f : (K,) frequencies k fs / period_samples [Hz], k = 0 .. period_samples // 2
    H : (K, n_sensors) complex FRF (NaN where the input has no power)
    coherence : (K, n_sensors) [-] (1 where only one period is left)
    u_power : (K,) input power per line [u unit^2], averaged over periods
    """
    P = int(period_samples)
    if P < 8:
        raise ValueError(f"period_samples must be at least 8 samples, got {period_samples!r}")
    us, _ = as_record_list(u, "u")
    ys = y if isinstance(y, (list, tuple)) else [y]
    if len(ys) != len(us):
        raise ValueError(f"got {len(us)} input record(s) but {len(ys)} output record(s)")
    Suy = Suu = Syy = 0.0
    count = 0
    for r_u, r_y in zip(us, ys):
        r_y = np.asarray(r_y, float)
        r_y = r_y[:, None] if r_y.ndim == 1 else r_y
        if r_y.shape[0] != r_u.size:
            raise ValueError(f"input and output records have unequal lengths: {r_u.size} and {r_y.shape[0]}")
        n_per = r_u.size // P - int(skip_periods)
        if n_per < 1:
            raise ValueError(
                f"a record of {r_u.size} samples holds fewer than {skip_periods + 1} periods of {P} samples"
            )
        start = int(skip_periods) * P
        U = np.fft.rfft(r_u[start : start + n_per * P].reshape(n_per, P), axis=1)
        Y = np.fft.rfft(r_y[start : start + n_per * P].T.reshape(r_y.shape[1], n_per, P), axis=2)
        Suy = Suy + np.einsum("spk,pk->ks", Y, U.conj())
        Suu = Suu + np.sum(np.abs(U) ** 2, axis=0)
        Syy = Syy + np.sum(np.abs(Y) ** 2, axis=1).T
        count += n_per
    f = np.arange(P // 2 + 1) * fs / P
    with np.errstate(divide="ignore", invalid="ignore"):
        H = np.where(Suu[:, None] > 0, Suy / Suu[:, None], np.nan)
        coh = np.where((Suu[:, None] > 0) & (Syy > 0), np.abs(Suy) ** 2 / (Suu[:, None] * Syy), 0.0)
    if count == 1:
        coh = np.where(Suu[:, None] > 0, 1.0, 0.0) * np.ones_like(coh)
    return f, H, np.clip(coh, 0.0, 1.0), Suu / count
