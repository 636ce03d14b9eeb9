"""What a periodic record's unexcited lines hold beyond the noise: odd and even distortion.

A periodic input excites the lines k of a set E (multiples of the period's
line spacing).  A nonlinearity of degree n puts output on sums of n lines of
+-E.  When every excited k is an odd multiple of g (the greatest common
divisor of E; an odd multisine, or a single sine), the sums sort by parity
(Pintelon & Schoukens 2012, sec. 4.2, "detection lines"):

* odd degrees (a cubic spring, friction, a symmetric clearance) reach only
  odd multiples of g: the unexcited ones are the **odd** lines;
* even degrees (a quadratic spring, a gap on one side, any asymmetry) reach
  only even multiples of g: the **even** lines;
* no degree reaches a line that is not a multiple of g: the **noise** lines
  (there only when g > 1).

With excited lines of both parities (a full multisine) the classes merge:
the unexcited lines are **any** (out of the band, or between random lines).

On every line: the mean over the settled periods Y, its noise variance
s^2 / P from the scatter between the P periods, and the linear response to
what the input itself holds there, H U, taken away (H interpolated (a cubic spline) between
the neighbouring excited lines, inside the excited band: a shaker's force
carries the structure's distortion back, and the linear response to it is not
the structure's nonlinearity).  Per class and sensor:

* ``noise_ratio``: the class's power over its noise power (the sums over its
  lines); about 1 without distortion, with an sd of about
  ``sqrt((1 + 1/(P - 1)) / n)``, n the number of lines of equal noise that
  would give the same (``(sum v)^2 / sum v^2`` of the lines' noise variances v);
* ``detected``: the ratio above 1 by :data:`DETECT_SD` such sds;
* ``level_db``: the distortion's power (its noise taken off) over the output's
  power on the excited lines, in dB (``-inf`` where not above the noise).

The input's own unexcited lines are read the same way (``force``): a force
that holds distortion tells of shaker-structure interaction.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import gcd

import numpy as np
from scipy.interpolate import CubicSpline

from .lines import period_spectra
from .periods import PeriodLayout, find_periods

__all__ = ["Distortion", "distortion"]

#: a class's distortion is detected where its power over its noise is above 1 by this many sds
DETECT_SD = 4.0
#: lines up to this multiple of the highest excited line hold the distortion looked for (degree 3)
REACH = 3
#: and none above this share of the sampling rate (anti-aliasing filters)
TOP_SHARE = 0.45


@dataclass(frozen=True)
class Distortion:
    """The distortion of one periodic record (module docstring).

    ``classes``: {class: number of lines} of the classes the excitation has
    ('odd', 'even', 'noise' or 'any'); ``sensors``: {sensor: {class: {"noise_ratio",
    "detected", "level_db", "sd"}}}, the same for ``force``; ``periods`` P,
    ``spacing`` the line spacing [Hz], ``excited`` the excited lines' frequencies [Hz];
    ``lines``: {class or "excited": frequencies [Hz]} and ``power``: {sensor: {class or
    "excited": (power, noise power) of each line}} (DFT / sqrt(N), squared: the
    classic plot of the lines)."""

    classes: dict
    sensors: dict
    force: dict
    periods: int
    spacing: float
    excited: np.ndarray
    lines: dict
    power: dict

    def to_dict(self) -> dict:
        """The numbers, JSON-ready (the line spectra left out; a level not above the noise,
        -inf dB, as None)."""

        return {
            "classes": dict(self.classes),
            "periods": self.periods,
            "spacing_hz": self.spacing,
            "sensors": {name: json_ready(classes) for name, classes in self.sensors.items()},
            "force": json_ready(self.force),
        }

    @property
    def parity(self) -> bool:
        """The excitation separates odd from even distortion."""
        return "odd" in self.classes

    def verdict(self, sensor: str) -> str:
        """One line on a sensor's distortion."""
        return class_verdict(self.sensors[sensor], "lines")


