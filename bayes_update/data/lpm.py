"""Noise from a model-free linear fit: the local polynomial method (LPM).

Pintelon, Schoukens, Vandersteen and Barbé, "Estimation of nonparametric
noise and FRF models for multivariable systems", MSSP 24 (2010); Pintelon &
Schoukens, System Identification (2012), sec. 7.2 (the fit itself is
:func:`volterra.lpm.local_polynomial`).  On any excitation
(random included, no periods needed) the DFT of the output around each
frequency line k is fitted by

    Y(k + r) = G(k + r) U(k + r) + T(k + r) + V(k + r),   r = -R .. R,

with G (the FRF) and T (the leakage / transient term) polynomials of degree
``degree`` in r; the residual's energy divided by its degrees of freedom
``q = 2R + 1 - 2 (degree + 1)`` is the noise variance at line k.  Summed
over the lines (Parseval) it is the noise variance per sample, coloured
noise included; the per-line values are the noise spectrum.

What the residual holds: the output noise, the response to the force
channel's noise (the fit is driven by the recorded force), and the part of
the nonlinear distortion not coherent with the force.  So it is the sensor
noise only on a test whose response is linear to well below the noise (a
low-level test); sensor noise does not grow with the level, nonlinear
distortion does (:func:`bayes_update.data.noise.dataset_noise` carries it
from the low-level test to the others).

Where the record is short against a mode's half-power bandwidth (a lightly
damped mode on a 2-s record: lines 0.5 Hz apart, a bandwidth 2 zeta f of a
few tenths of a Hz), G and T change faster than the local polynomials can
follow and the residual near the mode is model error, not noise (on a portal
frame's 2-s multisine at 256 Hz: 1e4 times the noise's level over a few Hz
around the sway mode, an sd 18-22 times the noise added).  Such lines are
found against the running median of their neighbours (far beyond the
residual's chi-square spread) and given that median; the detail names them,
and more than :data:`MAX_UNRESOLVED_SHARE` of the lines is an error (record
longer, or declare the noise).  The guard needs clean lines between the modes:
lightly damped modes closer than about four local windows (4 (2R + 1) lines)
all along the band leave the running median itself above the noise, and the
estimate too high (12 modes of 0.2 % damping every 3.6 Hz on 4 s: 38 times
the noise); declare ``noise_sd`` for such records.

Frequencies in Hz, sd in the response's unit per sample.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, stats

from volterra.lpm import DEFAULT_DEGREE, DEFAULT_HALF_WIDTH, local_polynomial

#: the words of an estimate that holds the force noise's response (the force's own noise unknown)
HOLDS_FORCE_NOISE = "holds the sensor noise, the force noise's response"
#: half-width R of the local window [lines] and degree of the local polynomials: those of
#: volterra.lpm (the one local polynomial fit, which volterra.estimate_modes reads FRFs with)
#: a line's residual variance is unresolved (model error) beyond the running median of
#: MEDIAN_WINDOWS local windows' worth of lines times the chi-square quantile of 1 -
#: UNRESOLVED_P over its median (per line, the noise alone crosses it once in 1e4) ...
MEDIAN_WINDOWS = 4
UNRESOLVED_P = 1e-4
#: ... and a record with more than this share of unresolved lines gives no estimate
MAX_UNRESOLVED_SHARE = 0.35


@dataclass(frozen=True)
class LPMNoise:
    """sd [response unit per sample], its degrees of freedom, and the noise spectrum:
    f [Hz] and one-sided PSD [unit^2/Hz] (``sum psd * df = sd^2``)."""

    sd: float
    dof: float
    f: np.ndarray
    psd: np.ndarray
    detail: str


def _detrend(x: np.ndarray) -> np.ndarray:
    t = np.arange(x.size)
    return x - np.polyval(np.polyfit(t, x, 1), t)


def lpm_noise(
    force,
    response,
    fs: float,
    half_width: int = DEFAULT_HALF_WIDTH,
    degree: int = DEFAULT_DEGREE,
    force_noise_sd: float | None = None,
) -> LPMNoise:
    """Noise of ``response`` [its unit] given ``force`` from the LPM (module docstring).

    Both records are detrended (offsets, slow drifts) and transformed whole
    (no window).  The residual holds the response to the force channel's
    noise too (the fit is driven by the recorded force): with
    ``force_noise_sd`` [N] (white) it is taken out line by line through the
    LPM's FRF, ``v - |G|^2 s_u^2`` (at least a tenth of v: where the force's
    noise dominates, the sensor's cannot be told from it), and the estimate is
    the sensor's own; without, the estimate holds both and says so.  Raises
    ValueError for a record too short for the local windows or a response
    that is not 1-D.
    """
    u = _detrend(np.asarray(force, float))
    y = _detrend(np.asarray(response, float))
    if u.ndim != 1 or y.shape != u.shape:
        raise ValueError(f"force and response must be 1-D records of equal length, got {u.shape}, {y.shape}")
    lp = local_polynomial(u, y, half_width, degree, frf=force_noise_sd is not None)
    R, d, N = int(half_width), int(degree), u.size
    K = N // 2 + 1
    centres = lp.k
    v, q = lp.noise[:, 0], lp.dof
    if force_noise_sd is not None:
        # the force noise's response: |G|^2 times the force noise's variance per line (white: s_u^2)
        v = np.maximum(v - np.abs(lp.G[:, 0]) ** 2 * float(force_noise_sd) ** 2, 0.1 * v)
    f = np.fft.rfftfreq(N, 1.0 / fs)
    v, unresolved = _unresolved_lines(v, int(q.min()), MEDIAN_WINDOWS * (2 * R + 1))
    if unresolved.mean() > MAX_UNRESOLVED_SHARE:
        raise ValueError(
            f"the local polynomials cannot follow the FRF on {unresolved.mean():.0%} of the lines "
            f"(a record of {N / fs:.3g} s: lines {fs / N:.3g} Hz apart, coarse against the modes' "
            "bandwidth); record longer or declare noise_sd"
        )
    var_line = np.empty(K)
    var_line[centres] = v
    var_line[:R] = v[0]
    var_line[K - R :] = v[-1]
    weight = np.full(K, 2.0)
    weight[0] = 1.0
    if N % 2 == 0:
        weight[-1] = 1.0
    sd = float(np.sqrt(np.sum(weight * var_line) / N))
    dof = float(2 * np.mean(q) * K / (2 * R + 1))
    detail = f"local polynomial method (model-free linear fit, {2 * R + 1}-line windows, degree {d}; " + (
        "the force's noise taken out through the fit's FRF; holds the sensor noise and any incoherent distortion)"
        if force_noise_sd is not None
        else f"{HOLDS_FORCE_NOISE} (the force's own noise is unknown) and any incoherent distortion)"
    )
    if unresolved.any():
        fu = f[centres][unresolved]
        detail += (
            f"; {int(unresolved.sum())} of {unresolved.size} lines ({fu.min():.4g}-{fu.max():.4g} Hz) "
            "unresolved (a mode narrower than the local window) and given their neighbours' median"
        )
    return LPMNoise(sd, dof, f, weight * var_line / fs, detail)


def _unresolved_lines(v: np.ndarray, q: int, width: int):
    """(v with its unresolved lines replaced by the running median, the mask of them):
    a line is unresolved where its residual variance exceeds the running median over
    ``width`` lines by the chi-square ratio of :data:`UNRESOLVED_P` (``q`` complex
    degrees of freedom per line: the residual's variance is sigma^2 chi2_2q / 2q)."""
    med = ndimage.median_filter(v, size=min(v.size, width | 1), mode="nearest")
    ratio = stats.chi2.isf(UNRESOLVED_P, 2 * q) / stats.chi2.median(2 * q)
    bad = v > ratio * med
    return np.where(bad, med / stats.chi2.median(2 * q) * (2 * q), v), bad


def noise_from_fit_residual(residual, n_parameters: int) -> tuple[float, float]:
    """``(sd, dof)`` of a fit's residual [response unit]: ``||r|| / sqrt(n - p)``
    for ``n`` samples and ``p`` fitted parameters (e.g. a Volterra fit's
    coefficients and h0).  The caller vouches that the fit is complete (all
    of the response but noise is in the model)."""
    r = np.asarray(residual, float).ravel()
    p = int(n_parameters)
    if p < 0 or r.size <= p:
        raise ValueError(f"{r.size} residual samples cannot carry {p} parameters")
    return float(np.linalg.norm(r) / np.sqrt(r.size - p)), float(r.size - p)
