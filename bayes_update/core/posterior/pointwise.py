"""The pointwise log-likelihood of posterior draws, for ArviZ's ``loo``, ``waic`` and
``compare`` (docs/likelihood.md, "Pointwise log-likelihood").

A stage's likelihood, ``-1/2 ||r||^2`` with ``r = (ref - out(x)) / (||ref|| s)``,
weighs every direction of the space its compared output lives in alike and
independently: the observations it treats as independent are the coordinates
of the record's compared output in an orthonormal basis Q of that space (per
sensor: the span of the compared orders' regressors, :meth:`volterra.VolterraProjector.span`),
``c_j = q_j . ref``, each ``N(q_j . out(x), (s ||ref||)^2)``.  Their
log densities at a draw are

    -1/2 a_j^2 - log(s ||ref||) - 1/2 log(2 pi),    a = Q^T r(x'),

summing to the stage's log L plus its normalisation; x' is the draw's
argument of the (curvature-adjusted) likelihood.  ``r(x')`` comes from the
Gauss-Newton model at the mode, ``r_0 + J (x' - x_0)`` (the mode's residual and
Jacobian: no model run), exact for a model linear in its parameters near the
mode; ``check`` records how far its stage sums fall from the chain's own log L.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["observation_basis", "pointwise_log_likelihood"]


def observation_basis(problem, stage: str) -> np.ndarray:
    """Q (n_output, p * n_sensors): an orthonormal basis of the stage's compared
    output (block diagonal over the sensors, whose outputs are stacked)."""
    q = problem.projector(stage).span(problem.compared_orders(stage))
    k = len(problem.sensors)
    if k == 1:
        return q
    Q = np.zeros((k * q.shape[0], k * q.shape[1]))
    for j in range(k):
        Q[j * q.shape[0] : (j + 1) * q.shape[0], j * q.shape[1] : (j + 1) * q.shape[1]] = q
    return Q


def pointwise_log_likelihood(problem, likelihood, mode, X, adjustment=None) -> dict:
    """``{stage: (m, n_obs) float32}`` of the draws ``X`` (m, d) in internal
    coordinates (module docstring); ``mode``: the MAP's ModeResult (its residual and
    Jacobian scaled by ``likelihood``'s scales, rows in ``problem.stages`` order)."""
    X = np.atleast_2d(np.asarray(X, float))
    args = adjustment(X) if adjustment is not None else X
    dx = args - np.asarray(mode.x, float)
    out, row = {}, 0
    for stage in problem.stages:
        ref = problem.output(stage, problem.reference_components(stage))
        n = ref.size
        r0, J = mode.residual[row : row + n], mode.jacobian[row : row + n]
        row += n
        Q = observation_basis(problem, stage)
        a = (Q.T @ r0)[None, :] + dx @ (Q.T @ J).T
        norm = -math.log(likelihood.scales[stage].sd * float(np.linalg.norm(ref))) - 0.5 * math.log(2 * math.pi)
        out[stage] = (-0.5 * a**2 + norm).astype(np.float32)
    return out


def linearisation_check(pointwise: dict, chain_log_likelihood: dict, likelihood, problem) -> dict:
    """Per stage, the median over draws of |(sum of the pointwise values without their
    normalisation) - the chain's log L| [log units]: how well the Gauss-Newton model
    follows the likelihood the chain sampled."""
    out = {}
    for stage, values in pointwise.items():
        ref = problem.output(stage, problem.reference_components(stage))
        norm = -math.log(likelihood.scales[stage].sd * float(np.linalg.norm(ref))) - 0.5 * math.log(2 * math.pi)
        total = values.astype(float).sum(axis=1) - values.shape[1] * norm
        chain = np.asarray(chain_log_likelihood[stage], float).reshape(-1)
        out[stage] = float(np.median(np.abs(total - chain)))
    return out
