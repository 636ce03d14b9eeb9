"""Signal processing of the paper: H1 FRF estimate, magnitude-squared coherence, PSD.

All estimators are Welch/CSD averages (``scipy.signal.csd`` and ``welch``,
one-sided, density scaling)::

    H1(f) = S_uy(f) / S_uu(f),    gamma^2(f) = |S_uy|^2 / (S_uu S_yy)

with u the force [N] and y the response (velocity [m/s]); H1 is then in
(m/s)/N.  Averages run over the segments of every record given (a list of
records is averaged together, e.g. repeated tests).

Two ways to segment, chosen by the test:

* :func:`frf_h1` with ``nperseg`` set: classic Welch (Hann window, 50 %
  overlap by default) for stationary excitation (random, long sines).
* :func:`transient_frf`, for the paper's chirp tests (a sweep, then a free
  decay: the record starts and ends at rest).  The H1 estimate uses each
  whole record with a rectangular window: for a record that starts and ends
  at rest that is leakage free, and on the default data set's low chirp it
  matches the FE model's linear FRF to better than 1 % around the resonance.
  Welch segments shorter than the record are not: on a 4 s record of a
  resonance with 1.3 % damping, 1 s Hann segments (MATLAB's defaults, as the
  paper probably used) bias H1 by about 50 % at the peak and give a
  coherence of 0.4 there even for a linear, noise-free test.  The coherence
  therefore comes from long segments (7/8 of the record, shifted by 1/32 of
  it, rectangular window, zero-padded to the record length so that it sits
  on the same frequency grid); it is above 0.99 wherever the force has
  energy and the noise is low, and drops outside the sweep band and with
  noise.  Caution: it does not reveal the nonlinearity of a chirp test (the
  nonlinear distortion of a deterministic sweep is coherent with the force);
  the change of H1 from level to level does (the paper's Fig. 11).

* :func:`psd`: Welch PSD (Hann, 1 s segments, 50 % overlap by default), for
  the sine tests (the paper's Fig. 14, 0-140 Hz).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal as ss


@dataclass
class FRFEstimate:
    """An H1 FRF estimate with its spectra.

    f : frequencies [Hz]; h1 : complex FRF [response unit / force unit, e.g.
    (m/s)/N]; coherence : magnitude-squared coherence [-]; s_uu, s_yy : auto
    spectral densities [N^2/Hz, (m/s)^2/Hz]; s_uy : cross spectral density;
    n_averages : segments averaged for the coherence; method : description.
    """

    f: np.ndarray
    h1: np.ndarray
    coherence: np.ndarray
    s_uu: np.ndarray
    s_yy: np.ndarray
    s_uy: np.ndarray
    n_averages: int
    method: str

    def band(self, f_min: float, f_max: float) -> np.ndarray:
        """Boolean mask of the frequencies in [f_min, f_max] Hz."""
        return (self.f >= f_min) & (self.f <= f_max)


def _records(x, name):
    if isinstance(x, (list, tuple)):
        recs = [np.asarray(r, dtype=float) for r in x]
    else:
        recs = [np.asarray(x, dtype=float)]
    for r in recs:
        if r.ndim != 1 or r.size < 2:
            raise ValueError(f"{name}: each record must be a 1-D array of at least 2 samples")
        if not np.all(np.isfinite(r)):
            raise ValueError(f"{name}: NaN or inf in a record")
    return recs


def _pairs(u, y):
    us, ys = _records(u, "force"), _records(y, "response")
    if len(us) != len(ys):
        raise ValueError(f"{len(us)} force record(s) but {len(ys)} response record(s)")
    for a, b in zip(us, ys):
        if a.size != b.size:
            raise ValueError(f"force and response records differ in length ({a.size} vs {b.size})")
    return us, ys


def _segments(n, nperseg, noverlap):
    return 1 + (n - nperseg) // (nperseg - noverlap)


def _welch_spectra(us, ys, fs, nperseg, noverlap, window, nfft):
    s_uu = s_yy = s_uy = None
    n_avg = 0
    for u, y in zip(us, ys):
        seg = min(nperseg, u.size) if nperseg is not None else u.size
        ov = noverlap if nperseg is not None else 0
        if ov is None:
            ov = seg // 2
        ov = min(ov, seg - 1)
        nf = max(nfft or seg, seg)
        kw = dict(fs=fs, window=window, nperseg=seg, noverlap=ov, nfft=nf, detrend=False)
        f, puu = ss.welch(u, **kw)
        _, pyy = ss.welch(y, **kw)
        _, puy = ss.csd(u, y, **kw)
        k = _segments(u.size, seg, ov)
        if s_uu is None:
            s_uu, s_yy, s_uy, f0 = k * puu, k * pyy, k * puy, f
        else:
            if f.size != f0.size:
                raise ValueError("records give different frequency grids; pass nfft")
            s_uu, s_yy, s_uy = s_uu + k * puu, s_yy + k * pyy, s_uy + k * puy
        n_avg += k
    return f0, s_uu / n_avg, s_yy / n_avg, s_uy / n_avg, n_avg


def _h1_and_coherence(s_uu, s_yy, s_uy):
    with np.errstate(divide="ignore", invalid="ignore"):
        h1 = np.where(s_uu > 0, s_uy / s_uu, np.nan)
        coh = np.where((s_uu > 0) & (s_yy > 0), np.abs(s_uy) ** 2 / (s_uu * s_yy), np.nan)
    return h1, np.clip(coh, 0.0, 1.0)


def frf_h1(
    force,
    response,
    fs: float,
    nperseg: int | None = None,
    noverlap: int | None = None,
    window="hann",
    nfft: int | None = None,
) -> FRFEstimate:
    """Welch H1 FRF and coherence from force [N] to response (e.g. velocity [m/s]).

    ``force``, ``response``: 1-D arrays or lists of records (averaged
    together).  ``nperseg`` [samples]: segment length; None uses each whole
    record as one segment with a rectangular window (then the coherence of a
    single record is identically 1: use :func:`transient_frf` for transient
    tests).  ``noverlap``: default half a segment.  ``window``: any
    ``scipy.signal.get_window`` spec (ignored when ``nperseg`` is None).
    """
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs}")
    us, ys = _pairs(force, response)
    if nperseg is None:
        window = "boxcar"
        method = "whole record, rectangular window"
    else:
        method = f"Welch, {nperseg}-sample {window} segments"
    f, s_uu, s_yy, s_uy, n = _welch_spectra(us, ys, fs, nperseg, noverlap, window, nfft)
    h1, coh = _h1_and_coherence(s_uu, s_yy, s_uy)
    return FRFEstimate(f, h1, coh, s_uu, s_yy, s_uy, n, method)


def transient_frf(force, response, fs: float) -> FRFEstimate:
    """H1 and coherence of a transient test (chirp then free decay, starting and
    ending at rest): H1 from the whole record(s) (rectangular window, leakage
    free), coherence from long shifted segments (7/8 of the record, step 1/32
    of it) on the same frequency grid.  See the module docstring for why."""
    us, ys = _pairs(force, response)
    whole = frf_h1(us, ys, fs)
    n = min(u.size for u in us)
    if any(u.size != n for u in us):
        raise ValueError("transient_frf needs records of equal length")
    seg = max(2, (7 * n) // 8)
    step = max(1, n // 32)
    _, s_uu, s_yy, s_uy, k = _welch_spectra(us, ys, fs, seg, seg - step, "boxcar", n)
    _, coh = _h1_and_coherence(s_uu, s_yy, s_uy)
    return FRFEstimate(
        whole.f,
        whole.h1,
        coh,
        whole.s_uu,
        whole.s_yy,
        whole.s_uy,
        k,
        f"H1 from the whole record; coherence from {k} segments of {seg} samples (rectangular, step {step})",
    )


def coherence(force, response, fs: float, **options) -> tuple[np.ndarray, np.ndarray]:
    """``(f [Hz], magnitude-squared coherence)``; ``options`` as :func:`frf_h1`."""
    est = frf_h1(force, response, fs, **options)
    return est.f, est.coherence


def psd(
    x, fs: float, nperseg: int | None = None, noverlap: int | None = None, window="hann"
) -> tuple[np.ndarray, np.ndarray]:
    """Welch power spectral density ``(f [Hz], P [unit^2/Hz])`` of one record or
    a list of records (averaged).  Default segments: 1 s (``fs`` samples),
    Hann, 50 % overlap."""
    if not fs > 0:
        raise ValueError(f"fs must be positive, got {fs}")
    recs = _records(x, "x")
    seg = int(round(fs)) if nperseg is None else int(nperseg)
    total = None
    n_avg = 0
    for r in recs:
        s = min(seg, r.size)
        ov = s // 2 if noverlap is None else min(noverlap, s - 1)
        f, p = ss.welch(r, fs=fs, window=window, nperseg=s, noverlap=ov, nfft=seg, detrend=False)
        k = _segments(r.size, s, ov)
        total = k * p if total is None else total + k * p
        n_avg += k
    return f, total / n_avg
