"""The local polynomial method (LPM): an FRF and its noise from one record of any excitation.

Pintelon, Schoukens, Vandersteen and Barbé, "Estimation of nonparametric
noise and FRF models for multivariable systems", MSSP 24 (2010); Pintelon &
Schoukens, System Identification (2012), sec. 7.2.  The record's DFT (no
window) is fitted around every line k by

    Y(k + r) = G(k + r) U(k + r) + T(k + r) + V(k + r),   r = -R .. R,

with G (the FRF) and T (the transient: leakage of a record that does not
start and end at rest) polynomials of degree ``degree`` in r.  G(k) is the
FRF at line k, free of leakage as far as the polynomials follow it; the
residual's energy over its degrees of freedom ``q = 2R + 1 - 2 (degree + 1)``
is the noise variance of Y at line k (the output noise, and the input
noise's response).  Where a mode's half-power band holds fewer than about 10
lines the polynomials cannot follow it (degree 4, R = 6: 2 % at the peak of
a mode 10 lines wide, 0.2 % at 20 lines, noise free).

One function, :func:`local_polynomial`, used by :func:`volterra.estimate_modes`
(the lines of a record without periods) and by the data layer's noise
estimate (``bayes_update.data.lpm``).  DFTs are scaled by 1 / sqrt(N);
frequencies are line indices here (the callers map them to Hz).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LocalPolynomial", "local_polynomial", "DEFAULT_HALF_WIDTH", "DEFAULT_DEGREE"]

#: half-width R of the local window [lines] and degree of the local polynomials
DEFAULT_HALF_WIDTH = 6
DEFAULT_DEGREE = 4
#: lines solved at once (memory: a block's SVD holds BLOCK x (2R + 1)^2 complex numbers)
BLOCK = 4096


@dataclass(frozen=True)
class LocalPolynomial:
    """The LPM on lines ``k`` (indices into the record's rfft, R .. K - R - 1 or the
    ones asked for): ``G`` (m, S) the FRF, ``noise`` (m, S) the noise variance of
    Y per line (DFT / sqrt(N)), ``var_g`` (m, S) the variance of G, ``dof`` (m,)
    the residual's degrees of freedom per line, ``u_power`` (m,) ``|U(k)|^2``."""

    k: np.ndarray
    G: np.ndarray
    noise: np.ndarray
    var_g: np.ndarray
    dof: np.ndarray
    u_power: np.ndarray


def local_polynomial(
    u, y, half_width: int = DEFAULT_HALF_WIDTH, degree: int = DEFAULT_DEGREE, lines=None, frf: bool = True
) -> LocalPolynomial:
    """The LPM of one record (module docstring).

    Parameters
    ----------
    u : (N,) input; y : (N,) or (N, S) outputs (offsets and drifts removed by the caller).
    half_width, degree : R and the polynomials' degree.
    lines : line indices to solve (default every line R .. K - R - 1).
    frf : also solve G and its variance (False: only the noise, as the data layer's
        noise estimate needs).
    """
    u = np.asarray(u, float)
    y = np.asarray(y, float)
    y = y[:, None] if y.ndim == 1 else y
    if u.ndim != 1 or y.shape[0] != u.size:
        raise ValueError(f"u must be 1-D and y (N,) or (N, S) of the same length, got {u.shape}, {y.shape}")
    R, d = int(half_width), int(degree)
    n_par = 2 * (d + 1)
    if 2 * R + 1 <= n_par + 1:
        raise ValueError(f"half_width {R} leaves no degrees of freedom for degree {d}")
    N = u.size
    U = np.fft.rfft(u) / np.sqrt(N)
    Y = np.fft.rfft(y, axis=0) / np.sqrt(N)
    K = U.size
    if K < 4 * (2 * R + 1):
        raise ValueError(f"a record of {N} samples is too short for the LPM's {2 * R + 1}-line windows")
    k_all = np.arange(R, K - R) if lines is None else np.asarray(lines, int)
    if k_all.size and (k_all.min() < R or k_all.max() > K - R - 1):
        raise ValueError(f"lines must lie in {R} .. {K - R - 1}")
    r = np.arange(-R, R + 1)
    P = np.vander(r / R, d + 1, increasing=True)  # (2R+1, d+1)
    S = y.shape[1]
    G = np.zeros((k_all.size, S), complex)
    noise = np.zeros((k_all.size, S))
    var_g = np.zeros((k_all.size, S))
    dof = np.zeros(k_all.size)
    for a in range(0, k_all.size, BLOCK):
        kk = k_all[a : a + BLOCK]
        idx = kk[:, None] + r[None, :]
        A = np.concatenate([U[idx][:, :, None] * P[None], np.broadcast_to(P, (kk.size,) + P.shape)], axis=2)
        Uc, s, Vh = np.linalg.svd(A, full_matrices=True)
        tol = s[:, :1] * 1e-10 * (2 * R + 1)
        rank = np.sum(s > tol, axis=1)
        Yl = Y[idx]  # (m, 2R+1, S)
        coef = np.einsum("mji,mjs->mis", Uc.conj(), Yl)  # Y in the left singular basis
        keep = np.arange(2 * R + 1)[None, :] >= rank[:, None]
        q = (2 * R + 1) - rank
        noise[a : a + kk.size] = np.sum(np.abs(coef) ** 2 * keep[:, :, None], axis=1) / q[:, None]
        dof[a : a + kk.size] = q
        if frf:
            inv = np.where(np.arange(n_par)[None, :] < rank[:, None], 1.0 / np.where(s > tol, s, 1.0), 0.0)
            v0 = Vh[:, :, 0].conj()  # row 0 of V: G(0)'s coefficient
            G[a : a + kk.size] = np.einsum("mi,mis->ms", v0 * inv, coef[:, :n_par])
            var_g[a : a + kk.size] = noise[a : a + kk.size] * np.sum(np.abs(v0 * inv) ** 2, axis=1)[:, None]
    return LocalPolynomial(k_all, G, noise, var_g, dof, np.abs(U[k_all]) ** 2)
