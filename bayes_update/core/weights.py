"""The metrics' weights: each sensor's measurement noise, and what the Volterra
projection of a test leaves unexplained beyond it (its representation floor).

Why measurement noise and nothing else.  The weights of the tests (in
``calibrate``'s joint objective, in the several-sensor metrics) must come from
the noise of the measurement, which is the same at every excitation level,
never from the residual of a test's own Volterra fit: on a high-level test
that residual also holds every order the fit leaves out.  On a measured
electronic Duffing oscillator (sensor noise 0.25 mV) it was 0.25 mV on the
low-level test but 3.1 mV on the high-level multisine, which cut the
multisine's weight about 150-fold and gave a calibration with 2.1x the
prediction error of a direct output-error fit; weighted by the sensor noise
the same calibration gave 1.04x (docs/design.md, "Measured records").

The noise of each channel comes from :func:`bayes_update.data.noise.dataset_noise`
(declared, repeated periods, zero-input sections, a quiet band, the linear
test's model-free fit residual carried to the other tests of the sensor).
The force channel's noise enters too: the model is driven by the recorded
force, so its response carries the force noise through the structure, which
the measured response does not.  For white force noise of sd ``s_u`` that
part has sd ``s_u ||h1||``, with ``||h1||`` the energy norm of the linear
impulse response: the root sum of squares of the first-order coefficients in
the orthonormal basis (each function's impulse response has unit energy).
So each sensor's effective noise is ``sqrt(s_y^2 + (s_u ||h1||)^2)``.
"""

from __future__ import annotations

import math

import numpy as np

import volterra

__all__ = ["effective_noise", "linear_gain", "representation_floor"]


def linear_gain(force, response, basis: volterra.KautzBasis) -> np.ndarray:
    """``||h1||`` per sensor [response unit / force unit]: the energy norm of the
    first-order kernel fitted on a (linear) record, the root sum of squares of
    its coefficients in the orthonormal basis."""
    proj = volterra.VolterraProjector(np.asarray(force, float), basis.subset((1,)))
    y = np.asarray(response, float)
    y = y[:, None] if y.ndim == 1 else y
    return np.array([math.sqrt(float(np.sum(proj.model(y[:, j]).coefficients_of(1) ** 2))) for j in range(y.shape[1])])


def effective_noise(estimates: dict, sensors, gain) -> np.ndarray:
    """sd per sensor [its unit] of what noise puts between the measured response
    and a perfect model driven by the recorded force: the sensor's own noise and
    the force channel's through the structure (module docstring).  A force
    whose noise is unknown counts as noise-free (the reports say so)."""
    s_y = np.array([estimates[name].sd for name, _ in sensors], float)
    force = estimates.get("force")
    s_u = force.sd if force is not None and force.sd is not None else 0.0
    return np.sqrt(s_y**2 + (s_u * np.asarray(gain, float)) ** 2)


def representation_floor(response, fitted, noise_sd) -> float:
    """The share of a test's rms that its own Volterra fit (orders 1-3) leaves
    unexplained beyond the noise: ``sqrt(max(||r||^2 - n sum_j s_j^2, 0)) / ||y||``
    with r the fit's residual, n the samples and s_j each sensor's noise [-]."""
    y = np.asarray(response, float)
    r = y - np.asarray(fitted, float)
    n = y.shape[0]
    excess = float(np.sum(r**2)) - n * float(np.sum(np.square(noise_sd)))
    return math.sqrt(max(excess, 0.0)) / float(np.linalg.norm(y))
