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
    sd_ratios: np.ndarray  # per coordinate: adjusted / unadjusted Laplace sd
    names: tuple = ()  # the coordinates' names
    between_tests: dict | None = None  # where the tests disagree: between_test_covariance's record
    #: where the tests disagree: maps a draw's offset from the centre to the offset it would have
    #: in the posterior without their disagreement (the uncertainty within one test)
    within: np.ndarray | None = None

    def __call__(self, X) -> np.ndarray:
        """The points at which to evaluate the unadjusted likelihood."""
        return self.center + (np.atleast_2d(X) - self.center) @ self.A.T

    def covariance(self, cov) -> np.ndarray:
        """The covariance of the adjusted posterior where the unadjusted one's is ``cov``
        (a Gaussian about the centre): ``A^-1 cov A^-T``."""
        A_inv = np.linalg.inv(self.A)
        return A_inv @ np.asarray(cov, float) @ A_inv.T

    def to_dict(self) -> dict:
        return {
            "variance_ratios": self.variance_ratios.tolist(),
            "sd_ratios": dict(zip(self.names, self.sd_ratios.tolist())),
            "between_tests": self.between_tests,
        }


def curvature_adjustment(
    likelihood: Likelihood, jacobian, center, widths, stages=None, clip: float = 16.0, names=(), residual=None
) -> CurvatureAdjustment | None:
    """The :class:`CurvatureAdjustment` at the mode ``center``.

    Parameters
    ----------
    jacobian : (n, d) derivative of the stages' scaled residual vectors,
        concatenated in ``stages`` order (:class:`bayes_update.core.mode.ModeResult`).
    widths : the prior box's widths; one unit of information per width^2 is
        added to both H and M, so that a direction the data do not constrain
        is left alone (its ratio is 1, not 0/0).
    clip : the sandwich's variance ratios are clipped to [1/clip, clip] (its
        second moment is an estimate from replicates).
    residual : the stages' scaled residual vectors at the mode (same rows); with
        it, where the tests disagree beyond their errors, the covariance the
        adjustment targets takes their disagreement too
        (:func:`between_test_covariance`).

    Returns None without the bootstrap's residuals (a likelihood given by
    hand).  The error covariance is the second moment of the noise replicates
    and of the model-form error's draws (:meth:`Likelihood.error_rows`) plus the
    discretisation error budgeted isotropically (``e_model^2`` per direction, as in
    the scale ``s^2 = s_n^2 + s_form^2 + e_model^2``)."""
    stages = likelihood.stages if stages is None else tuple(stages)
    res = {st: likelihood.error_rows(st) for st in stages}
    if any(v is None for v in res.values()):
        return None
    widths = np.asarray(widths, float)
    J = np.asarray(jacobian, float) * widths  # coordinates x / width
    n_rows = sum(res[st][0].shape[1] for st in stages)
    if J.ndim != 2 or J.shape[0] != n_rows:
        raise ValueError(f"the Jacobian has {J.shape[0] if J.ndim else 0} rows, the stages' residuals {n_rows}")
    d = J.shape[1]
    blocks, row = [], 0
    for st in stages:
        (D, weights), sc = res[st], likelihood.scales[st]
        Js = J[row : row + D.shape[1]]
        rs = None if residual is None else np.asarray(residual, float)[row : row + D.shape[1]]
        row += D.shape[1]
        DJ = (D / sc.sd) @ Js
        blocks.append(
            (
                st,
                Js.T @ Js,
                (DJ * weights[:, None]).T @ DJ + (sc.model_error / sc.sd) ** 2 * (Js.T @ Js),
                None if rs is None else Js.T @ rs,
            )
        )
    H = np.eye(d) + sum(b[1] for b in blocks)
    M = np.eye(d) + sum(b[2] for b in blocks)
    h_half, h_ihalf = _sqrt_and_inverse(H)
    omega, U = np.linalg.eigh(h_ihalf @ M @ h_ihalf)
    X = (U * np.clip(omega, 1.0 / clip, clip)) @ U.T  # H^1/2 (target covariance) H^1/2
    between = between_test_covariance(blocks, len(stages)) if residual is not None else None
    A_within = _adjustment_matrix(X, h_half, h_ihalf)
    if between is not None:
        # each test's estimate off the joint one by a random effect b_k ~ N(0, T): the joint
        # estimate H^-1 sum_k H_k x_k then varies by H^-1 (sum_k H_k T H_k) H^-1 more
        X = X + h_ihalf @ sum(Hk @ between["T"] @ Hk for _, Hk, _, _ in blocks) @ h_ihalf
    omega = np.linalg.eigvalsh(0.5 * (X + X.T))
    A_s = _adjustment_matrix(X, h_half, h_ihalf)
    A = A_s * np.outer(widths, 1.0 / widths)
    A_s_inv = np.linalg.inv(A_s)
    cov0 = np.linalg.inv(H)
    cov1 = A_s_inv @ cov0 @ A_s_inv.T
    record, within = None, None
    if between is not None:
        record = _between_record(between, widths, names)
        record["offsets"] = {name: (xk * widths).tolist() for name, xk in between["estimates"]}
        # draws of the adjusted posterior -> draws of the within-test one (without T), about the centre
        within = (np.linalg.solve(A_within, A_s)) * np.outer(widths, 1.0 / widths)
    return CurvatureAdjustment(
        center=np.asarray(center, float),
        A=A,
        variance_ratios=omega,
        sd_ratios=np.sqrt(np.diag(cov1) / np.diag(cov0)),
        names=tuple(names),
        between_tests=record,
        within=within,
    )


