"""Residual modes: the modes above a record's band, as modes of their own
(:func:`fit_residual_modes`, ``ModalModel.from_modes(residual_modes=...)``).

A structure's modes above the excited band still respond to it: quasi-statically
when they lie far above (a residual flexibility), with a frequency dependence of
their own when they lie near its top.  At a driving point seen in acceleration their
share can be most of the response: on the GVT-like wing of the tests
(``tests/gvt_rig.py``, 2-12 Hz, two modes at 12.9 and 14.1 Hz above it) the six
in-band modes with a mass line left 34.5 % of the low-level record's tip
acceleration unexplained, with one residual mode fitted here 4.5 % (found at
13.4 Hz), with two 4.2 % (the second at 18.4 Hz); the sensors away from the driving
point 2-4 % throughout.

Each residual mode is a linear mode like the others (its coefficients per sensor
fitted with them by :func:`~bayes_update.models.modal.fit.fit_outputs`), its
frequency and damping found by least squares on the record (the output
coefficients solved linearly inside, variable projection): one at a time from the
band's top upwards, each with the ones before it held.  They are never updated and
carry no element.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from .fit import fit_outputs

__all__ = ["RESIDUAL_DAMPING", "excited_top", "fit_residual_modes"]

#: the damping ratios a residual mode may take [-]
RESIDUAL_DAMPING = (0.005, 0.3)
#: the first residual mode's search starts at this many times the band's top, each next one's
#: this many band tops higher
FIRST_START, NEXT_STEP = 1.1, 0.4


def excited_top(force, fs: float, share: float = 1e-2) -> float:
    """The highest frequency [Hz] of the record's periodogram (the whole record, its mean
    removed) whose force energy is at least ``share`` of its largest line's: the top of the
    excited band, exact for a periodic record of whole periods.  (A Welch estimate with 4 s
    segments read the GVT-like multisine's 12 Hz top as 15.7 Hz: its window's leakage
    over 0.25 Hz lines at 1 % of the peak.)"""
    u = np.asarray(force, float)
    power = np.abs(np.fft.rfft(u - u.mean())) ** 2
    f = np.fft.rfftfreq(u.size, 1.0 / fs)
    return float(f[np.flatnonzero(power >= share * power.max())[-1]])


def fit_residual_modes(
    modes, force, response, fs: float, sensors, n: int, band_top_hz: float, residual=True, transient=True
):
    """(n, 2) residual modes ``[(f_hz, zeta), ...]`` above ``band_top_hz`` [Hz] (below 0.45 fs)
    that, beside ``modes`` (M, 2), best explain the record ``force`` [N], ``response`` (n, S)
    at ``fs`` [Hz] (least squares on every sensor's fit error over its rms; ``residual``,
    ``transient`` as for :func:`~bayes_update.models.modal.fit.fit_outputs`)."""
    if n < 0 or int(n) != n:
        raise ValueError(f"residual_modes must be a whole number >= 0, got {n!r}")
    top = float(band_top_hz)
    ceiling = 0.45 * float(fs)
    if n and not 0 < top < ceiling:
        raise ValueError(
            f"residual modes lie above the band's top {top:g} Hz and below 0.45 fs = {ceiling:g} Hz: no room; "
            "a record excited up to near the Nyquist frequency needs none (pass residual_modes=0)"
        )
    found = np.asarray(modes, float).reshape(-1, 2)
    out = []
    for k in range(int(n)):
        f0 = min(top * (FIRST_START + NEXT_STEP * k), 0.5 * (top + ceiling))  # inside the bounds

        def errors(p, held=np.vstack([found, *[np.atleast_2d(m) for m in out]])):
            fit = fit_outputs(np.vstack([held, [p]]), force, response, fs, sensors, residual, transient)
            return fit.errors.ravel()

        sol = least_squares(
            errors,
            [f0, 0.05],
            bounds=([top, RESIDUAL_DAMPING[0]], [ceiling, RESIDUAL_DAMPING[1]]),
            x_scale=[0.1 * top, 0.05],
            max_nfev=60,
        )
        out.append(tuple(float(v) for v in sol.x))
    return np.array(out, float).reshape(-1, 2)
