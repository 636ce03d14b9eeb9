"""What the data pin and what they leave free: the directions of the parameters a
calibration's chi-square hardly changes along (:func:`unidentified_directions`), the
Gauss-Newton covariance at its end, and the parameters' sds through their transform
(step 4 of :mod:`bayes_update.core.calibrate`)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["IDENTIFIED_SINGULAR_VALUE", "gauss_newton_covariance", "parameter_sd", "unidentified_directions"]

#: a direction is unidentified when one prior range along it changes chi^2 by less than this^2
IDENTIFIED_SINGULAR_VALUE = 2.0


def unidentified_directions(jacobian, widths, names, rows_to_noise=None) -> list:
    """Directions (unit vectors in prior-range units) along which ``jacobian``
    (residual per internal coordinate; rows in noise units after multiplying
    by ``rows_to_noise``) changes chi^2 by less than 4 over one prior range."""
    J = np.asarray(jacobian, float) * np.asarray(widths, float)
    if rows_to_noise is not None:
        J = J * np.asarray(rows_to_noise, float)[:, None]
    _, S, Vt = np.linalg.svd(J, full_matrices=False)
    out = []
    for s, v in zip(S, Vt):
        if s < IDENTIFIED_SINGULAR_VALUE:
            v = v * np.sign(v[np.argmax(np.abs(v))])
            out.append(
                {
                    "direction": {n: round(float(c), 4) for n, c in zip(names, v)},
                    "sd_over_range": float(1.0 / s) if s > 0 else math.inf,
                }
            )
    return out


def gauss_newton_covariance(J, widths, floor: float = 1e-10) -> np.ndarray:
    """``(J^T J)^-1``, inverted in coordinates divided by ``widths`` (e.g. the prior
    ranges), where an eigenvalue below ``floor`` times the largest (a direction the
    data do not constrain) is raised to it: that direction comes out very wide, not
    infinite or negative (nor of zero width, as a pseudo-inverse would make it)."""
    widths = np.asarray(widths, float)
    Js = np.asarray(J, float) * widths
    w, V = np.linalg.eigh(Js.T @ Js)
    w = np.maximum(w, floor * max(w.max(), 1e-300))
    return ((V / w) @ V.T) * np.outer(widths, widths)


def parameter_sd(space, x, covariance) -> dict:
    """{name: sd in the parameter's unit} of internal point ``x`` with covariance
    ``covariance`` (the delta method through ``space.to_parameters``)."""
    x = np.asarray(x, float)
    names = list(space.names)
    h = 1e-6 * np.maximum(np.abs(np.diff(space.box(), axis=1)[:, 0]), 1e-12)
    G = np.empty((len(names), len(x)))
    for j in range(len(x)):
        up, down = x.copy(), x.copy()
        up[j] += h[j]
        down[j] -= h[j]
        t_up, t_down = space.to_parameters(up), space.to_parameters(down)
        G[:, j] = [(t_up[n] - t_down[n]) / (2 * h[j]) for n in names]
    var = np.einsum("ij,jk,ik->i", G, covariance, G)
    return {n: float(np.sqrt(max(v, 0.0))) for n, v in zip(names, var)}
