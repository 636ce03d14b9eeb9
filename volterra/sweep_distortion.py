"""The harmonics of a sine sweep: odd and even distortion of a record whose input is one
sine of slowly changing frequency.

A sweep has no unexcited lines to read (:mod:`volterra.distortion` needs a periodic
input); at each instant, though, its input is one sine of frequency f0(t), and a
nonlinearity of degree n puts output at multiples of it up to n f0: the odd
multiples (3 f0, 5 f0) from odd degrees (a cubic spring, friction, a symmetric
clearance), the even ones (2 f0, 4 f0) from even degrees (a quadratic spring, a gap
on one side, any asymmetry).  Read on a short-time Fourier transform (Hann frames,
half overlapping):

* f0 of each frame from the input's spectral peak; frames where the input is not
  one sine (its peak holds less than 80 % of the frame's power, or
  silence) are left out;
* the linear response taken away in time, r = y - h * u, with h the record's own
  impulse response: the swept band deconvolved over the whole record and kept over
  the lags where a linear response is, which a sweep's harmonics never reach (Farina
  2000: harmonic k at frequency f was made when the sweep was at f / k, at a lag of
  t(f) - t(f / k)).  Taken away in time, the fundamental goes with its leakage and a
  fast sweep's transients (the ringing of the modes it passed), and the linear
  response to what the force holds at k f0 (a shaker's force carries the structure's
  distortion back) is not counted as the structure's;
* on each harmonic k (2 .. ``n_harmonics``) the power of r in a window of a few bins
  (the main lobe plus the drift of k f0 over half a frame), against its noise read at
  the same frequency from the frames where no harmonic is near it (the median over
  them, over ln 2): a sensor's noise may be coloured, and taking the linear response
  away adds the force's noise through the structure's resonances, but neither changes
  with time.  Left out of both: the frames within the kept lags of the sweep's passage
  of the bin's frequency (the noise went with the response there) and, for a sweep
  down, as long as the structure rings after it.

A record that sweeps up and down again is read as two sweeps (deconvolved together, the
harmonics of one would land on the other's linear lags); a stepped sine, whose f0 stands
still between steps, as one.

Per class (odd, even) and sensor, summed over the frames and harmonics, the same
numbers as a periodic record's (:class:`volterra.distortion.Distortion`):
``noise_ratio`` (the harmonics' power over their noise, about 1 without distortion),
its ``sd`` (the window's own correlation between bins, :func:`volterra.sweep_frames.bin_covariance`),
``detected`` (the ratio above 1 by :data:`volterra.distortion.DETECT_SD` sds) and ``level_db`` (the
harmonics' power less their noise over the output's power at f0).  The input's own
harmonics are read the same way (``force``), its fundamental left in: its leakage
raises the noise read, so the force's reading errs low.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .distortion import class_numbers, class_verdict, distortion, json_ready
from .periods import PeriodLayout, find_periods
from .sweep_frames import (
    LOBE,
    MIN_FRAMES,
    best_frame,
    bin_covariance,
    first_frame,
    frame_length,
    frame_times,
    frames_of,
    readable,
    spectra,
    track,
)
from .sweep_residual import linear_response, near_passage

__all__ = ["SweepDistortion", "record_distortion", "sweep_distortion"]

#: frames of one sine cover at least this share of a sweep's record (the rest: its rest and decay),
#: and its f0 moves by at most MAX_JUMP_BINS between at least MIN_SMOOTH of neighbouring frames
MIN_COVERED = 0.25
MAX_JUMP_BINS = 2.0
MIN_SMOOTH = 0.8
#: a class is read from at least this many (frame, harmonic) windows, else left unread (NaN): the
#: ratio's normal approximation needs them (one window of a fast sweep read 25x its noise on a
#: linear structure of the front end's corpus, its stated sd 0.77)
MIN_TERMS = 8
#: a bin's noise is read from at least this many frames where no harmonic is near it
MIN_BACKGROUND = 4


@dataclass(frozen=True)
class SweepDistortion:
    """The harmonics of one sweep (module docstring).

    ``classes``: {"odd": harmonics read (3, 5, ...), "even": (2, 4, ...)}; ``sensors``:
    {sensor: {class: {"noise_ratio", "sd", "detected", "level_db"}}}, the same for
    ``force``; ``frames`` used, ``frame_s`` their length [s]; ``f0`` [Hz] each frame's
    frequency; ``harmonics`` and ``noise``: {sensor: (frames, n_harmonics - 1) power of
    harmonics 2 .. and their noise, over the frame's output power at f0} (NaN where not
    read)."""

    classes: dict
    sensors: dict
    force: dict
    frames: int
    frame_s: float
    f0: np.ndarray
    harmonics: dict
    noise: dict

    def to_dict(self) -> dict:
        """The numbers, JSON-ready (the per-frame tracks left out; -inf dB and a class not read,
        NaN, as None)."""

        return {
            "classes": {c: list(k) for c, k in self.classes.items()},
            "sweep": {
                "frames": self.frames,
                "frame_s": self.frame_s,
                "f0_hz": [float(self.f0.min()), float(self.f0.max())],
            },
            "sensors": {name: json_ready(classes) for name, classes in self.sensors.items()},
            "force": json_ready(self.force),
        }

    def verdict(self, sensor: str) -> str:
        """One line on a sensor's harmonics."""
        return class_verdict(self.sensors[sensor], "harmonics")


