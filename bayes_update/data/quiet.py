"""Noise where the structure is not excited: zero-input sections and a quiet band.

* :func:`quiet_sections`: stretches of a record where the force is at its
  noise floor (a lead-in before the excitation, a pause, a tail after it).
* :func:`zero_input_noise`: one channel's noise sd in those stretches.  A
  response right after the excitation stops is a free decay, not noise: in
  each stretch the block variance is followed down to its floor, the decay
  of its last part fitted (an exponential in energy), and the stretch starts
  only where the decay has fallen to 1 % of the floor's variance.  A
  stretch whose first and second halves still differ (a decay slower than
  the stretch) is not used.  A linear trend is removed per stretch (offsets,
  drifts).
* :func:`noise_band` and :func:`band_noise`: the quiet band above the
  excitation (from 3x the top of the excited band, above the cubic
  harmonics, to 0.45 fs), where a record sampled well above its band holds
  noise only; the noise is taken as white there (its level in the band,
  extrapolated to the whole record's band).

Indices are samples, frequencies Hz, sd in the channel's unit per sample.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import welch

import volterra

#: moving window of the force's level [s] (at least MIN_WINDOW samples)
WINDOW_S = 0.1
MIN_WINDOW = 16
#: a force counts as quiet below this multiple of its floor (the 1st percentile of its moving sd) ...
QUIET_FACTOR = 3.0
#: ... in a record whose excited parts (95th percentile) are at least this multiple above the floor
MIN_CONTRAST = 20.0
#: shortest usable stretch [samples]; total needed over the stretches
MIN_STRETCH = 64
MIN_TOTAL = 256
#: the free decay is followed down to this share of the floor's variance
DECAY_RESIDUE = 0.01
#: the two halves of a used stretch (n samples each) may differ in sd by at most a
#: factor 1 + HALF_TOLERANCE / sqrt(n) (4 sd of the ratio for white noise is 2.8 / sqrt(n))
HALF_TOLERANCE = 4.0
#: quiet band: from BAND_HARMONIC x the excited band's top to BAND_TOP x fs, with at least BAND_LINES PSD lines
BAND_HARMONIC = 3.0
BAND_TOP = 0.45
BAND_LINES = 16
#: the quiet band holds white noise when its level (harmonic lines left out) changes less than
#: this factor between its lowest and highest thirds (3 dB; a sensor's anti-alias filter is flat
#: to well within 1 dB below 0.45 fs); coloured noise or the record's harmonics change it more
WHITE_RATIO = 2.0


def window_samples(fs: float) -> int:
    return max(MIN_WINDOW, int(round(WINDOW_S * fs)))


def _moving_sd(x: np.ndarray, w: int) -> np.ndarray:
    """sd of x over the w samples starting at each k (k = 0 .. n - w), each window's mean removed."""
    c1 = np.concatenate([[0.0], np.cumsum(x)])
    c2 = np.concatenate([[0.0], np.cumsum(x * x)])
    m1 = (c1[w:] - c1[:-w]) / w
    m2 = (c2[w:] - c2[:-w]) / w
    return np.sqrt(np.clip(m2 - m1 * m1, 0.0, None))


def _runs(mask: np.ndarray) -> list:
    d = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def quiet_sections(force, fs: float):
    """``[(start, stop), ...]`` sample ranges where the force is at its noise floor
    (its moving sd below :data:`QUIET_FACTOR` x the floor, in a record that is
    also excited at least :data:`MIN_CONTRAST` x above it), each at least
    :data:`MIN_STRETCH` samples; or a sentence saying why there are none."""
    f = np.asarray(force, float)
    w = window_samples(fs)
    if f.size < 4 * w:
        return f"the record is too short ({f.size} samples) to look for zero-input sections"
    s = _moving_sd(f, w)
    floor, active = np.percentile(s, 1), np.percentile(s, 95)
    if not active > MIN_CONTRAST * floor:
        return (
            "no zero-input section: the force is never at a floor well below its excited level "
            f"(1st/95th percentile of its {w}-sample sd differ {active / max(floor, 1e-300):.3g}x)"
        )
    quiet = s <= QUIET_FACTOR * floor
    out = []
    for a, b in _runs(quiet):
        # window k covers samples k .. k+w-1: the force is quiet on [a + w - 1, b) shrunk by one window
        lo, hi = a + w, b - 1
        if hi - lo >= MIN_STRETCH:
            out.append((lo, hi))
    if not out:
        return f"no zero-input section of at least {MIN_STRETCH} samples (force at its floor only briefly)"
    return out


def _block_var(x: np.ndarray, b: int) -> np.ndarray:
    m = x.size // b
    B = x[: m * b].reshape(m, b)
    return B.var(axis=1)


