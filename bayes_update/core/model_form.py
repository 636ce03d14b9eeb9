"""The model-form error: what the best fit leaves beyond the noise, as random draws
the likelihood can count (docs/likelihood.md, "Model-form error").

At the mode the record's residual ``r = y_measured - y_model`` (time domain,
each sensor, the means removed as the records' are) is measurement noise plus
what the model cannot represent: an effect it lacks, dynamics outside it, a
sensor's own.  The second part is treated as a stationary random process
``delta`` whose power spectrum is the residual's beyond the noise's (a
Kennedy-O'Hagan discrepancy whose spectral density is read off the data;
for a random or random-phase multisine excitation the distortion a model
leaves behaves as such a process over realisations of the excitation:
Pintelon & Schoukens 2012, ch. 3, the best linear approximation and its
stochastic nonlinear distortion).  Its draws are the residual's own Fourier
amplitudes, shrunk to the excess over the noise band by band, with random
phases (the same phase for every sensor at a frequency, so the sensors'
cross-spectra are kept): :func:`form_draws`.  Projected on a test's
regressors like the noise replicates, they give the variance the model-form
error puts along the directions the parameters move the output, which a
smooth residual concentrates in a few of them.

Where the residual is the noise's (a model that is right), the shrinkage
leaves nothing: a band counts only where its average periodogram exceeds
the noise's by more than :data:`THRESHOLD_SD` of its own scatter.
"""

from __future__ import annotations

import numpy as np
from scipy.ndimage import uniform_filter1d

__all__ = ["BAND_BINS", "THRESHOLD_SD", "excess_gain", "form_draws", "periodogram"]

#: frequency bins averaged into one band for the comparison with the noise: the
#: band's periodogram then scatters by 1/sqrt(BAND_BINS) of its mean (25 %)
BAND_BINS = 16
#: a band's excess over the noise counts beyond this many sd of that scatter (soft
#: threshold): a residual of noise alone leaves 0.5 % of the noise's power, on average
THRESHOLD_SD = 2.0


def periodogram(x) -> np.ndarray:
    """``|rfft(x)|^2 / n`` along the first axis, (n // 2 + 1,) or (n // 2 + 1, k)."""
    x = np.asarray(x, float)
    return np.abs(np.fft.rfft(x, axis=0)) ** 2 / x.shape[0]


def excess_gain(residual_periodogram, noise_spectrum, bins: int = BAND_BINS) -> np.ndarray:
    """Per frequency (and sensor) the amplitude factor in [0, 1] that leaves of the
    residual what exceeds the noise: ``sqrt(max(S_r - S_n (1 + c / sqrt(bins)), 0) / S_r)``
    with ``S_r``, ``S_n`` band averages over ``bins`` bins and ``c`` :data:`THRESHOLD_SD`."""
    S_r = uniform_filter1d(np.asarray(residual_periodogram, float), bins, axis=0, mode="nearest")
    S_n = uniform_filter1d(np.asarray(noise_spectrum, float), bins, axis=0, mode="nearest")
    excess = np.maximum(S_r - S_n * (1.0 + THRESHOLD_SD / np.sqrt(bins)), 0.0)
    return np.sqrt(np.divide(excess, S_r, out=np.zeros_like(S_r), where=S_r > 0))


def form_draws(residual, noise_spectrum, n_draws: int, rng, bins: int = BAND_BINS):
    """``(draws, excess)``: ``n_draws`` random-phase draws of the residual's excess over
    the noise (module docstring), shape ``(n_draws,) + residual.shape``, and the
    excess itself with its phases kept, ``residual.shape``.

    Parameters
    ----------
    residual : (n,) or (n, k) time-domain residual at the mode [sensor units].
    noise_spectrum : the noise's periodogram in the residual (:func:`periodogram`
        averaged over noise replicates), (n // 2 + 1,) or (n // 2 + 1, k).
    """
    r = np.asarray(residual, float)
    n = r.shape[0]
    R = np.fft.rfft(r, axis=0)
    g = excess_gain(np.abs(R) ** 2 / n, noise_spectrum, bins)
    A = g * R
    A[0] = 0.0  # no mean (the records' means are removed)
    excess = np.fft.irfft(A, n, axis=0)
    phase = np.exp(2j * np.pi * rng.random((n_draws, A.shape[0])))
    if n % 2 == 0:
        phase[:, -1] = np.where(phase[:, -1].real >= 0.0, 1.0, -1.0)  # the Nyquist line stays real
    shape = (n_draws, A.shape[0]) + (1,) * (A.ndim - 1)
    draws = np.fft.irfft(A[None] * phase.reshape(shape), n, axis=1)
    return draws, excess
