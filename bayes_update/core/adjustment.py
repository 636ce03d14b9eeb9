"""The curvature adjustment of the likelihood (Chandler and Bate 2007): its
curvature at the mode set to the inverse of the sandwich covariance built
from the noise replicates of :func:`bayes_update.core.likelihood.estimate_likelihood`
(docs/likelihood.md, "Curvature adjustment")."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bayes_update.core.likelihood import Likelihood

__all__ = ["CurvatureAdjustment", "curvature_adjustment"]


@dataclass(frozen=True)
class CurvatureAdjustment:
    """``log L_adj(x) = log L(center + A (x - center))``: the likelihood with
    its curvature at the mode set to the inverse of the sandwich covariance
    (Chandler and Bate 2007, "horizontal" adjustment; Ribatet et al. 2012).

    Why: ``log L`` weighs every direction of a stage's residual vector with
    one noise scale, the mean over the directions the parameters move.  The
    noise is not isotropic there (the bootstrap's variances along those
    directions differ up to 10x at SBC truths), so the curvature of
    ``log L`` is right on average and wrong along single parameter
    combinations: the sandwich ``H^-1 M H^-1`` (H = J^T J, M = J^T Sigma J
    with Sigma the replicates' covariance) was up to 1.4x the Laplace sd in c
    and k_s, which is what the SBC's 80 % coverage of 90 % intervals said.
    ``variance_ratios`` are the eigenvalues of H^-1/2 M H^-1/2: 1 everywhere
    means a well-specified likelihood (then A = I)."""

    center: np.ndarray
    A: np.ndarray
    variance_ratios: np.ndarray
    sd_ratios: np.ndarray       # per coordinate: adjusted / unadjusted Laplace sd
    names: tuple = ()           # the coordinates' names

    def __call__(self, X) -> np.ndarray:
        """The points at which to evaluate the unadjusted likelihood."""
        return self.center + (np.atleast_2d(X) - self.center) @ self.A.T

    def to_dict(self) -> dict:
        return {"variance_ratios": self.variance_ratios.tolist(),
                "sd_ratios": dict(zip(self.names, self.sd_ratios.tolist()))}


def curvature_adjustment(likelihood: Likelihood, jacobian, center, widths, stages=None,
                         clip: float = 16.0, names=()) -> CurvatureAdjustment | None:
    """The :class:`CurvatureAdjustment` at the mode ``center``.

    Parameters
    ----------
    jacobian : (n, d) derivative of the stages' scaled residual vectors,
        concatenated in ``stages`` order (:class:`bayes_update.core.mode.ModeResult`).
    widths : the prior box's widths; one unit of information per width^2 is
        added to both H and M, so that a direction the data do not constrain
        is left alone (its ratio is 1, not 0/0).
    clip : the variance ratios are clipped to [1/clip, clip].

    Returns None without the bootstrap's residuals (a likelihood given by
    hand).  The noise covariance is the replicates' second moment plus the
    model error budgeted isotropically (``e_model^2`` per direction, as in
    the scale ``s^2 = s_n^2 + e_model^2``)."""
    res = likelihood.noise_residuals
    stages = likelihood.stages if stages is None else tuple(stages)
    if not res or any(st not in res for st in stages):
        return None
    widths = np.asarray(widths, float)
    J = np.asarray(jacobian, float) * widths                            # coordinates x / width
    res = {st: v if isinstance(v, tuple) else (v, np.full(len(v), 1.0 / len(v))) for st, v in res.items()
           if st in stages}
    n_rows = sum(res[st][0].shape[1] for st in stages)
    if J.ndim != 2 or J.shape[0] != n_rows:
        raise ValueError(f"the Jacobian has {J.shape[0] if J.ndim else 0} rows, the stages' residuals {n_rows}")
    d = J.shape[1]
    H = np.eye(d)
    M = np.eye(d)
    row = 0
    for st in stages:
        (D, weights), sc = res[st], likelihood.scales[st]
        Js = J[row:row + D.shape[1]]
        row += D.shape[1]
        DJ = (D / sc.sd) @ Js
        H += Js.T @ Js
        M += (DJ * weights[:, None]).T @ DJ + (sc.model_error / sc.sd) ** 2 * (Js.T @ Js)
    w, V = np.linalg.eigh(H)
    h_half, h_ihalf = (V * np.sqrt(w)) @ V.T, (V / np.sqrt(w)) @ V.T
    omega, U = np.linalg.eigh(h_ihalf @ M @ h_ihalf)
    omega = np.clip(omega, 1.0 / clip, clip)
    A_s = h_ihalf @ ((U / np.sqrt(omega)) @ U.T) @ h_half
    A = A_s * np.outer(widths, 1.0 / widths)
    A_s_inv = np.linalg.inv(A_s)
    cov0 = np.linalg.inv(H)
    cov1 = A_s_inv @ cov0 @ A_s_inv.T
    return CurvatureAdjustment(center=np.asarray(center, float), A=A, variance_ratios=omega,
                               sd_ratios=np.sqrt(np.diag(cov1) / np.diag(cov0)), names=tuple(names))
