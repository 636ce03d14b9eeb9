"""How a modal model's modes move with the level, against the records (the ``diagnose`` and
``signature`` hooks of :class:`~bayes_update.models.modal.ModalModel` in the discrepancy workflow).

A joint shows itself in how its mode's frequency and damping move with the level: a cubic
spring moves the frequency (up when it hardens), a cubic damper raises the damping, a smooth
Coulomb friction damps small amplitudes most, a Jenkins element lowers the frequency and raises
the damping as it slips, a clearance raises the frequency once its gap closes.  The first look's
estimator (:func:`bayes_update.data.inspect.level_dependence`: the equivalent linear modes of
each test) reads each measured record and the model's response to the same recorded force, so
that what it makes of a nonlinear record (a sweep, a distorted multisine) is the same on both
sides.  The number an element's physics should shrink is their difference for its mode: the
median over the tests of hypot(the frequency's difference in %, the damping ratio's in percentage
points).  The median, not the rms: the estimator can fail on one test (on the GVT-like wing's high
sweep it read the 3.9 Hz joint mode at 4.25 Hz), and one such test would be the whole rms.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

__all__ = ["MEANING", "diagnose", "distortion_against", "signature"]

#: what :func:`signature`'s number is
MEANING = (
    "the mode's frequency and damping in every test, model against measured (the first look's "
    "equivalent linear modes): median over the tests of hypot(the frequency's difference [%], the "
    "damping ratio's [percentage points])"
)


def diagnose(model, dataset, theta) -> dict:
    """``{"measured", "model": [per mode {"freq_hz": {test file: f}, "damping_ratio": {...}}],
    "mismatch": [per mode, the median over the tests both show it in of hypot(100 df / f,
    100 dzeta)], "distortion": the odd and even lines of every periodic test, measured and model
    (:func:`distortion_against`)}`` for the model at ``theta`` [its parameters] against ``dataset``'s records
    (NaN for a mode no test shows on both sides)."""
    from bayes_update.data.inspect import level_dependence

    fs = float(dataset.sampling_rate_hz)
    modes = [tuple(m) for m in model.modes]
    runs = [model.simulate(theta, t.force - np.mean(t.force), fs) for t in dataset.tests]
    simulated = dataclasses.replace(
        dataset, tests=[dataclasses.replace(t, response=np.asarray(y)) for t, y in zip(dataset.tests, runs)]
    )
    measured, mine = level_dependence(dataset, modes), level_dependence(simulated, modes)
    return {
        "measured": measured,
        "model": mine,
        "mismatch": [_mismatch(a, b) for a, b in zip(measured, mine)],
        "distortion": distortion_against(dataset, runs),
    }


def distortion_against(dataset, runs) -> dict:
    """{test file: {sensor: {class: {"measured_db", "model_db", "measured_detected",
    "model_detected"}}}} for every periodic test: :func:`volterra.distortion` of the record and
    of the model's response ``runs`` (one (n, S) array per test) to the same recorded force (its
    noise in both), each class's distortion in dB of the output (-inf where not above the
    noise): whether the model's nonlinearity puts what the structure's puts on the odd and even
    lines."""
    from volterra.distortion import distortion
    from volterra.periods import PeriodLayout, find_periods

    fs = float(dataset.sampling_rate_hz)
    out = {}
    for t, y in zip(dataset.tests, runs):
        layout = find_periods(t.force, t.period_samples)
        if not isinstance(layout, PeriodLayout):
            continue
        names = [n for n, _ in t.sensors]
        try:
            sides = [distortion(t.force, r, fs, layout, sensors=names) for r in (t.response, np.asarray(y))]
        except ValueError:
            continue
        out[t.file] = {
            n: {
                c: {
                    "measured_db": sides[0].sensors[n][c]["level_db"],
                    "model_db": sides[1].sensors[n][c]["level_db"],
                    "measured_detected": sides[0].sensors[n][c]["detected"],
                    "model_detected": sides[1].sensors[n][c]["detected"],
                }
                for c in sides[0].sensors[n]
            }
            for n in names
        }
    return out


def _mismatch(measured: dict, mine: dict) -> float:
    both = [k for k in measured["freq_hz"] if k in mine["freq_hz"]]
    if not both:
        return math.nan
    d2 = [
        (100 * (mine["freq_hz"][k] / measured["freq_hz"][k] - 1)) ** 2
        + (100 * (mine["damping_ratio"][k] - measured["damping_ratio"][k])) ** 2
        for k in both
    ]
    return float(np.sqrt(np.median(d2)))


def signature(model, effect: str, diagnostics: dict):
    """(key, meaning, value) of the number the candidate element ``effect`` should shrink: its
    mode's mismatch (:func:`diagnose`); for an element at a sensor's point, which acts on every
    mode, the rms over the modes both sides show (each one's a median over the tests).  None for
    a name that is not a candidate."""
    element = next((e for e in model.candidates if e.name == effect), None)
    if element is None or diagnostics is None:
        return None
    mismatch = np.asarray(diagnostics["mismatch"], float)
    if element.at is None:
        return f"mode {element.mode}", MEANING, float(mismatch[element.index])
    seen = mismatch[np.isfinite(mismatch)]
    value = float(np.sqrt(np.mean(seen**2))) if seen.size else math.nan
    return f"every mode (a joint at {element.where})", MEANING, value