def sweep_distortion(u, y, fs: float, n_harmonics: int = 5, sensors=None, frame_s: float | None = None):
    """The odd and even harmonics of a sine sweep (module docstring).

    u : (n,) input (force); y : (n,) or (n, S) responses; fs : sampling rate [Hz];
    n_harmonics : the highest harmonic read (at least 3); sensors : S names (default
    ``y0, y1, ...``); frame_s : frame length [s] (default: the power of two under which
    harmonic 3 can be read where the response is largest).  Raises ValueError ("not a
    sweep: ...") when the input is not one: fewer than 8 frames of 8 cycles or more hold one
    sine, they cover less than :data:`MIN_COVERED` of the record, or f0 jumps between them."""
    u = np.asarray(u, float)
    Y = np.asarray(y, float)
    Y = Y[:, None] if Y.ndim == 1 else Y
    if Y.shape[0] != u.size:
        raise ValueError(f"y has {Y.shape[0]} samples, u {u.size}")
    if n_harmonics < 3:
        raise ValueError(f"n_harmonics must be at least 3, got {n_harmonics}")
    names = list(sensors) if sensors is not None else [f"y{j}" for j in range(Y.shape[1])]
    if len(names) != Y.shape[1]:
        raise ValueError(f"{len(names)} sensor names for {Y.shape[1]} responses")
    u, Y = u - u.mean(), Y - Y.mean(axis=0)
    first = first_frame(u, fs)
    f0, keep, _ = track(u, fs, first)
    if f0.size < MIN_FRAMES:
        raise ValueError(f"not a sweep: {f0.size} frames of any length hold one sine (at least {MIN_FRAMES} needed)")
    covered = f0.size * (first // 2) / u.size
    adjacent = np.diff(keep) == 1
    jumps = np.abs(np.diff(f0))[adjacent] * first / fs  # in bins, between neighbouring frames
    smooth = float(np.mean(jumps <= MAX_JUMP_BINS)) if jumps.size else 0.0
    if covered < MIN_COVERED or smooth < MIN_SMOOTH:
        # a random or burst record has frames where one line stands out, its f0 jumping about
        raise ValueError(
            f"not a sweep: frames of one sine cover {100 * covered:.0f} % of the record (at least "
            f"{100 * MIN_COVERED:.0f} %), and f0 moves by at most {MAX_JUMP_BINS:g} bins between "
            f"{100 * smooth:.0f} % of neighbouring frames (at least {100 * MIN_SMOOTH:.0f} %)"
        )
    classes = {"odd": tuple(range(3, n_harmonics + 1, 2)), "even": tuple(range(2, n_harmonics + 1, 2))}
    parts = [
        _segment(u[a:b], Y[a:b], fs, n_harmonics, frame_s, classes)
        for a, b in _one_way(f0, frame_times(keep.max() + 1, first, fs)[keep], fs / first, fs, u.size, first)
    ]
    parts = [p for p in parts if p is not None]
    if not parts:
        raise ValueError(f"not a sweep: no part of it holds {MIN_FRAMES} frames of one sine")

    def stats(channel):
        # each class over the output's power at f0 in the frames where it was read, every part
        return {
            c: _class_stats(
                [t for p in parts for t in p["terms"][channel][c]], sum(p["fundamental"][channel][c] for p in parts)
            )
            for c in classes
        }

    names_out = {name: stats(j) for j, name in enumerate(names)}
    power = {name: np.vstack([p["track"][j][0] for p in parts]) for j, name in enumerate(names)}
    noise = {name: np.vstack([p["track"][j][1] for p in parts]) for j, name in enumerate(names)}
    f0_all = np.concatenate([p["f0"] for p in parts])
    frame_s = parts[0]["frame_s"]
    return SweepDistortion(classes, names_out, stats("force"), int(f0_all.size), frame_s, f0_all, power, noise)


def _one_way(f0, times, df: float, fs: float, n: int, frame: int) -> list:
    """``[(start, stop), ...]`` samples of the parts of a record that sweep one way: a sweep up
    then down again is two sweeps (deconvolved together, the harmonics of one would land on the
    other's linear lags); a stepped sine, whose f0 stands still between steps, one.  ``f0``
    [Hz] at frame ``times`` [s] read on frames of ``frame`` samples, bin ``df`` [Hz]."""
    step = np.diff(f0)
    # f0 is read to a fraction of a bin: a step below a quarter of the frames' bin stands still
    moving = np.abs(step) > 0.25 * df
    way = np.sign(step[moving])
    at = times[1:][moving]
    flips = np.flatnonzero(way[1:] != way[:-1])
    cuts = [0] + [int(round(0.5 * (at[k] + at[k + 1]) * fs)) for k in flips] + [n]
    # a part shorter than MIN_FRAMES frames (f0's jitter read as a turn) joins the one before
    shortest = MIN_FRAMES * frame // 2
    kept = [0]
    for c in cuts[1:-1]:
        if c - kept[-1] >= shortest and n - c >= shortest:
            kept.append(c)
    kept.append(n)
    return list(zip(kept[:-1], kept[1:]))


def _segment(u, Y, fs: float, n_harmonics: int, frame_s, classes) -> dict | None:
    """One sweep's reading (one way): per channel (sensor index, or "force") and class the
    terms (power, noise, bins, frames of noise, bin covariance) and the output's power at f0
    where read; the per-frame tracks; None where it holds too few frames of one sine."""
    if frame_s is None:
        first = first_frame(u, fs)
        f, U, SY = spectra(u, Y, fs, first)
        f0, keep, rate = track(u, fs, first, (f, U))
        if f0.size < MIN_FRAMES:
            return None
        # where the response is large (a nonlinearity acts there: resonances), each sensor alike
        k0 = np.rint(f0 / (f[1] - f[0])).astype(int)
        weight = sum(np.abs(S[k0, keep]) ** 2 / np.max(np.abs(S[k0, keep]) ** 2) for S in SY)
        nper = best_frame(f0, rate, fs, u.size, weight)
    else:
        nper = frame_length(fs, u.size, frame_s)
    f, U, SY = spectra(u, Y, fs, nper)
    f0, keep, rate = track(u, fs, nper, (f, U))
    if f0.size < MIN_FRAMES:
        return None
    T, df = nper / fs, f[1] - f[0]
    times = frame_times(U.shape[1], nper, fs)[keep]
    U = U[:, keep]
    k0 = np.rint(f0 / df).astype(int)
    cols = np.arange(U.shape[1])
    drift = np.abs(rate) * T * T / 2  # bins k f0 moves over half a frame, per harmonic order
    cov = {}

    def covariance(m):
        if m not in cov:
            cov[m] = bin_covariance(nper, m)
        return cov[m]

    def read(R, fundamental, cancelled):
        B, count = _background(np.abs(R) ** 2, f0 / df, drift, n_harmonics, ~cancelled)
        terms, read_in = {c: [] for c in classes}, {c: set() for c in classes}
        track_k = np.full((2, f0.size, n_harmonics - 1), np.nan)
        for k in range(2, n_harmonics + 1):
            w = LOBE + np.ceil(k * drift).astype(int)
            for i in np.flatnonzero(readable(f0, rate, T, k, fs)):
                lo = int(np.rint(k * f0[i] / df)) - w[i]
                bins = slice(max(lo, 0), lo + 2 * w[i] + 1)
                if np.any(count[bins] < MIN_BACKGROUND) or np.any(cancelled[bins, i]):
                    continue
                p, noise = float(np.sum(np.abs(R[bins, i]) ** 2)), float(np.sum(B[bins]))
                m = 2 * int(w[i]) + 1
                terms["odd" if k % 2 else "even"].append((p, noise, m, int(np.min(count[bins])), covariance(m)))
                read_in["odd" if k % 2 else "even"].add(i)
                track_k[:, i, k - 2] = p / fundamental[i], noise / fundamental[i]
        return terms, {c: float(np.sum(fundamental[sorted(read_in[c])])) for c in classes}, track_k

    out = {"terms": {}, "fundamental": {}, "track": {}, "f0": f0, "frame_s": float(T)}
    w1 = LOBE + np.ceil(drift).astype(int)
    for j in range(Y.shape[1]):
        Yk = SY[j][:, keep]
        fund = np.array([_window(Yk[:, i], k0[i], w1[i]) for i in cols])
        # the linear response taken away in time (the fundamental's leakage, the modes' ringing
        # and the response to the force's own harmonics go with it)
        y_lin, before, after, ring = linear_response(u, Y[:, j], fs, f0, rate)
        R = frames_of(Y[:, j] - y_lin, fs, nper)[1][:, keep]
        # frame times from (before) to (after, or as long as the structure rings if longer) after
        # the sweep passed the bin's frequency, and half a frame: there the kept lags took the
        # noise away with the response, and past them a mode still rings (a sweep down: the
        # harmonics at f come after the sweep passed f)
        cancelled = near_passage(f, times, f0, before + T / 2, max(after, ring) + T / 2)
        out["terms"][j], out["fundamental"][j], out["track"][j] = read(R, fund, cancelled)
    fund_u = np.array([_window(U[:, i], k0[i], w1[i]) for i in cols])
    out["terms"]["force"], out["fundamental"]["force"], _ = read(U, fund_u, np.zeros(U.shape, bool))
    return out


def _background(P, centres, drift, n_harmonics: int, usable):
    """Each bin's noise power (from its median over the frames where neither the fundamental nor a
    harmonic up to ``n_harmonics`` + 1 is within its window and a bin of it) and how many
    frames that mean is over.  ``P`` (bins, frames) power, ``centres`` f0 of each frame [bins],
    ``usable`` (bins, frames) the cells whose noise is whole (:func:`volterra.sweep_residual.near_passage`).
    Read at the harmonic's own frequency, not beside it: the channel's noise may be coloured
    (a pink sensor, the force's noise through the structure's resonances, which taking the
    linear response away puts in the residual), but it does not change with time."""
    bins = np.arange(P.shape[0])[:, None]
    clean = np.array(usable, bool)
    for k in range(1, n_harmonics + 2):
        w = LOBE + np.ceil(k * drift) + 1
        clean &= np.abs(bins - k * centres[None, :]) > w[None, :]
    count = clean.sum(axis=1)
    # the median over those frames over ln 2 (a bin's noise power is exponential: its median is
    # ln 2 its mean): a response left in a few frames (a mode ringing past the impulse response
    # kept, the joint's softened ringing) does not raise it
    masked = np.where(clean, P, np.nan)
    masked[count == 0] = 0.0  # no frame: no estimate (NaN below), and no warning of an empty median
    B = np.nanmedian(masked, axis=1) / np.log(2.0)
    return np.where(count > 0, B, np.nan), count


def _window(X, centre: float, w: int) -> float:
    """Power of the bins within ``w`` of the bin nearest ``centre``."""
    c = int(np.rint(centre))
    return float(np.sum(np.abs(X[max(c - w, 0) : c + w + 1]) ** 2))


def _class_stats(terms: list, fundamental: float) -> dict:
    """noise_ratio, sd, detected and level_db of one class from its (power, noise, bins) terms."""
    if len(terms) < MIN_TERMS:
        return {"noise_ratio": float("nan"), "sd": float("nan"), "detected": False, "level_db": float("-inf")}
    p, n, m, n_null, c = (np.array(x, float) for x in zip(*terms))
    power, noise = float(p.sum()), float(n.sum())
    # var(power - noise) = (1 + 1 / n_null) c m mu^2, mu = noise / m the mean bin power (bin_covariance)
    sd = float(np.sqrt(np.sum((1 + 1 / n_null) * c * n**2 / m))) / noise if noise > 0 else 0.0
    return class_numbers(power, noise, sd, fundamental)


def record_distortion(u, y, fs: float, period_samples=None, sensors=None):
    """The odd and even distortion of any record: :func:`volterra.distortion` where the
    input repeats (``period_samples`` [samples], else found), :func:`sweep_distortion` where
    it is a sine sweep, None for another record (random, an impact).  A record that repeats
    but cannot be read raises ValueError (:func:`volterra.distortion`'s message)."""
    layout = find_periods(np.asarray(u, float), period_samples)
    if isinstance(layout, PeriodLayout):
        return distortion(u, y, fs, layout, sensors=sensors)
    try:
        return sweep_distortion(u, y, fs, sensors=sensors)
    except ValueError as exc:
        if str(exc).startswith("not a sweep"):
            return None
        raise
