"""The evidence the discrepancy workflow compares models by, when every model leaves a
gap (docs/discrepancy.md, "Evidence").

A model's misfit beyond the noise is its model-form error, and it differs from
model to model: an effect that explains part of the baseline's misfit leaves a
smaller one.  So each model M is scored under a Gaussian error of covariance

    S_M = S_noise + c_M I (+ the unabsorbed discretisation error, isotropic)

in the space of each test's compared output (its coordinates in the orthonormal
basis of :func:`bayes_update.core.posterior.pointwise.observation_basis`): the
noise replicates' second moment, and a model-form variance per coordinate c_M at
which M's own residual at its mode is most likely (:func:`form_scale`: an error
scale per model and test, estimated as a hyperparameter and profiled out; 0 where
the noise explains the residual).  At M's mode, with a the residual's
coordinates,

    log L_M = -1/2 a^T S_M^-1 a - 1/2 log det(2 pi S_M),

and the Laplace factor uses the precision ``J_a^T S_M^-1 J_a`` (J_a the Jacobian's
coordinates).  Where the form error dominates, 2 ln B between two models is about
``N log(|a_0|^2 / |a_1|^2)`` per test of N coordinates: the evidence grows with
the share of the misfit an effect removes, not with that misfit over the noise
(taken for noise, a model-form residual made every candidate decisive on a real
record).  Where a model leaves the noise alone, this is the usual chi-square
evidence with the noise's own covariance, and the fitted parameters' covariance
(the inverse of the same precision, plus one unit of information per prior width)
is the noise's.

Why isotropic and not the random-phase covariance of the residual's spectrum
(:mod:`bayes_update.core.model_form`, which the posterior uses along the
parameters' directions): a model-form error is coherent with the input, so it
projects on the input's regressors in full, where a random-phase process of the
same spectrum projects like noise; scored under that covariance, a model whose
residual was smaller in every test lost (2 ln B -44 for a tip spring that
removed 27 % of a cantilever's linear misfit and 7 % of its nonlinear one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import optimize

from surrogates.evaluation import evaluate_many

__all__ = ["Scored", "error_covariance", "evidence", "form_scale", "score_model"]


@dataclass(frozen=True)
class Scored:
    log_evidence: float
    covariance: np.ndarray  # of the internal coordinates (the mode's Laplace, on this error model)


@dataclass
class _Responses:
    """Picklable: ``(stage, theta) -> the model's response on the stage's test`` (None where it cannot run)."""

    problem: object

    def __call__(self, task):
        stage, theta = task
        try:
            return self.problem.run(theta, self.problem.tests[stage].force)
        except self.problem.failures:
            return None


def score_model(problem, likelihood, mode, theta, log_prior_density: float, widths, executor=None) -> Scored:
    """Log evidence and Laplace covariance of a model at its ``mode`` (residual and
    Jacobian scaled by ``likelihood``'s scales, rows in ``problem.stages`` order;
    ``theta``: its parameters there) under its own error covariance (module
    docstring); one model run per test."""
    runs = evaluate_many(
        _Responses(problem), [(st, theta) for st in problem.stages], executor, batch_size=1, progress=False
    )
    a, J, S, row = {}, {}, {}, 0
    for stage, y in zip(problem.stages, runs):
        sc = likelihood.scales[stage]
        n = problem.output(stage, problem.reference_components(stage)).size
        resid = None if y is None else problem.tests[stage].response - problem.compared_response(y)
        S[stage], Q = error_covariance(problem, likelihood, stage, resid)
        a[stage] = Q.T @ (np.asarray(mode.residual[row : row + n], float) * sc.sd)
        J[stage] = Q.T @ (np.asarray(mode.jacobian[row : row + n], float) * sc.sd)
        row += n
    log_z, cov = evidence(a, J, S, log_prior_density, widths)
    return Scored(log_z, cov)


def error_covariance(problem, likelihood, stage: str, residual=None):
    """(S, Q): the error covariance of a stage's compared output in the
    coordinates of its observation basis Q, from the noise replicates (their second
    moment, shrunk towards the isotropic one of the same trace; isotropic where there
    are none), the unabsorbed discretisation error per direction and, given a model's
    time-domain ``residual`` on the stage's test, its model-form variance per
    coordinate (:func:`form_scale`)."""
    from bayes_update.core.posterior.pointwise import observation_basis

    sc = likelihood.scales[stage]
    Q = observation_basis(problem, stage)
    N = Q.shape[1]
    unabsorbed = sc.model_error_unabsorbed if sc.model_error_unabsorbed is not None else sc.model_error
    res = (likelihood.noise_residuals or {}).get(stage)
    if res is None:
        S = (sc.noise_mean_square + unabsorbed**2) / N * np.eye(N)
    else:
        D, w = res if isinstance(res, tuple) else (res, np.full(len(res), 1.0 / len(res)))
        A = D @ Q
        S_rep = 0.5 * ((A * w[:, None]).T @ A + ((A * w[:, None]).T @ A).T)
        # K replicates span at most K of the N directions: shrunk towards the isotropic noise of
        # the same trace (weight N / (K + N)), so that no direction is taken as noise-free
        K = int(np.count_nonzero(w > 0))
        alpha = N / (K + N)
        S = (1 - alpha) * S_rep + (alpha * np.trace(S_rep) / N + unabsorbed**2 / N) * np.eye(N)
    if residual is not None:
        r = np.asarray(residual, float).reshape(len(residual), -1)
        a = sum(M @ r[:, j] for j, M in enumerate(_coordinate_maps(problem, stage)))
        c = form_scale(S, a)
        S = S + c * np.eye(N)
    return S, Q


def form_scale(S_noise, a) -> float:
    """The model-form error's variance per coordinate, c >= 0, that makes the residual
    coordinates ``a`` most likely under ``N(0, S_noise + c I)`` (maximum likelihood,
    one scalar per model and test; 0 where the noise explains ``a``)."""
    lam, V = np.linalg.eigh(0.5 * (S_noise + S_noise.T))
    lam = np.maximum(lam, 1e-12 * max(float(lam.mean()), 1e-300))
    va2 = (V.T @ np.asarray(a, float)) ** 2

    def slope(c):  # d(-log L)/dc: negative where a larger c is more likely
        return 0.5 * float(np.sum(1.0 / (lam + c) - va2 / (lam + c) ** 2))

    if slope(0.0) >= 0.0:
        return 0.0
    hi = max(float(va2.sum()), float(lam.max()))
    while slope(hi) < 0.0:  # the root lies below |a|^2 (one coordinate holding it all)
        hi *= 2.0
    return float(optimize.brentq(slope, 0.0, hi, xtol=1e-14 * hi, rtol=1e-10))


def _coordinate_maps(problem, stage: str) -> list:
    """Per sensor, the linear map from its time record to the stage's compared-output
    coordinates (those of :func:`~bayes_update.core.posterior.pointwise.observation_basis`),
    over the compared output's norm; several sensors are weighted by their noise, as
    :meth:`~bayes_update.core.problem.Problem.components` weighs them."""
    B = problem.projector(stage).span_map(problem.compared_orders(stage))
    norm = float(np.linalg.norm(problem.output(stage, problem.reference_components(stage))))
    if len(problem.sensors) == 1:
        return [B / norm]
    w = 1.0 / np.asarray(problem.sensor_noise(stage), float)
    k, p = len(problem.sensors), B.shape[0]
    maps = []
    for j in range(k):
        M = np.zeros((k * p, B.shape[1]))
        M[j * p : (j + 1) * p] = w[j] * B / norm
        maps.append(M)
    return maps


def evidence(a: dict, J: dict, S: dict, log_prior_density: float, widths) -> tuple[float, np.ndarray]:
    """(Laplace log evidence, covariance of the coordinates) from each stage's residual
    coordinates ``a``, Jacobian coordinates ``J`` and error covariance ``S`` (module
    docstring); ``widths``: the prior box's (one unit of information per width^2 in the
    covariance, as the mode's Laplace covariance has)."""
    widths = np.asarray(widths, float)
    d = len(widths)
    log_l, H = 0.0, np.zeros((d, d))
    for stage in a:
        lam, V = np.linalg.eigh(0.5 * (S[stage] + S[stage].T))
        # the control variate's weights can leave a direction a hair below zero: floor it
        lam = np.maximum(lam, 1e-6 * max(float(lam.mean()), 1e-300))
        va, VJ = V.T @ a[stage], V.T @ J[stage]
        log_l += -0.5 * float(va @ (va / lam)) - 0.5 * float(np.sum(np.log(2 * math.pi * lam)))
        H += (VJ / lam[:, None]).T @ VJ
    sign, logdet = np.linalg.slogdet(H + np.diag(2.0 * math.pi / widths**2))
    log_z = -math.inf if sign <= 0 else log_l + log_prior_density + 0.5 * d * math.log(2 * math.pi) - 0.5 * logdet
    return log_z, np.linalg.inv(H + np.diag(1.0 / widths**2))
