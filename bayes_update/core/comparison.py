"""The evidence the discrepancy workflow compares models by, when every model leaves a
gap (docs/discrepancy.md, "Evidence").

A model's misfit beyond the noise is its model-form error, and it differs from
model to model: an effect that explains part of the baseline's misfit leaves a
smaller one.  So each model M is scored under a Gaussian error of covariance

    S_M = S_noise + S_form(M) (+ the unabsorbed discretisation error, isotropic)

in the space of each test's compared output (its coordinates in the orthonormal
basis of :func:`bayes_update.core.posterior.pointwise.observation_basis`): the noise
replicates' second moment, and the second moment of the random-phase draws of
what M's own residual at its mode holds beyond the noise
(:mod:`bayes_update.core.model_form`; one model run per test).  At M's mode, with
a the residual's coordinates,

    log L_M = -1/2 a^T S_M^-1 a - 1/2 log det(2 pi S_M),

and the Laplace factor uses the precision ``J_a^T S_M^-1 J_a`` (J_a the Jacobian's
coordinates).  A misfit no model explains is in every model's S alike and counts
for nothing; an effect that removes part of it shrinks S in those directions,
and the evidence grows as the log of what it removed there, over the noise
(about ``sum log(1 + lambda_i / v_noise)`` over the directions the misfit fills):
taken for noise instead, a model-form residual made every candidate decisive on a
real record.  Where a model leaves the noise alone, this is the usual chi-square
evidence with the noise's own covariance.  The covariance of the fitted
parameters is the inverse of the same precision (plus one unit of information per
prior width), so an effect that closes the gap is pinned at the noise's precision.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bayes_update.core.model_form import form_draws
from surrogates.evaluation import evaluate_many

__all__ = ["Scored", "error_covariance", "evidence", "score_model"]

#: random-phase draws of a model's form error per test
FORM_DRAWS = 64


@dataclass(frozen=True)
class Scored:
    log_evidence: float
    covariance: np.ndarray       # of the internal coordinates (the mode's Laplace, on this error model)
    form_share: dict             # {stage: rms of the model-form error / rms of the compared output}


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


def score_model(problem, likelihood, mode, theta, log_prior_density: float, widths, executor=None,
                seed: int = 0) -> Scored:
    """Log evidence and Laplace covariance of a model at its ``mode`` (residual and
    Jacobian scaled by ``likelihood``'s scales, rows in ``problem.stages`` order;
    ``theta``: its parameters there) under its own error covariance (module
    docstring); one model run per test."""
    runs = evaluate_many(_Responses(problem), [(st, theta) for st in problem.stages], executor, batch_size=1,
                         progress=False)
    a, J, S, share, row = {}, {}, {}, {}, 0
    for i, (stage, y) in enumerate(zip(problem.stages, runs)):
        sc = likelihood.scales[stage]
        n = problem.output(stage, problem.reference_components(stage)).size
        resid = None if y is None else problem.tests[stage].response - problem.compared_response(y)
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(200 + i,)))
        S[stage], Q, share[stage] = error_covariance(problem, likelihood, stage, resid, rng)
        a[stage] = Q.T @ (np.asarray(mode.residual[row:row + n], float) * sc.sd)
        J[stage] = Q.T @ (np.asarray(mode.jacobian[row:row + n], float) * sc.sd)
        row += n
    log_z, cov = evidence(a, J, S, log_prior_density, widths)
    return Scored(log_z, cov, share)


def error_covariance(problem, likelihood, stage: str, residual=None, rng=None, n_draws: int = FORM_DRAWS):
    """(S, Q, form share): the error covariance of a stage's compared output in the
    coordinates of its observation basis Q, from the noise replicates (their second
    moment, shrunk towards the isotropic one of the same trace; isotropic where there
    are none), the unabsorbed discretisation error per
    direction and, given a model's time-domain ``residual`` on the stage's test, what
    it holds beyond the noise (random-phase draws; their rms relative to the
    compared output's norm is the form share)."""
    from bayes_update.core.posterior.pointwise import observation_basis

    sc = likelihood.scales[stage]
    Q = observation_basis(problem, stage)
    N = Q.shape[1]
    unabsorbed = sc.model_error_unabsorbed if sc.model_error_unabsorbed is not None else sc.model_error
    res = (likelihood.noise_residuals or {}).get(stage)
    if res is None:
        S = (sc.noise_mean_square + unabsorbed ** 2) / N * np.eye(N)
    else:
        D, w = res if isinstance(res, tuple) else (res, np.full(len(res), 1.0 / len(res)))
        A = D @ Q
        S_rep = 0.5 * ((A * w[:, None]).T @ A + ((A * w[:, None]).T @ A).T)
        # K replicates span at most K of the N directions: shrunk towards the isotropic noise of
        # the same trace (weight N / (K + N)), so that no direction is taken as noise-free
        K = int(np.count_nonzero(w > 0))
        alpha = N / (K + N)
        S = (1 - alpha) * S_rep + (alpha * np.trace(S_rep) / N + unabsorbed ** 2 / N) * np.eye(N)
    spectrum = (likelihood.noise_spectra or {}).get(stage)
    share = 0.0
    if residual is not None and spectrum is not None:
        norm = float(np.linalg.norm(problem.output(stage, problem.reference_components(stage))))
        draws, _ = form_draws(residual, spectrum, n_draws, rng if rng is not None else np.random.default_rng(0))
        F = np.array([Q.T @ problem.output(stage, problem.components(stage, dk)) / norm for dk in draws])
        S = S + F.T @ F / len(F)
        share = float(np.sqrt(np.sum(F ** 2) / len(F)))
    return S, Q, share


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
    sign, logdet = np.linalg.slogdet(H + np.diag(2.0 * math.pi / widths ** 2))
    log_z = -math.inf if sign <= 0 else log_l + log_prior_density + 0.5 * d * math.log(2 * math.pi) - 0.5 * logdet
    return log_z, np.linalg.inv(H + np.diag(1.0 / widths ** 2))
