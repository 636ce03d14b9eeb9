"""Which candidate poles are modes, and where exactly: the steps of :func:`volterra.estimate_modes`
after the LSCF (its module docstring, steps 3-5).

* :func:`weights`: 1 / the sd of each line's FRF estimate.
* :func:`select`: backward elimination of the least significant mode
  (:func:`volterra.lsfd.significance`) while it is below its threshold.
* :func:`refine_modes`: the poles of the modal fit (:func:`volterra.lsfd.refine`)
  in bounded boxes, re-centred where a pole ends on its box.
* :func:`overlapped`: the weaker of two modes closer than their half-power
  half-widths whose shapes over the sensors agree (one mode and its misfit).
* :func:`residual_peak`: where the fit's weighted residual holds a peak away
  from every mode (a mode the LSCF did not stabilise: weak beside strong
  ones), as a start for one more mode.

A mode's significance is compared with its threshold times the *local* level
of the fit's weighted residual around it (the median over 25 half-power
half-widths, at least 50 lines, against the median a well-fitted line has): a
misfit the modal model leaves near a strong mode (a nonlinearity, a
discrete record read as continuous) is not a mode.

Frequencies Hz, damping ratios [-].
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats
from scipy.ndimage import median_filter, uniform_filter1d

from . import lsfd

__all__ = [
    "PoleEstimationError",
    "MIN_SIGNIFICANCE",
    "weights",
    "inside",
    "select",
    "refine_modes",
    "residual_peak",
    "relative_residual",
    "energies",
    "fit_lines",
    "peak_mode",
    "overlapped",
]

#: Default smallest significance of a mode (chi-square rise) ...
MIN_SIGNIFICANCE = 25.0
#: ... and per real unknown the mode adds (false alarm below 1e-4 for any number of sensors)
SIGNIFICANCE_PER_UNKNOWN = 5.0
#: lines of the running median that sets the output noise of a line's weight
WEIGHT_WINDOW = 31
#: lines fitted away from the candidates' neighbourhoods (thinned beyond): speed
MAX_FIT_LINES = 4096
#: a residual peak is a start for a mode only beyond this many half-power half-widths of every mode
PEAK_CLEARANCE = 3.0
#: lines the residual's energy is smoothed over when looking for its peak
PEAK_LINES = 11
#: the residual's local level: over this many half-power half-widths around a mode, at least LOCAL_LINES
LOCAL_WIDTHS, LOCAL_LINES = 25.0, 50
#: two overlapping modes whose shapes over the sensors agree this well (MAC) are one mode's misfit
SAME_SHAPE_MAC = 0.9


class PoleEstimationError(ValueError):
    """No trustworthy pole could be estimated from the data; the message says
    what to check (band, coherence, offsets and drifts, level of the record)."""


def weights(var, H, u_power, var_input=None):
    """1 / sd of each line's H.  The variance is (noise of the output on that line) /
    (input power on that line): the first taken as a running median over
    :data:`WEIGHT_WINDOW` lines (robust to one line's chance value), the second
    line by line (a line the input barely excites is an uncertain one); floored at
    a relative precision of 1e-6 of the sensor's level.  ``var_input`` (the part of
    ``var`` the force's noise gives, ``|H|^2`` times its power over the input's) is
    kept line by line, not smoothed: it peaks at a mode's resonance, which a running
    median would flatten."""
    W = np.empty(var.shape)
    up = np.maximum(np.asarray(u_power, float), 1e-300)
    extra = np.zeros(var.shape) if var_input is None else np.nan_to_num(np.asarray(var_input, float))
    for s in range(var.shape[1]):
        v = (var[:, s] - extra[:, s]) * up
        ok = np.isfinite(v) & (v > 0)
        fill = float(np.median(v[ok])) if ok.any() else 1.0
        v = median_filter(np.where(ok, v, fill), size=min(WEIGHT_WINDOW, v.size) | 1, mode="nearest") / up
        v = v + extra[:, s]
        floor = (1e-6 * float(np.median(np.abs(H[:, s])))) ** 2
        W[:, s] = 1.0 / np.sqrt(np.maximum(v, max(floor, 1e-300)))
    return W


def inside(f, z, band, spacing):
    """The half-power band of (f, z) holds a line at least (a narrower peak is one
    line's chance, not a mode the record resolves) and lies inside ``band`` with
    two lines to spare."""
    return 2 * z * f >= spacing and f * (1 - z) - 2 * spacing >= band[0] and f * (1 + z) + 2 * spacing <= band[1]


def fit_lines(f, modes, spacing):
    """Indices of the lines to fit: all within 5 half-power bandwidths of a mode, every
    k-th elsewhere so that at most MAX_FIT_LINES remain there."""
    if f.size <= MAX_FIT_LINES:
        return np.arange(f.size)
    near = np.zeros(f.size, bool)
    for fr, ze in modes:
        near |= np.abs(f - fr) <= 10 * ze * fr + 3 * spacing
    far = np.flatnonzero(~near)
    step = max(1, int(math.ceil(far.size / MAX_FIT_LINES)))
    return np.sort(np.concatenate([np.flatnonzero(near), far[::step]]))


def local_level(f, resid, freq, zeta, spacing):
    """The weighted residual's level around ``freq`` (module docstring), at least 1."""
    e = np.sum(np.abs(resid) ** 2, axis=1)
    near = np.abs(f - freq) <= max(LOCAL_WIDTHS * zeta * freq, LOCAL_LINES * spacing)
    if near.sum() < 5:
        near = np.ones(f.size, bool)
    S = resid.shape[1]
    return max(1.0, float(np.median(e[near])) / (stats.chi2.median(2 * S) / 2))


def threshold(n_sensors, level, min_significance, correlated=1):
    """The chi-square rise a mode needs: ``min_significance`` or 5 per real unknown it
    adds (2 per sensor and 2 for its pole), times the local ``level``, times
    ``correlated``: the lines over which neighbouring estimates share their data (the
    LPM's window: a chance excess spreads over that many lines)."""
    return max(min_significance, SIGNIFICANCE_PER_UNKNOWN * (2 * n_sensors + 2)) * level * correlated


def select(d, modes, pseudo, fixed, min_significance, spacing, correlated=1):
    """(kept modes, their significance): drop the least significant (against its
    threshold) while one is below; ``fixed``: keep every mode (their significance only)."""
    modes = list(modes)
    S = d.H.shape[1]
    while modes:
        sig, resid = lsfd.significance(d, modes, pseudo)
        if fixed:
            return modes, sig
        ratio = [
            s / threshold(S, local_level(d.f, resid, fr, ze, spacing), min_significance, correlated)
            for s, (fr, ze) in zip(sig, modes)
        ]
        drop = int(np.argmin(ratio))
        if ratio[drop] >= 1.0:
            return modes, sig
        modes.pop(drop)
    return [], np.zeros(0)


def overlapped(d, modes, sig, pseudo):
    """Index of the less significant of two modes the record cannot tell from one, or None.

    Two modes closer than the sum of their half-power half-widths (modal overlap above
    one) whose shapes over the sensors agree (MAC of their parts at their own
    frequencies above :data:`SAME_SHAPE_MAC`; always so on one sensor) are not two
    modes a reader of this record can resolve: the pair is one mode and the misfit a
    modal model leaves at its peak (a weakly nonlinear record: a low-level sweep
    through a cubic spring's resonance gave 40.506 Hz with a "mode" at 39.667 Hz of
    0.1 % of its energy).  Overlapping modes of different shapes (a symmetric
    structure's split pair seen by two sensors) are kept."""
    if len(modes) < 2:
        return None
    parts, _, _ = lsfd.fit(d, modes, pseudo)
    shapes = [parts[m, int(np.argmin(np.abs(d.f - fr)))] for m, (fr, _) in enumerate(modes)]
    pairs = []
    for a in range(len(modes)):
        for b in range(a + 1, len(modes)):
            (fa, za), (fb, zb) = modes[a], modes[b]
            if abs(fa - fb) >= za * fa + zb * fb:
                continue
            va, vb = shapes[a], shapes[b]
            mac = abs(np.vdot(va, vb)) ** 2 / max(float(np.vdot(va, va).real * np.vdot(vb, vb).real), 1e-300)
            if mac > SAME_SHAPE_MAC:
                pairs.append(a if sig[a] < sig[b] else b)
    return min(pairs, key=lambda i: sig[i]) if pairs else None


def bounds(modes, cuts=None):
    """Per pole f0 (1 +- max(4 zeta0, 1 %)) cut halfway to the neighbours among the poles
    ``cuts`` marks (default all), zeta0 / 4 .. 4 zeta0."""
    f0 = np.array([m[0] for m in modes])
    z0 = np.array([m[1] for m in modes])
    span = np.maximum(4.0 * z0, 0.01)
    lo, hi = f0 / (1 + span), f0 * (1 + span)
    idx = np.arange(f0.size) if cuts is None else np.flatnonzero(cuts)
    order = idx[np.argsort(f0[idx])]
    for a, b in zip(order[:-1], order[1:]):
        mid = math.sqrt(f0[a] * f0[b])
        hi[a], lo[b] = min(hi[a], mid), max(lo[b], mid)
    return (lo, hi), (z0 / 4, np.minimum(4 * z0, 0.95))


def refine_modes(d, modes, pseudo, band, spacing, tries: int = 3):
    """``(modes, pseudo, stuck)``: refined modes and pseudo poles, each a list of (f, zeta),
    and the indices of the modes that did not settle.  The pseudo poles are refined
    with the modes (a mode just outside the band is fitted as well as the band's edge
    lets it, so that it does not pull the modes inside).  A pole that ends on its box
    is searched again in a box centred where it ended (``tries`` boxes in all); a
    mode still on its box then is ``stuck`` unless it has left the band (the caller
    makes such a one a pseudo pole: the tail of a mode outside)."""
    allp = list(modes) + list(pseudo)
    fr, ze = np.array([m[0] for m in allp]), np.array([m[1] for m in allp])
    M = len(modes)
    for _ in range(tries):
        # a pseudo pole inside the band (a broad cluster read as the tail of a mode outside) does not
        # fence a mode in: one at 270.7 Hz, 24 % damped, kept a 5.5 % mode at 272.7 Hz from its start
        # at 288 Hz, and the mode was missed
        cuts = (np.arange(fr.size) < M) | (fr < band[0]) | (fr > band[1])
        box = bounds(list(zip(fr, ze)), cuts)
        # a pseudo pole outside the band stays outside it (it stands for modes there)
        (flo, fhi), _ = box
        for i in range(M, fr.size):
            if fr[i] > band[1]:
                flo[i], fhi[i] = max(flo[i], band[1]), max(fhi[i], 1.5 * fr[i])
            elif fr[i] < band[0]:
                flo[i], fhi[i] = min(flo[i], fr[i] / 1.5), min(fhi[i], band[0])
        fr, ze, edge = lsfd.refine(d, fr, ze, box)
        if not edge[:M].any():
            break
    stuck = [int(m) for m in np.flatnonzero(edge[:M]) if inside(fr[m], ze[m], band, spacing)]
    out = list(zip(fr.tolist(), ze.tolist()))
    return out[:M], out[M:], stuck


def residual_peak(d, modes, pseudo, band, spacing, min_significance, exclude=(), correlated=1):
    """(f, zeta) start of one more mode where the weighted residual of the fit holds its
    largest excess over its median level (smoothed over :data:`PEAK_LINES` lines,
    so that a broad weak mode counts by its whole peak), beyond
    :data:`PEAK_CLEARANCE` half-power half-widths of every mode, 1 % of the
    ``exclude`` starts already tried, and inside the band; the excess over its
    half-power region must be able to make a mode as significant as
    :func:`select` asks, else None.  The damping start is that region's
    half-power width (at least 1.5 lines)."""
    _, r, _ = lsfd.fit(d, modes, pseudo)
    f = d.f
    e = np.sum(np.abs(r) ** 2, axis=1)
    free = (f > band[0] + 3 * spacing) & (f < band[1] - 3 * spacing)
    for fr, ze in modes:
        free &= np.abs(f - fr) > PEAK_CLEARANCE * ze * fr
    for fr, ze in exclude:
        free &= np.abs(f - fr) > max(PEAK_CLEARANCE * ze, 0.01) * fr
    if free.sum() < PEAK_LINES:
        return None
    level = float(np.median(e[free]))
    es = uniform_filter1d(e, PEAK_LINES, mode="nearest")
    k = int(np.flatnonzero(free)[np.argmax(es[free])])
    half = level + (es[k] - level) / 2
    a = k
    while a > 0 and es[a - 1] > half and free[a - 1]:
        a -= 1
    b = k
    while b < f.size - 1 and es[b + 1] > half and free[b + 1]:
        b += 1
    excess = float(np.sum(e[a : b + 1] - level))
    S = d.H.shape[1]
    if excess < threshold(S, max(1.0, level / (stats.chi2.median(2 * S) / 2)), min_significance, correlated):
        return None
    zeta = max((f[b] - f[a]) / (2 * f[k]), 1.5 * spacing / f[k], 1e-4)
    return float(f[k]), float(min(zeta, 0.3))


def relative_residual(d, modes, pseudo):
    """sqrt(mean over sensors of ||W (H - fit)||^2 / ||W H||^2): the part of the FRF the
    modal fit leaves unexplained, each line weighted by its certainty (the lines where
    the input is buried in the input sensor's noise count for little)."""
    _, r, _ = lsfd.fit(d, modes, pseudo)
    per = np.sum(np.abs(r) ** 2, axis=0) / np.sum(np.abs(d.W * d.H) ** 2, axis=0)
    return float(np.sqrt(np.mean(per)))


def energies(H, upow, parts):
    """Each mode's share of the response energy (input-power weighted, every sensor
    normalised by its own energy)."""
    norm = np.sum(upow[:, None] * np.abs(H) ** 2, axis=0)
    e = np.sum(upow[None, :, None] * np.abs(parts) ** 2, axis=1) / norm
    e = e.sum(axis=1)
    return e / e.sum()


def peak_mode(f, H):
    """(f [Hz], zeta [-]) of the largest peak of the sensors' summed ``|H|^2`` and its half-power width."""
    p = np.sum(np.abs(H) ** 2, axis=1)
    i = int(np.argmax(p))
    lo = next((k for k in range(i, -1, -1) if p[k] <= p[i] / 2), None)
    hi = next((k for k in range(i, len(p)) if p[k] <= p[i] / 2), None)
    if lo is None or hi is None:
        return None
    return float(f[i]), float(min(max((f[hi] - f[lo]) / (2 * f[i]), 1e-4), 0.3))