def class_numbers(power: float, noise: float, sd: float, reference: float) -> dict:
    """A class's numbers from its power and its noise power (summed over its lines or windows),
    the sd of their ratio and the output's power it is measured against: ``noise_ratio``,
    ``sd``, ``detected`` (the ratio above 1 by :data:`DETECT_SD` sds) and ``level_db`` (the
    power less its noise over ``reference``; -inf where not above the noise)."""
    ratio = power / noise if noise > 0 else (float("inf") if power > 0 else float("nan"))
    above = power - noise
    level = 10 * np.log10(above / reference) if above > 0 and reference > 0 else float("-inf")
    return {"noise_ratio": ratio, "sd": sd, "detected": bool(ratio > 1.0 + DETECT_SD * sd), "level_db": float(level)}


def json_ready(classes: dict) -> dict:
    """``{class: numbers}`` with every non-finite number (a level not above the noise, a class
    not read) as None."""

    def value(v):
        return None if isinstance(v, float) and not np.isfinite(v) else v

    return {c: {k: value(v) for k, v in r.items()} for c, r in classes.items()}


def class_verdict(classes: dict, what: str) -> str:
    """One line on a channel's classes (the noise class left out), ``what`` naming what was
    read ("lines", "harmonics")."""
    parts = []
    for cls, r in classes.items():
        if cls == "noise":
            continue
        if not np.isfinite(r["noise_ratio"]):
            parts.append(f"{cls} {what} not read (beyond the band, or too few frames)")
            continue
        lvl = f"{r['level_db']:.0f} dB of the output" if r["detected"] else "at the noise"
        parts.append(f"{cls} {what} {r['noise_ratio']:.3g}x their noise ({lvl})")
    return "; ".join(parts)


