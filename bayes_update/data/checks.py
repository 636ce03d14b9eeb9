"""Cheap checks of one channel of a record, for the inspection report:
offset, drift, clipping (plain functions of a 1-D array, any unit); and the
one check every command makes of a record's force (:func:`require_live_force`)."""

from __future__ import annotations

import numpy as np

from bayes_update.data.format import DatasetError

#: the slow trend is read from Hann-weighted means over windows of 1/TREND_BLOCKS of
#: the record, every half window
TREND_BLOCKS = 8
#: ... and no shorter than this many periods of the lowest excited frequency: a Hann
#: window over two or more cycles leaves at most 2.4 % of a line's amplitude (its
#: transform is sinc(k) / (1 - k^2) at k cycles a window); over half a cycle (a 2 Hz
#: multisine line in 1/8 of a 2-s record) it leaves most of it, which read as a drift
#: of 40-65 % of the rms on records without any
TREND_CYCLES = 2.0
#: a run of this many consecutive samples at the channel's max or min is clipping, and so
#: are more samples at them than CLIP_COUNT and CLIP_SHARE of the record (a clipped
#: record sampled at 2.5x its band has runs of 1-2 samples only)
CLIP_RUN = 3
CLIP_COUNT = 8
CLIP_SHARE = 1e-3


def offset(x) -> float:
    """The channel's mean over the record [its unit] (a sensor offset, for a
    response whose own mean is zero)."""
    return float(np.mean(np.asarray(x, float)))


def trend(x, min_window: int = 0) -> np.ndarray:
    """The slow trend of a record: its Hann-weighted means over windows of
    1/:data:`TREND_BLOCKS` of the record or ``min_window`` samples, the longer,
    one every half window, minus the record's mean [its unit].  An oscillation
    with two or more cycles per window averages out (the Hann window leaks
    little); a drift does not.  Raises ``ValueError`` when the record holds
    fewer than two such windows."""
    x = np.asarray(x, float)
    m = max(x.size // TREND_BLOCKS, int(min_window))
    if m < 4 or 2 * m > x.size:
        raise ValueError(
            f"a record of {x.size} samples is too short for a trend over windows of {max(m, 4)} samples (at least two)"
        )
    w = np.hanning(m + 2)[1:-1]
    starts = np.arange(0, x.size - m + 1, m // 2)
    return np.array([w @ x[s : s + m] for s in starts]) / w.sum() - x.mean()


def drift(x, fs: float | None = None, lowest_hz: float | None = None) -> float:
    """Peak-to-peak of the slow trend (:func:`trend`) over the record, as a share
    of the record's rms about its mean [-] (0.05: the channel drifts by 5 % of
    its rms).  With the sampling rate ``fs`` [Hz] and the lowest excited
    frequency ``lowest_hz`` [Hz], the trend's windows span at least
    :data:`TREND_CYCLES` periods of it, so the excitation is not read as a
    drift; ``nan`` when the record is too short for two such windows (a drift
    cannot then be told from the excitation's lowest lines)."""
    x = np.asarray(x, float)
    window = 0
    if lowest_hz is not None:
        if fs is None or not (fs > 0 and lowest_hz > 0):
            raise ValueError(f"drift needs fs > 0 and lowest_hz > 0 together (got fs={fs}, lowest_hz={lowest_hz})")
        window = int(np.ceil(TREND_CYCLES * fs / lowest_hz))
    rms = float(np.std(x))
    try:
        span = float(np.ptp(trend(x, window)))
    except ValueError:
        if window and 2 * window > x.size:
            return float("nan")
        raise
    return span / rms if rms > 0 else 0.0


def clipping(x) -> dict:
    """Samples at the channel's extreme values: ``{"clipped", "longest_run",
    "at_limits"}``; ``clipped`` when a run of at least :data:`CLIP_RUN`
    consecutive samples sits at the max or at the min, or more than
    :data:`CLIP_COUNT` and :data:`CLIP_SHARE` of the samples do (an amplifier
    or ADC range exceeded).  Exact equality (a recorder's clipped values are
    equal); a coarsely quantised record of a steady sine (the top code hit at
    many peaks) can be reported clipped when it is not."""
    x = np.asarray(x, float)
    longest, total = 0, 0
    for limit in (x.max(), x.min()):
        at = x == limit
        total += int(at.sum())
        d = np.diff(np.concatenate([[0], at.astype(np.int8), [0]]))
        runs = np.flatnonzero(d == -1) - np.flatnonzero(d == 1)
        longest = max(longest, int(runs.max()) if runs.size else 0)
    if x.max() == x.min():
        total = x.size
    many = total > max(CLIP_COUNT, CLIP_SHARE * x.size)
    return {"clipped": bool(longest >= CLIP_RUN or many), "longest_run": longest, "at_limits": total}


def require_live_force(record) -> None:
    """Raise :class:`DatasetError` (naming the file and the test) when a test's
    force is zero or constant over its whole record: it excites nothing a model
    could be compared with.  Quiet sections within a record are fine."""
    force = np.asarray(record.force, float)
    span, top = float(np.ptp(force)), float(np.max(np.abs(force)))
    if not span > 1e-12 * top:
        what = "zero" if top == 0 else f"constant ({force[0]:.6g} N)"
        raise DatasetError(
            f"{record.source or record.file}: test {record.name!r} (role {record.role!r}): "
            f"its force is {what} over the whole record, so it excites nothing the model "
            "could be compared with; check the force column (channel, scaling) or remove "
            "the test from dataset.json"
        )
