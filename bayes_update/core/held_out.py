"""Does a model predict the held-out tests better than another, beyond what their noise
could do?  The score users and benchmarks use: the time-domain output error of the
simulated response from the record's start, per sensor, on every test with role
``validation``.

Two models' responses m0 and m1 to a held-out record y = truth + noise (noise sd sigma
per sensor): the gain ``D = sum (||y - m0||^2 - ||y - m1||^2) / sigma^2`` (over the
tests and sensors) is ``||t - m0||^2 - ||t - m1||^2`` plus ``2 n . (m1 - m0) / sigma^2``,
whose sd is ``2 ||m1 - m0|| / sigma`` (the noise is common to both errors, so only its
projection on the models' difference counts).  The gain is significant when it
exceeds :data:`SIGNIFICANT_SD` of that: an improvement no noise realisation of the
record would give, and no test is predicted worse by more than that many sd of its own
noise and by more than :data:`WORSE_SHARE` of its error (a summed gain lets one test's drop
hide another's rise: a two-mode model of a cantilever with a cubic tip spring, given the
spring, predicted the held-out random test better, 16.1 -> 10.0 %, and the sweep worse,
38.5 -> 42.4 %, a summed gain of +559 sd).
Two models whose held-out responses differ by less than half a
noise sd in all (``||m1 - m0|| / sigma < 1/2``, the gain's sd below one) make the same
prediction as far as any record can tell: no improvement, whatever z says (where a
model leaves a residual many times its noise, an effect at its null, 1e-10, moved the
responses by 1e-6 of the noise and scored z = +2275).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from surrogates.evaluation import evaluate_many

__all__ = ["SIGNIFICANT_SD", "WORSE_SHARE", "describe", "held_out_comparison", "held_out_runs"]

#: a held-out gain counts beyond this many sd of its noise
SIGNIFICANT_SD = 3.0
#: a test is predicted worse when its loss is significant and its relative error grows by more than
#: this share of itself: where both models miss a test by far more than its noise, any change of
#: the prediction is significant (a wing's high sweep missed by 42.1 % and 42.4 %, its noise floor
#: 0.17 %: -1000 sd); the cantilever's sweep, 38.5 -> 42.4 %, grew by 10 %
WORSE_SHARE = 0.03


@dataclass
class _Responses:
    """Picklable ``theta -> {validation test: compared response}``, None for a test the model
    cannot run (it diverged, or refused the force)."""

    problem: object

    def __call__(self, theta):
        out = {}
        for name, t in self.problem.validation.items():
            try:
                out[name] = self.problem.compared_response(self.problem.run(theta, t.force))
            except self.problem.failures:
                out[name] = None
        return out


def held_out_runs(problem, thetas: list, executor=None) -> list:
    """Each theta's responses on the validation tests (one model run per test and theta)."""
    if not problem.validation:
        return [{} for _ in thetas]
    return evaluate_many(_Responses(problem), list(thetas), executor, progress=False)


def held_out_comparison(problem, before: dict | None, after: dict | None) -> dict | None:
    """Compare two models' responses on the validation tests (:func:`held_out_runs`):
    ``{"gain", "sd", "z", "improves", "worse", "tests": {test: {"before", "after", "z"}}}`` with the
    relative output errors per test and each test's own gain in sd of its noise (rms over its sensors, as
    :meth:`~bayes_update.core.problem.Problem.prediction_errors`), or None without
    validation tests.  A test one model cannot run (its response None) is predicted infinitely
    badly by it: its error and z are infinite, and it counts as worse for ``after`` (a model
    that diverges on a held-out test does not predict it better, however well it fits the
    others); a test neither model runs is left out."""
    if not problem.validation or before is None or after is None:
        return None
    gain, var, tests = 0.0, 0.0, {}
    for name, t in problem.validation.items():
        y = t.response.reshape(len(t.response), -1)
        if before[name] is None or after[name] is None:
            if before[name] is not None or after[name] is not None:
                ran = before[name] if after[name] is None else after[name]
                err = _relative(y, ran.reshape(y.shape))
                tests[name] = (
                    {"before": err, "after": math.inf, "z": -math.inf}
                    if after[name] is None
                    else {"before": math.inf, "after": err, "z": math.inf}
                )
            continue
        m0, m1 = before[name].reshape(y.shape), after[name].reshape(y.shape)
        sigma = np.asarray(problem.test_noise(name), float).reshape(-1)
        g = float(np.sum((np.sum((y - m0) ** 2, axis=0) - np.sum((y - m1) ** 2, axis=0)) / sigma**2))
        v = 4.0 * float(np.sum(np.sum((m1 - m0) ** 2, axis=0) / sigma**2))
        gain, var = gain + g, var + v
        tests[name] = {"before": _relative(y, m0), "after": _relative(y, m1), "z": g / math.sqrt(v) if v > 0 else 0.0}
    sd = math.sqrt(var)
    z = gain / sd if sd > 0 else 0.0
    rescued = any(t["z"] == math.inf for t in tests.values())  # runs where the other model could not
    distinct = sd >= 1.0 or rescued
    worse = [n for n, t in tests.items() if t["z"] <= -SIGNIFICANT_SD and t["after"] > (1 + WORSE_SHARE) * t["before"]]
    return {
        "gain": gain,
        "sd": sd,
        "z": z,
        "distinct": distinct,
        "improves": bool(((sd >= 1.0 and z > SIGNIFICANT_SD) or rescued) and not worse),
        "worse": worse,
        "tests": tests,
    }


def _relative(y: np.ndarray, m: np.ndarray) -> float:
    """The rms over the sensors (columns) of ||y - m|| / ||y||."""
    rel = np.linalg.norm(y - m, axis=0) / np.linalg.norm(y, axis=0)
    return float(np.sqrt(np.mean(rel**2)))


def describe(comparison: dict | None) -> str:
    """One line of a :func:`held_out_comparison`: each test's relative error before ->
    after and the gain's z, e.g. ``random 16 % -> 10.1 %, sweep 39.6 % -> cannot run (-205 sd)``.
    Why each test: where the model leaves a residual many times its noise, z measures
    the noise only, and one test's drop can hide another's rise."""
    if comparison is None:
        return "-"
    tests = ", ".join(f"{t} {_percent(v['before'])} -> {_percent(v['after'])}" for t, v in comparison["tests"].items())
    if not comparison.get("distinct", True):
        return f"{tests} (the same prediction within the noise)"
    both = "" if all(math.isfinite(v["z"]) for v in comparison["tests"].values()) else " on the tests both run"
    return f"{tests} ({comparison['z']:+.1f} sd{both})"


def _percent(error: float) -> str:
    """``12.3 %``, or ``cannot run`` for a model that could not run the test."""
    return f"{100 * error:.3g} %" if math.isfinite(error) else "cannot run"
