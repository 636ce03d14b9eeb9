"""The finer model the model error is measured against when the model has no ``refined()``.

The posterior's model-error term (docs/likelihood.md, "Model error") is the
difference between the model and a finer model of the same physics at the
estimate.  A model's discretisation error is the one error the data cannot
show: the parameters take it up (a time integrator's frequency warping reads as
a stiffer spring), so the fit's residual is as small as with an exact model and
the posterior is confidently off.  On the 3-DOF chain of the lab records
(benchmarks/runs_per_posterior.py, chain6) without ``refined()``: k2 7 sd and
zeta 8 sd from the generator's values, the sds 5-8 times narrower than with it.

Most user models step in time at a multiple of the rate they are given, so
without a ``refined()`` the model itself at twice the sampling rate is used
(:class:`AtTwiceTheRate`: the force interpolated band-limited, the response
read back at the record's samples), after a probe that it runs there and
that the rate changes its response by less than :data:`MAX_PROBE_CHANGE` (a
model whose output at another rate is another system, e.g. a discrete-time
filter with fixed coefficients, is not refined by it).  A model opts out by a
``refined()`` that returns itself.
"""

from __future__ import annotations

import warnings

import numpy as np
from scipy import signal

#: a response that moves by more than this share of its rms at twice the rate is not a
#: discretisation of one continuous model (a discrete-time model): no refinement from it
MAX_PROBE_CHANGE = 0.3
#: samples of the probe's force (from the middle of the first estimation test)
PROBE_SAMPLES = 1024


class AtTwiceTheRate:
    """``model`` run at twice the sampling rate on the force interpolated band-limited
    (scipy's polyphase resampler: a Kaiser-windowed sinc that keeps every recorded
    sample), its response read at the recorded samples."""

    def __init__(self, model):
        self.model = model

    def __repr__(self):
        return f"AtTwiceTheRate({self.model!r})"

    @property
    def parameters(self):
        return self.model.parameters

    def simulate(self, theta, force, fs):
        force = np.asarray(force, float)
        fine = signal.resample_poly(force, 2, 1)[: 2 * force.size - 1]
        return np.asarray(self.model.simulate(theta, fine, 2.0 * fs))[::2]


def twice_the_rate(model, theta, force, fs: float) -> tuple[AtTwiceTheRate | None, str]:
    """(the refinement, what it is) or (None, why not): the probe of the module docstring
    at ``theta`` on the middle :data:`PROBE_SAMPLES` samples of ``force``."""
    name = type(model).__name__
    n = len(force)
    mid = np.asarray(force, float)[max(0, n // 2 - PROBE_SAMPLES // 2) :][:PROBE_SAMPLES]
    refined = AtTwiceTheRate(model)
    try:
        coarse = np.asarray(model.simulate(theta, mid, fs), float)
        fine = np.asarray(refined.simulate(theta, mid, fs), float)
    except Exception as exc:  # the model does not run at another rate: no refinement
        return None, (
            f"none: {name} has no refined(), and at twice the sampling rate it raised "
            f"{type(exc).__name__}: {exc}; the model error is taken as 0"
        )
    if fine.shape != coarse.shape or not (np.all(np.isfinite(fine)) and np.all(np.isfinite(coarse))):
        return None, (
            f"none: {name} has no refined(), and at twice the sampling rate its response had shape "
            f"{fine.shape} (or non-finite values) against {coarse.shape}; the model error is taken as 0"
        )
    scale = np.linalg.norm(coarse)
    change = np.linalg.norm(fine - coarse) / scale if scale > 0 else 0.0
    if change > MAX_PROBE_CHANGE:
        # either a model of the samples (then nothing is wrong) or a continuous model far from
        # converged at this rate (then its posterior is too narrow): only the user can tell
        warnings.warn(
            f"{name} has no refined(), and at twice the sampling rate its response changes by "
            f"{100 * change:.3g} %: if it models a continuous structure it is far from converged at "
            "this rate and its posterior will be too narrow; give it a refined() (a finer model of the "
            "same physics)",
            RuntimeWarning,
            stacklevel=2,
        )
        return None, (
            f"none: {name} has no refined(), and at twice the sampling rate its response changes by "
            f"{100 * change:.3g} % (a model of the samples, or far from converged: a warning says "
            "so); the model error is taken as 0"
        )
    return refined, (
        f"{name} at twice the sampling rate (it has no refined(); the probe moved its response by {100 * change:.3g} %)"
    )
