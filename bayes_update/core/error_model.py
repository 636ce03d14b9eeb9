"""What separates a model's time response from a record besides the parameters: the
error model of every test, estimation and validation alike, for predictive bands.

Each sensor of each test gets two white-in-time Gaussian terms (a band at a
sample needs only the marginal variance there):

* the measurement noise, the sensor's own and the force's through the
  structure (:meth:`bayes_update.core.problem.Problem.test_noise`);
* the model-form error.  On an estimation test it is what the record's
  residual at the test's own best point holds beyond the noise
  (:attr:`bayes_update.core.likelihood.StageScale.model_form_rms`, relative to
  the record's rms).  On any other test it is carried from the estimation tests
  by the test's level (the rms of its force) in two parts, per sensor:

  - a part that does not grow with the level, the smallest excess any
    estimation test shows (in the sensor's unit): sensor noise does not grow
    with the level, so what the lowest test leaves beyond the noise model is
    mostly the noise's own form (a coloured noise taken for white, a sensor's
    dynamics);
  - a part that grows with the level, relative to the response: what the
    other tests leave beyond that, through a power law ``rho(a) = rho_k (a /
    a_k)^p``, the exponent fitted where two tests show such a part, held
    within [0, 2] (a linear effect's share stays, a quadratic damper's grows as
    a, a cubic spring's as a^2); where one test does, the variance averaged over
    p uniform in [0, 2].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ErrorModel", "carried_error", "error_models"]

#: the largest exponent of the model-form error's share against the level (a cubic term's)
MAX_EXPONENT = 2.0
#: a relative model-form error below this counts as none (no power law through it)
FLOOR = 1e-6


@dataclass(frozen=True)
class ErrorModel:
    """A test's error model per sensor: ``noise_sd`` [sensor unit], the model-form
    error's level-independent part ``form_sd`` [sensor unit] and its share of the
    response's rms ``form_share``, and where the model-form error comes from."""

    noise_sd: np.ndarray
    form_share: np.ndarray
    source: str
    form_sd: np.ndarray | None = None

    def sd(self, response_rms) -> np.ndarray:
        """The total error's sd per sensor for a response of that rms per sensor."""
        flat = 0.0 if self.form_sd is None else self.form_sd
        return np.sqrt(self.noise_sd**2 + flat**2 + (self.form_share * np.asarray(response_rms, float)) ** 2)

    def to_dict(self, sensors) -> dict:
        out = {
            "noise_sd": dict(zip(sensors, map(float, self.noise_sd))),
            "model_form_share": dict(zip(sensors, map(float, self.form_share))),
            "model_form_source": self.source,
        }
        if self.form_sd is not None:
            out["model_form_sd"] = dict(zip(sensors, map(float, self.form_sd)))
        return out


def _level(force) -> float:
    f = np.asarray(force, float)
    return float(np.sqrt(np.mean((f - f.mean()) ** 2)))


def error_models(problem, likelihood) -> dict:
    """``{test name: ErrorModel}`` for every test of ``problem`` (module docstring);
    the model-form shares from ``likelihood`` (0 where it did not measure them)."""
    sensors = [name for name, _ in problem.sensors]
    known = {}
    for stage, test in problem.tests.items():
        rms = (likelihood.scales[stage].model_form_rms or {}) if stage in likelihood.scales else {}
        y = test.response.reshape(len(test.response), -1)
        known[test.name] = (
            _level(test.force),
            np.array([rms.get(s, 0.0) for s in sensors], float),
            np.sqrt(np.mean(y**2, axis=0)),
        )
    out = {}
    for test in list(problem.tests.values()) + list(problem.validation.values()):
        noise = np.asarray(problem.test_noise(test.name), float)
        if test.name in known:
            out[test.name] = ErrorModel(
                noise, known[test.name][1], "the residual at its own best point beyond the noise"
            )
        else:
            flat, share, source = carried_error(_level(test.force), list(known.values()))
            out[test.name] = ErrorModel(noise, share, source, flat)
    return out


def _mean_power(ratio: float) -> float:
    """The mean of ``ratio^(2 p)`` over p uniform in [0, MAX_EXPONENT]."""
    q = 2.0 * MAX_EXPONENT * math.log(ratio)
    return 1.0 if abs(q) < 1e-12 else math.expm1(q) / q


def carried_error(level: float, known: list) -> tuple[np.ndarray, np.ndarray, str]:
    """``(form_sd, form_share, how)`` at force level ``level`` from ``[(level_k, share_k,
    rms_k)]`` of the estimation tests, per sensor (module docstring)."""
    levels = np.array([k[0] for k in known])
    excess = np.array([k[1] * k[2] for k in known])  # (tests, sensors) absolute excess
    flat = excess.min(axis=0)
    growing = np.sqrt(np.maximum(excess**2 - flat**2, 0.0)) / np.array([k[2] for k in known])
    share = np.zeros_like(flat)
    for j in range(len(flat)):
        has = np.flatnonzero(growing[:, j] > FLOOR)
        if has.size == 0:
            continue
        if has.size == 1:
            # the exponent unknown in [0, MAX_EXPONENT]: the mean variance over it, uniform
            i = has[0]
            share[j] = growing[i, j] * math.sqrt(_mean_power(level / levels[i]))
            continue
        else:
            lo, hi = has[np.argmin(levels[has])], has[np.argmax(levels[has])]
            p = (
                float(
                    np.clip(
                        np.log(growing[hi, j] / growing[lo, j]) / math.log(levels[hi] / levels[lo]), 0.0, MAX_EXPONENT
                    )
                )
                if levels[hi] > levels[lo]
                else 0.0
            )
            i = hi if level >= levels[hi] else lo if level <= levels[lo] else hi
        share[j] = growing[i, j] * (level / levels[i]) ** p
    how = "interpolated" if levels.min() <= level <= levels.max() else "extrapolated"
    return (
        flat,
        share,
        (
            f"{how} in level (force rms {level:.3g}) from the estimation tests': a part that does "
            "not grow with the level and one that does (power law)"
        ),
    )
