"""Least-squares identification of a Kautz-basis Volterra model (eq. 18-19).

:func:`fit_volterra` stacks the regressors of one or several records, solves
the column-normalised least-squares problem (h0 unpenalised, optional ridge)
by a blocked Householder QR and an SVD of its R factor, and returns a
:class:`volterra.VolterraModel` with :class:`FitInfo` diagnostics.  What the
fitted kernels can and cannot represent: :mod:`volterra.model`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._validation import paired_records
from .basis import KautzBasis
from .model import VolterraModel, _coefficient_blocks, _finite

__all__ = ["fit_volterra", "FitInfo"]


@dataclass(frozen=True, repr=False)
class FitInfo:
    """Diagnostics of a least-squares fit.

    Attributes
    ----------
    n_samples : int            total number of samples (rows) used
    n_records : int            number of records fitted jointly
    n_params : int             number of kernel coefficients P (h0 not counted)
    rank : int                 numerical rank of the column-normalised regressor matrix
                               (columns centred when h0 is fitted)
    singular_values : ndarray  of the column-normalised regressor matrix
    condition_number : float   s_max / s_min of the column-normalised regressor matrix
    ridge : float              Tikhonov parameter used (column-normalised problem)
    rss : float                residual sum of squares [y unit^2]
    residual_rms : float       sqrt(rss / n_samples) [y unit]
    relative_residual : float  ||y - y_fit|| / ||y||
    sigma : float              residual standard deviation sqrt(rss / (N - rank - 1 with h0)) [y unit]
    stderr : ndarray           standard errors of the coefficients (white residual assumed)
    component_shares : dict    {order: ||y_n|| / ||y||} on the fitted data (order 0: h0)
    h0_stderr : float          standard error of h0 [y unit] (NaN if h0 was not fitted)
    """

    n_samples: int
    n_records: int
    n_params: int
    rank: int
    singular_values: np.ndarray
    condition_number: float
    ridge: float
    rss: float
    residual_rms: float
    relative_residual: float
    sigma: float
    stderr: np.ndarray
    component_shares: dict
    h0_stderr: float = float("nan")

    def __repr__(self):
        return (
            f"FitInfo(n_samples={self.n_samples}, n_records={self.n_records}, "
            f"n_params={self.n_params}, rank={self.rank}, "
            f"condition_number={self.condition_number:.3g}, "
            f"relative_residual={self.relative_residual:.3g})"
        )


def _tall_qr_r(A: np.ndarray, chunk: int | None = None) -> np.ndarray:
    """R factor of a tall matrix by Householder QR in row blocks (TSQR): QR of
    each block, then QR of the stacked R factors.  Same R (up to signs) as one
    QR of the whole matrix, at a fraction of the cost for tall-skinny A."""
    m, n = A.shape
    if chunk is None:
        chunk = max(512, 8 * n)
    if m <= 2 * chunk:
        return np.linalg.qr(A, mode="r")
    Rs = [np.linalg.qr(A[i : i + chunk], mode="r") for i in range(0, m, chunk)]
    return _tall_qr_r(np.vstack(Rs), chunk)


def _resolve_offset(us, input_offset) -> float:
    """The input offset [u unit]: a number, or "mean" (mean of all input samples)."""
    if isinstance(input_offset, str):
        if input_offset != "mean":
            raise ValueError(f'input_offset must be a number or "mean", got {input_offset!r}')
        return float(sum(r.sum() for r in us) / sum(r.size for r in us))
    return _finite(input_offset, "input_offset")


def _stacked_rows(us, ys, sub, offset):
    """Transposed regressor matrix of all records with y as its last row: (P+1, N)."""
    P = sub.n_params
    AT = np.empty((P + 1, sum(r.size for r in us)))
    k = 0
    for r_u, r_y in zip(us, ys):
        sub.regressor_rows(r_u - offset, out=AT[:P, k : k + r_u.size])
        AT[P, k : k + r_u.size] = r_y
        k += r_u.size
    return AT


def _column_scale(GT, labels):
    """Norms of the regressor rows (the ridge's column normalisation)."""
    scale = np.sqrt(np.einsum("ij,ij->i", GT, GT))
    if not np.all(scale > 0):
        dead = [labels[k] for k in np.flatnonzero(~(scale > 0))]
        raise ValueError(
            f"regressor column(s) {dead[:4]} are identically zero: the input does not excite the "
            "model (is u all zeros?)"
        )
    if not np.all(np.isfinite(scale)):
        raise ValueError("regressors overflow: rescale the input u (e.g. to O(1) units)")
    return scale


def fit_volterra(
    u,
    y,
    basis: KautzBasis,
    ridge: float = 0.0,
    orders=None,
    rcond: float = 1e-12,
    fit_h0: bool = True,
    input_offset=0.0,
) -> VolterraModel:
    """Identify a Kautz-basis Volterra model by linear least squares (eq. 18-19).

    Parameters
    ----------
    u, y : 1-D arrays of equal length, or lists of such records (a 2-D array
        is read as one record per row)
        Input (e.g. force [N]) and output (e.g. velocity [m/s]) sampled at
        ``basis.fs`` Hz; each record starts at rest (the Kautz filters start
        from zero state).  Several records (e.g. two or three excitation
        levels) are fitted jointly: each is filtered separately and their rows
        are stacked.
    basis : KautzBasis
        Poles and J per order; reuse the same basis for every record to be
        compared.
    ridge : float, default 0
        Tikhonov parameter on the column-normalised problem (dimensionless):
        minimises ``||y - h0 - G b||^2 + ridge * sum_j ||G_j||^2 b_j^2`` where
        G_j are the regressor columns (h0 is not penalised).  0 gives ordinary
        least squares.
    orders : iterable of int, optional
        Fit a subset of the basis orders, e.g. (1, 3).
    rcond : float
        Singular values below ``rcond * s_max`` (column-normalised) are
        discarded (rank-deficient problems).
    fit_h0 : bool, default True
        Fit the zeroth-order term h0, one constant [y unit] shared by all
        records (e.g. an offset of the output sensor).  It is not part of the
        components y1, y2, y3 (the mean of y2 is in y2).
    input_offset : float or "mean", default 0
        Constant [u unit] subtracted from every input before filtering, stored
        in the model and subtracted again by :meth:`VolterraModel.components`.
        ``"mean"`` uses the mean of all input samples: for an input sensor
        with an offset, a recorded mean the system did not feel (the kernels
        are then those of the fluctuation; the true input's own sample mean,
        ~ rms / sqrt(N) for noise, goes with it).  The default 0 keeps the
        model a Volterra series of the input as given.

    Returns
    -------
    VolterraModel
        with ``.h0`` and ``.info`` (:class:`FitInfo`: condition number,
        residual, standard errors, ...).

    Notes
    -----
    With h0 the regressor columns and y are centred (over all records), which
    removes h0 from the problem; then ``h0 = mean(y) - mean(G) b``.  Solved by
    a Householder QR (blocked, TSQR) of the column-normalised regressor matrix
    augmented with y, followed by an SVD of its R factor (never by forming
    ``(G^T G)^-1``).  The standard errors assume white residuals; with
    coloured (e.g. truncation) residuals they are optimistic.
    """
    if not isinstance(basis, KautzBasis):
        raise ValueError(f"basis must be a KautzBasis, got {type(basis).__name__}")
    ridge = float(ridge)
    if not np.isfinite(ridge) or ridge < 0:
        raise ValueError(f"ridge must be a non-negative number, got {ridge!r}")
    us, ys, _ = paired_records(u, y)
    offset = _resolve_offset(us, input_offset)
    orders = basis._check_orders(orders)
    sub = basis.subset(orders)
    P = sub.n_params
    N = sum(r.size for r in us)
    if N <= P + fit_h0:
        raise ValueError(
            f"too few samples: {N} sample(s) for {P} regressors (orders {orders}, "
            f"J = {sub.n_functions}); need more than {P + fit_h0} samples - give a longer record "
            "or fewer Kautz functions"
        )
    AT = _stacked_rows(us, ys, sub, offset)
    ynorm = float(np.linalg.norm(AT[P]))
    scale = _column_scale(AT[:P], sub.labels())
    means = AT.mean(axis=1) if fit_h0 else np.zeros(P + 1)
    if fit_h0:
        AT -= means[:, None]  # centred columns and y: h0 drops out
    AT[:P] /= scale[:, None]  # column-normalised regressors G_s (in place)
    Gs = AT[:P].T
    R_full = _tall_qr_r(AT.T)
    R = R_full[:P, :P]
    qty = R_full[:P, P]  # Q^T y
    Ur, s, Vt = np.linalg.svd(R)  # numpy LAPACK: one BLAS thread pool with the QR
    uty = Ur.T @ qty
    keep = s > rcond * s[0]
    rank = int(keep.sum())
    with np.errstate(divide="ignore", invalid="ignore"):
        filt = np.where(keep, s / (s * s + ridge), 0.0)
    theta_s = Vt.T @ (filt * uty)
    theta = theta_s / scale
    mean_s = means[:P] / scale  # column means of the normalised regressors
    h0 = float(means[P] - mean_s @ theta_s) if fit_h0 else 0.0

    blocks = _coefficient_blocks(orders, sub)
    parts = {n: Gs[:, blocks[n]] @ theta_s[blocks[n]] + mean_s[blocks[n]] @ theta_s[blocks[n]] for n in orders}
    resid = AT[P] - Gs @ theta_s  # = y - h0 - sum(parts)  (h0 = 0 without fit_h0)
    rss = float(resid @ resid)
    dof = max(N - rank - fit_h0, 1)
    sigma2 = rss / dof
    cov_s = (Vt.T * filt**2) @ Vt * sigma2
    stderr = np.sqrt(np.clip(np.diag(cov_s), 0, None)) / scale
    # h0 = mean(y) - mean_s . theta_s, the two independent (centred columns)
    h0_stderr = math.sqrt(sigma2 / N + float(mean_s @ cov_s @ mean_s)) if fit_h0 else float("nan")
    shares = {0: abs(h0) * math.sqrt(N)} if fit_h0 else {}
    shares.update({n: float(np.linalg.norm(yn)) for n, yn in parts.items()})
    shares = {n: v / ynorm if ynorm > 0 else float("nan") for n, v in shares.items()}

    info = FitInfo(
        n_samples=N,
        n_records=len(us),
        n_params=P,
        rank=rank,
        singular_values=s,
        condition_number=float(s[0] / s[-1]) if s[-1] > 0 else float("inf"),
        ridge=ridge,
        rss=rss,
        residual_rms=math.sqrt(rss / N),
        relative_residual=math.sqrt(rss) / ynorm if ynorm > 0 else float("nan"),
        sigma=math.sqrt(sigma2),
        stderr=stderr,
        component_shares=shares,
        h0_stderr=h0_stderr,
    )
    return VolterraModel(sub, theta, orders, info, h0=h0, input_offset=offset)