def _decayed_start(x: np.ndarray, fs: float) -> int | None:
    """First sample of ``x`` (a quiet stretch) after which a free decay has died
    out (its energy below DECAY_RESIDUE x the floor's variance), or None.

    Block variances (blocks of one window); the floor is the median of the last
    third; the decay runs from the stretch's start to the first block below
    2x the floor; its energy's decay rate is fitted on the blocks between 1x
    and 1000x the floor above it and extrapolated down to DECAY_RESIDUE."""
    b = window_samples(fs)
    v = _block_var(x, b)
    if v.size < 6:
        return None
    floor = float(np.median(v[-max(3, v.size // 3) :]))
    if not floor > 0:
        return None
    excess = v - floor
    down = np.flatnonzero(v <= 2.0 * floor)
    if down.size == 0:
        return None
    last = int(down[0]) - 1  # last block of the decay (-1: none)
    if last < 0:
        return 0
    sel = np.arange(last + 1)
    sel = sel[(excess[sel] > floor) & (excess[sel] < 1e3 * floor)]
    rate = None
    if sel.size >= 3:
        slope = np.polyfit(sel, np.log(excess[sel]), 1)[0]
        if slope < 0:
            rate = -slope  # per block, in log energy
    if rate is None:
        return (last + 4) * b
    extra = np.log(max(excess[last], floor) / (DECAY_RESIDUE * floor)) / rate
    return int(np.ceil((last + 1 + extra) * b))


def zero_input_noise(x, sections, fs: float):
    """Noise sd of one channel in the zero-input ``sections`` (from
    :func:`quiet_sections`): ``(sd, dof, detail, spans)`` with ``spans`` the
    sample ranges used, or a sentence saying why not."""
    x = np.asarray(x, float)
    used, rss, dof, why = [], 0.0, 0, []
    for a, b in sections:
        seg = x[a:b]
        start = _decayed_start(seg, fs)
        if start is None or b - (a + start) < MIN_STRETCH:
            why.append(f"{a / fs:.1f}-{b / fs:.1f} s: the free decay has not died out")
            continue
        seg = seg[start:]
        t = np.arange(seg.size)
        r = seg - np.polyval(np.polyfit(t, seg, 1), t)
        h = seg.size // 2
        s1, s2 = np.std(r[:h]), np.std(r[h:])
        if max(s1, s2) > (1.0 + HALF_TOLERANCE / np.sqrt(h)) * min(s1, s2):
            why.append(f"{a / fs:.1f}-{b / fs:.1f} s: not stationary (halves' sd {s1:.3g}, {s2:.3g})")
            continue
        used.append((a + start, b))
        rss += float(r @ r)
        dof += seg.size - 2
    if dof < MIN_TOTAL:
        reason = "; ".join(why) if why else "too short"
        return f"no usable zero-input section of {MIN_TOTAL} samples in all ({reason})"
    spans = ", ".join(f"{a / fs:.1f}-{b / fs:.1f} s" for a, b in used)
    return (
        float(np.sqrt(rss / dof)),
        float(dof),
        f"zero-input sections {spans} ({sum(b - a for a, b in used) / fs:.1f} s, free decay skipped)",
        tuple(used),
    )


def excited_band(force, fs: float, level: float = 0.01) -> tuple[float, float]:
    """(f_min, f_max) [Hz] where the force's PSD exceeds ``level`` x its peak
    (:func:`volterra.excited_band` on 4 s Hann segments, the mean removed)."""
    f = np.asarray(force, float)
    return volterra.excited_band(f, fs, level=level, nperseg=min(f.size, int(4 * fs)))


def noise_band(force, fs: float):
    """The quiet band ``(lo, hi)`` [Hz] above the excitation (3x the top of the
    excited band to 0.45 fs), or a sentence saying why there is none."""
    try:
        _, f_hi = excited_band(force, fs)
    except ValueError as exc:
        return f"no quiet band: {exc}"
    lo, hi = BAND_HARMONIC * f_hi, BAND_TOP * fs
    if hi - lo < BAND_LINES * fs / 256:
        return (
            f"no quiet band: the force excites up to {f_hi:.4g} Hz and fs = {fs:.4g} Hz leaves no band "
            f"from {BAND_HARMONIC:g}x that to {BAND_TOP:g} fs = {hi:.4g} Hz"
        )
    return lo, hi


def band_noise(x, fs: float, band):
    """White-noise sd of one channel from its PSD in ``band`` [Hz]: ``(sd, dof,
    detail, ())`` with ``sd^2 = mean PSD x fs / 2`` (one-sided PSD of white noise
    of variance v: 2 v / fs), the lines above 4x the band's median (harmonics,
    a mode) left out; or a sentence saying why not: too few lines, or a level
    that changes more than :data:`WHITE_RATIO` across the band (coloured noise,
    whose level there does not stand for the excited band's, or the record's
    own harmonics filling it)."""
    x = np.asarray(x, float)
    nper = min(x.size, 256)
    f, p = welch(x, fs=fs, nperseg=nper, detrend="linear")
    sel = (f >= band[0]) & (f <= band[1])
    if sel.sum() < BAND_LINES:
        return f"the band {band[0]:.4g}-{band[1]:.4g} Hz holds fewer than {BAND_LINES} PSD lines"
    pb = p[sel]
    keep = pb <= 4.0 * np.median(pb)
    # its level at the two ends: the medians of its lowest and highest thirds (a harmonic line does
    # not move a median; a coloured noise's slope, or harmonics filling a third, do)
    third = max(1, pb.size // 3)
    a, b = float(np.median(pb[:third])), float(np.median(pb[-third:]))
    change = max(a / b, b / a) if min(a, b) > 0 else np.inf
    if change > WHITE_RATIO:
        return (
            f"the quiet band {band[0]:.4g}-{band[1]:.4g} Hz does not hold white noise (its level changes "
            f"{change:.3g}x across it: coloured noise, or the record's own harmonics filling it)"
        )
    n_seg = max(1, (x.size - nper) // (nper // 2) + 1)
    return (
        float(np.sqrt(np.mean(pb[keep]) * fs / 2.0)),
        float(keep.sum() * n_seg),
        f"quiet band {band[0]:.4g}-{band[1]:.4g} Hz (white noise assumed)",
        (),
    )