def _adjustment_matrix(X, h_half, h_ihalf) -> np.ndarray:
    """A (scaled coordinates) with ``A^T H A = (H^-1/2 X H^-1/2)^-1``: the adjustment whose
    target covariance is ``H^-1/2 X H^-1/2``."""
    omega, U = np.linalg.eigh(0.5 * (X + X.T))
    return h_ihalf @ ((U / np.sqrt(omega)) @ U.T) @ h_half


def _sqrt_and_inverse(H):
    w, V = np.linalg.eigh(H)
    return (V * np.sqrt(w)) @ V.T, (V / np.sqrt(w)) @ V.T


#: the tests disagree when their estimates' chi-square exceeds this quantile of its distribution
DISAGREEMENT_QUANTILE = 0.99
#: a test's own estimate moves along a direction only where it holds at least this share of the
#: joint information there; two tests are compared along the directions where each does.  A
#: direction a test barely pins (the circuit's low level: the trade of f0 and k3) is noise and
#: overshoot in its own estimate, not information: a Gauss-Newton step along it put k3 at its bound
MIN_SHARE = 0.1


def _shares(blocks, H):
    """(H^-1/2, eigenvectors U of the first test's information in coordinates whitened by the
    joint H, and every test's share of the joint information along each of them)."""
    _, h_ihalf = _sqrt_and_inverse(H)
    _, U = np.linalg.eigh(h_ihalf @ blocks[0][1] @ h_ihalf)
    shares = np.array([np.einsum("ij,ik,kj->j", U, h_ihalf @ Hk @ h_ihalf, U) for _, Hk, _, _ in blocks])
    return h_ihalf, U, shares


def own_step(Hk, gk, H) -> np.ndarray:
    """A test's own Gauss-Newton step from the joint mode (coordinates divided by the
    prior widths), along the directions where it holds at least :data:`MIN_SHARE` of the
    joint information ``H`` (elsewhere it stays at the joint estimate): with
    ``W = H^-1/2 H_k H^-1/2 = sum_j l_j u_j u_j^T``, ``-H^-1/2 sum_{l_j >= MIN_SHARE}
    u_j u_j^T H^-1/2 g_k / l_j``."""
    _, h_ihalf = _sqrt_and_inverse(H)
    lam, U = np.linalg.eigh(h_ihalf @ Hk @ h_ihalf)
    keep = lam >= MIN_SHARE
    return -h_ihalf @ (U[:, keep] @ ((U[:, keep].T @ (h_ihalf @ gk)) / lam[keep]))


