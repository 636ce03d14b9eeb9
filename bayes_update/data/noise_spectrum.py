"""A channel's noise as its estimate saw it, as a spectrum: what the inspection report draws
beside the record's (:func:`noise_spectrum`).  Apart from :mod:`bayes_update.data.noise`, which
estimates the sd the weights use: this only redraws it."""

from __future__ import annotations

import numpy as np
from scipy.signal import welch

from bayes_update.data.lpm import lpm_noise
from bayes_update.data.noise import NoiseEstimate
from bayes_update.data.periodic import PeriodLayout, find_periods


def noise_spectrum(record, name: str, estimate: NoiseEstimate, fs: float | None = None):
    """``(f [Hz], one-sided PSD [unit^2/Hz])`` of a channel's noise as its estimate
    saw it: ``periods``, the PSD of the deviations from the period mean (x P / (P - 1));
    ``zero_input``, of the stretches used; ``fit_residual`` of the LPM, its noise
    spectrum; otherwise (declared, quiet band, carried, a caller's fit) white at the estimate's
    sd, ``2 sd^2 / fs``.  None when the noise is unknown."""
    if not estimate.known:
        return None
    fs = float(record.sampling_rate_hz if fs is None else fs)
    x = np.asarray(record.force if name == "force" else record.channel(name), float)
    white = (np.array([0.0, fs / 2]), np.full(2, 2.0 * estimate.sd**2 / fs))
    if estimate.method == "periods":
        layout = find_periods(record.force, record.period_samples)
        if not isinstance(layout, PeriodLayout):
            return white
        ((a, b),) = estimate.spans
        Y = x[a:b].reshape(-1, layout.period)
        P = Y.shape[0]
        D = (Y - Y.mean(axis=0)).ravel()
        f, p = welch(D, fs=fs, nperseg=min(layout.period, 512), detrend="linear")
        return f, p * P / (P - 1)
    if estimate.method == "zero_input":
        parts = [x[a:b] for a, b in estimate.spans]
        nper = min(256, min(len(q) for q in parts))
        spectra = [welch(q, fs=fs, nperseg=nper, detrend="linear") for q in parts]
        weights = np.array([len(q) for q in parts], float)
        return spectra[0][0], np.average([p for _, p in spectra], axis=0, weights=weights)
    # the LPM's fit: its own detail, or one that leads with why it replaced a quiet band's
    if estimate.method == "fit_residual" and "local polynomial method" in estimate.detail:
        est = lpm_noise(record.force, x, fs)
        return est.f, est.psd
    return white
