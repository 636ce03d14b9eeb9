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
    100 dzeta)], "distortion": the odd and even lines of every periodic test and the harmonics of
    every sweep, measured and model (:func:`distortion_against`), "harmonics_left": what of it the
    model does not make (:func:`harmonics_left`)}`` for the model at ``theta`` [its parameters]
    against ``dataset``'s records (NaN for a mode no test shows on both sides)."""
    from bayes_update.data.inspect import level_dependence

    fs = float(dataset.sampling_rate_hz)
    modes = [tuple(m) for m in model.modes]
    runs = [model.simulate(theta, t.force - np.mean(t.force), fs) for t in dataset.tests]
    simulated = dataclasses.replace(
        dataset, tests=[dataclasses.replace(t, response=np.asarray(y)) for t, y in zip(dataset.tests, runs)]
    )
    measured, mine = level_dependence(dataset, modes), level_dependence(simulated, modes)
    distortion = distortion_against(dataset, runs)
    return {
        "measured": measured,
        "model": mine,
        "mismatch": [_mismatch(a, b) for a, b in zip(measured, mine)],
        "distortion": distortion,
        "harmonics_left": harmonics_left(distortion),
    }


#: the model makes a class of distortion when it reaches the record's level within this [dB]
HARMONICS_MARGIN_DB = 6.0


def harmonics_left(distortion: dict) -> list:
    """The distortion the record holds and the model does not make (:func:`distortion_against`):
    ``[{"test", "sensor", "class", "measured_db", "model_db"}, ...]`` for every class detected
    in the record where the model's is not detected or more than :data:`HARMONICS_MARGIN_DB`
    below it (a factor 2 in amplitude), the largest gap first.  What a named element leaves
    unexplained in harmonics: a symmetric element makes no even harmonics, a smooth one too
    little of the higher ones."""
    out = []
    for test, sensors in distortion.items():
        for sensor, classes in sensors.items():
            for cls, r in classes.items():
                if cls == "noise" or not r["measured_detected"]:
                    continue
                model = r["model_db"] if r["model_detected"] else -math.inf
                if model < r["measured_db"] - HARMONICS_MARGIN_DB:
                    row = {"test": test, "sensor": sensor, "class": cls, "measured_db": r["measured_db"]}
                    out.append({**row, "model_db": model if math.isfinite(model) else None})
    return sorted(out, key=lambda r: -math.inf if r["model_db"] is None else r["model_db"] - r["measured_db"])


def distortion_against(dataset, runs) -> dict:
    """{test file: {sensor: {class: {"measured_db", "model_db", "measured_detected",
    "model_detected"}}}} for every periodic test and sine sweep: :func:`volterra.record_distortion`
    of the record and of the model's response ``runs`` (one (n, S) array per test) to the same
    recorded force (its noise in both), each class's distortion in dB of the output (-inf where
    not above the noise): whether the model's nonlinearity puts what the structure's puts on the
    odd and even lines (a sweep: harmonics)."""
    from volterra.sweep_distortion import record_distortion

    fs = float(dataset.sampling_rate_hz)
    out = {}
    for t, y in zip(dataset.tests, runs):
        names = [n for n, _ in t.sensors]
        try:
            sides = [record_distortion(t.force, r, fs, t.period_samples, names) for r in (t.response, np.asarray(y))]
        except ValueError:
            continue
        if sides[0] is None or sides[1] is None:
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