def between_test_covariance(blocks, n_stages: int):
    """Where the tests pull the parameters apart beyond their errors: the random-effects
    (between-test) covariance T of their estimates, or None where they agree.

    ``blocks``: per test ``(name, H_k, M_k, g_k)`` in coordinates divided by the prior
    widths, at the joint mode: ``H_k = J_k^T J_k``, ``M_k`` the second moment of its
    errors through J_k, ``g_k = J_k^T r_k``.  Each test alone would move the joint
    estimate by its own step (:func:`own_step`), with the sandwich covariance ``C_k``.
    Along the directions where every test holds at least :data:`MIN_SHARE` of the joint
    information (r of them), Cochran's ``Q = sum_k (x_k - x_w)^T C_k^-1 (x_k - x_w)``
    (``x_w`` the precision-weighted mean) against chi^2 with (K - 1) r degrees of
    freedom (:data:`DISAGREEMENT_QUANTILE`); beyond it, the method of moments of a
    random-effects meta-analysis (DerSimonian & Laird 1986, multivariate): T is the
    positive part of ``S - mean_k C_k``, S the estimates' sample covariance.  An
    effect the model lacks whose size changes with the level (a damper, a softening
    joint) is what pulls a low- and a high-level test apart; T is how far the
    model-form error moves a parameter from one test to the next, which the
    noise of either test does not hold."""
    K = len(blocks)
    if K < 2:
        return None
    H = np.eye(blocks[0][1].shape[0]) + sum(b[1] for b in blocks)
    h_ihalf, U, shares = _shares(blocks, H)
    V = U[:, np.all(shares >= MIN_SHARE, axis=0)]  # the shared directions, whitened
    r = V.shape[1]
    if r == 0:
        return None
    h_half = np.linalg.inv(h_ihalf)
    x = [own_step(Hk, gk, H) for _, Hk, _, gk in blocks]
    info = np.eye(len(H)) / n_stages
    C = []
    for _, Hk, Mk, _ in blocks:
        P = np.linalg.inv(Hk + info)
        C.append(P @ (Mk + info) @ P)
    xs = np.array([V.T @ h_half @ xk for xk in x])  # (K, r) in whitened shared coordinates
    Cs = [V.T @ h_half @ c @ h_half @ V for c in C]
    W = [np.linalg.inv(c) for c in Cs]
    x_w = np.linalg.solve(sum(W), sum(w @ xk for w, xk in zip(W, xs)))
    Q = float(sum((xk - x_w) @ w @ (xk - x_w) for w, xk in zip(W, xs)))
    from scipy.stats import chi2

    limit = float(chi2.ppf(DISAGREEMENT_QUANTILE, (K - 1) * r))
    if Q <= limit:
        return None
    S = np.cov(xs.T, ddof=1).reshape(r, r)
    w, E = np.linalg.eigh(S - sum(Cs) / K)
    T_s = (E * np.clip(w, 0.0, None)) @ E.T
    if not np.any(T_s):
        return None
    back = h_ihalf @ V  # whitened shared -> scaled coordinates
    return {
        "T": back @ T_s @ back.T,
        "Q": Q,
        "limit": limit,
        "n_directions": r,
        "estimates": [(b[0], back @ xk) for b, xk in zip(blocks, xs)],
        "covariances": C,
    }


def own_points(jacobian, residual, sizes, x, box) -> list:
    """Each test's own best point near the joint mode ``x``: :func:`own_step` on its
    rows (``sizes``: the rows of each test, in order), kept inside ``box`` (d, 2)."""
    box = np.asarray(box, float)
    widths = box[:, 1] - box[:, 0]
    J = np.asarray(jacobian, float) * widths
    r = np.asarray(residual, float)
    blocks, row = [], 0
    for n in sizes:
        Jk, rk = J[row : row + n], r[row : row + n]
        row += n
        blocks.append((Jk.T @ Jk, Jk.T @ rk))
    H = np.eye(J.shape[1]) + sum(Hk for Hk, _ in blocks)
    return [np.clip(np.asarray(x, float) + own_step(Hk, gk, H) * widths, box[:, 0], box[:, 1]) for Hk, gk in blocks]


def _between_record(between: dict, widths, names) -> dict:
    """JSON-ready: the test statistic, the between-test sd of each parameter (those the
    tests' disagreement moves) and each test's own estimate's shift from the joint one
    along the shared directions, in the parameters' units."""
    sd_T = np.sqrt(np.clip(np.diag(between["T"]), 0.0, None)) * widths
    moved = sd_T > 1e-9 * widths
    return {
        "chi2": between["Q"],
        "chi2_limit": between["limit"],
        "n_directions": between["n_directions"],
        "between_test_sd": {n: float(v) for n, v, m in zip(names, sd_T, moved) if m},
        "shift_from_joint": {
            name: {n: float(v * w) for n, v, w, m in zip(names, xk, widths, moved) if m}
            for name, xk in between["estimates"]
        },
    }