def line_classes(excited: np.ndarray, top: int) -> dict:
    """{class: line indices} of the unexcited lines 1 .. ``top`` - 1 (module docstring)."""
    k_exc = np.flatnonzero(excited)
    g = 0
    for k in k_exc:
        g = gcd(g, int(k))
    k = np.arange(1, top)
    k = k[~excited[1:top]]
    if g == 0:
        return {}
    multiple = k % g == 0
    if np.all((k_exc // g) % 2 == 1):
        out = {"odd": k[multiple & ((k // g) % 2 == 1)], "even": k[multiple & ((k // g) % 2 == 0)]}
        if g > 1:
            out["noise"] = k[~multiple]
        return out
    return {"any": k}


def _frf_between(Um, Ym, excited, k):
    """(S, len(k)) H on lines k inside the excited band, interpolated between the excited
    lines' Y / U; 0 outside the band."""
    k_exc = np.flatnonzero(excited)
    inside = (k > k_exc[0]) & (k < k_exc[-1])
    H = np.zeros((Ym.shape[0], k.size), complex)
    if k_exc.size < 2 or not inside.any():
        return H
    # a cubic spline through the excited lines' H (each sensor a column): a resonance a few
    # lines wide is curved between them (linear interpolation left a force's even lines, 3 %
    # of it, 1.46x the output's noise through a band-pass; the spline takes a force's 2 % to
    # -62 .. -74 dB of the output, at its noise, over 12 seeds: tests/test_distortion.py)
    He = Ym[:, k_exc].T / Um[k_exc, None]
    H[:, inside] = CubicSpline(k_exc, He, axis=0)(k[inside]).T
    return H


def _class_stats(Ymean, noise_var, excited_power, n_periods) -> dict:
    """noise_ratio, its sd, detected and level_db of one class on one channel."""
    power, noise = float(np.sum(np.abs(Ymean) ** 2)), float(np.sum(noise_var))
    # lines of unequal noise (the force sensor's noise through a resonance) count as fewer
    n_eff = noise**2 / float(np.sum(np.square(noise_var))) if noise > 0 else float(Ymean.size)
    sd = float(np.sqrt((1.0 + 1.0 / max(n_periods - 1, 1)) / n_eff))
    return class_numbers(power, noise, sd, excited_power)


def _drift_removed(x, layout: PeriodLayout):
    """``x`` less its linear drift, the slope read from the change of the period means from
    period 1 to the last (a line fitted to the record would take a slope from the periodic
    signal itself, whose periods then all carry the same ramp: lines at 1/k on every line)."""
    x = np.asarray(x, float)
    if layout.n_periods < 3:
        return x
    N = layout.period
    means = x[layout.start : layout.stop].reshape((layout.n_periods, N) + x.shape[1:]).mean(axis=1)
    slope = (means[-1] - means[1]) / (N * (layout.n_periods - 2))
    t = np.arange(x.shape[0]).reshape((-1,) + (1,) * (x.ndim - 1))
    return x - slope * t


def distortion(u, y, fs: float, layout: PeriodLayout | None = None, sensors=None) -> Distortion:
    """The odd and even distortion of a periodic record (module docstring).

    ``u`` (n,) the input, ``y`` (n,) or (n, S) the responses, ``fs`` [Hz];
    ``layout``: the record's periods (default: found in ``u``); ``sensors``:
    the responses' names (default ``y0``, ``y1``, ...).  Raises ValueError where
    the record is not periodic or holds fewer than two settled periods."""
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    y = y[:, None] if y.ndim == 1 else y
    if y.shape[0] != u.size:
        raise ValueError(f"u has {u.size} samples and y {y.shape[0]}: one record, the same samples")
    if layout is None:
        layout = find_periods(u)
        if isinstance(layout, str):
            raise ValueError(f"no distortion analysis: the record is not periodic ({layout})")
    sensors = [f"y{j}" for j in range(y.shape[1])] if sensors is None else list(sensors)
    U, Y, excited = period_spectra(_drift_removed(u, layout), _drift_removed(y, layout), layout)
    P = U.shape[0]
    if P < 2 or not excited.any():
        raise ValueError(
            f"no distortion analysis: {P} settled period(s) and {int(excited.sum())} excited lines "
            "(the scatter between at least two periods measures the noise)"
        )
    top = min(REACH * int(np.flatnonzero(excited)[-1]) + 1, int(TOP_SHARE * layout.period) + 1, excited.size)
    classes = line_classes(excited, top)
    Um, Ym = U.mean(axis=0), Y.mean(axis=1)
    spacing = fs / layout.period
    out = {name: {} for name in sensors}
    var_y = np.sum(np.abs(Y - Ym[:, None]) ** 2, axis=1) / (P - 1) / P
    lines = {"excited": np.flatnonzero(excited) * spacing}
    power = {name: {"excited": (np.abs(Ym[s, excited]) ** 2, var_y[s, excited])} for s, name in enumerate(sensors)}
    force = {}
    for cls, k in classes.items():
        if k.size == 0:
            continue
        lines[cls] = k * spacing
        # each period's output less the linear response to its own input on these lines: the
        # scatter of the difference is its noise, the force sensor's own noise included
        Z = Y[:, :, k] - _frf_between(Um, Ym, excited, k)[:, None, :] * U[None, :, k]
        Zm = Z.mean(axis=1)
        var_z = np.sum(np.abs(Z - Zm[:, None]) ** 2, axis=1) / (P - 1) / P
        for s, name in enumerate(sensors):
            excited_power = float(np.sum(np.abs(Ym[s, excited]) ** 2))
            out[name][cls] = _class_stats(Zm[s], var_z[s], excited_power, P)
            power[name][cls] = (np.abs(Zm[s]) ** 2, var_z[s])
        var_u = np.sum(np.abs(U[:, k] - Um[k]) ** 2, axis=0) / (P - 1) / P
        force[cls] = _class_stats(Um[k], var_u, float(np.sum(np.abs(Um[excited]) ** 2)), P)
    return Distortion(
        classes={c: int(k.size) for c, k in classes.items() if k.size},
        sensors=out,
        force=force,
        periods=P,
        spacing=spacing,
        excited=lines["excited"],
        lines=lines,
        power=power,
    )
