"""The FRF as modes plus residual terms: least-squares fit, each mode's significance, pole refinement.

Per sensor s, on the lines f of the band::

    H_s(f) ~ sum_m [R_ms / (j w - lam_m) + conj(R_ms) / (j w - conj lam_m)]
             + sum_p c_ps (j w / w_c)^p,          p in RESIDUAL_POWERS = (-2, -1, 0, 1, 2)
             + T_s(Omega) / U(f)                   (records that are not periodic)

with w = 2 pi f, complex residues R_ms, real residual coefficients c_ps and
w_c the band's geometric centre.  The residual terms stand for the modes
outside the band, whatever the sensor measures: a mode far below the band
acts on a displacement as -1 / (m w^2) (p = -2), on a velocity as p = -1, on
an acceleration as a constant; a mode far above it as a constant (residual
flexibility), p = 1 or p = 2 (residual mass) likewise.  ``pseudo`` poles
(poles outside the band, or at its edge) join the fit for modes just outside
it, whose tails the powers cannot follow; they are never reported as modes.

T is the transient of a record's DFT (Pintelon & Schoukens 2012, sec. 6.3):
a record that does not start at rest, or is cut before its response has
died out, has ``Y = G U + T`` exactly (for a discrete system) with
``T(Omega) = sum_m [t_m / (1 - z_m Omega) + conj(t_m) / (1 - conj(z_m) Omega)]``,
``Omega = exp(-j w / fs)``, ``z_m = exp(lam_m / fs)``, over the same poles
(modes and pseudo poles), one set of t per record and sensor; the modes
outside the band add a transient smooth over it, a polynomial of degree
``TRANSIENT_DEGREE`` in Omega (as the residual terms stand for their FRF).  So the whole
record's ``Y / U`` is fitted without leakage whatever the excitation.

* :func:`fit`: the linear least squares for given poles, every sensor weighted
  per line by ``W`` (1 / the sd of H on that line).
* :func:`significance`: for each mode, the rise of the weighted residual's
  energy (chi-square) when it is left out, the other poles held.
* :func:`refine`: the poles that minimise the weighted residual (variable
  projection: everything linear is solved at every step; Kaufman's Jacobian),
  bounded around their starts.

Frequencies in Hz, continuous poles ``lam`` in rad/s (upper half plane).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

__all__ = ["RESIDUAL_POWERS", "FitLines", "fit", "significance", "refine", "poles_from_modal"]

RESIDUAL_POWERS = (-2, -1, 0, 1, 2)
#: degree of the polynomial in Omega that stands for the transients of the modes outside the band
TRANSIENT_DEGREE = 3


@dataclass(frozen=True)
class FitLines:
    """The lines a modal fit runs on: ``f`` (L,) [Hz], ``H`` (L, S), weights ``W``
    (L, S) [1 / H unit]; for the transient terms ``fs`` [Hz], ``inv_u`` (L,) 1 / U on
    each line (0: no transient term, a periodic record's line) and ``record`` (L,)
    the record each line comes from."""

    f: np.ndarray
    H: np.ndarray
    W: np.ndarray
    fs: float = 1.0
    inv_u: np.ndarray | None = None
    record: np.ndarray | None = None

    def take(self, idx) -> "FitLines":
        sub = None if self.inv_u is None else self.inv_u[idx]
        rec = None if self.record is None else self.record[idx]
        return FitLines(self.f[idx], self.H[idx], self.W[idx], self.fs, sub, rec)

    @property
    def records(self) -> list:
        """Records with transient terms."""
        if self.inv_u is None:
            return []
        return sorted({int(r) for r in self.record[self.inv_u != 0]})


def poles_from_modal(freq_hz, zeta) -> np.ndarray:
    """Continuous poles [rad/s] of modes (f [Hz], zeta [-])."""
    w = 2 * np.pi * np.asarray(freq_hz, float)
    z = np.asarray(zeta, float)
    return -z * w + 1j * w * np.sqrt(1 - z**2)


def _poles(modes) -> np.ndarray:
    return poles_from_modal(*zip(*modes)) if len(modes) else np.zeros(0, complex)


def _transient_blocks(d: FitLines, lam):
    """(A, B, masks): 1 / (1 - z Omega), 1 / (1 - conj z Omega) (L, M) and per record the
    line mask times 1 / U (L,)."""
    om = np.exp(-2j * np.pi * d.f / d.fs)[:, None]
    z = np.exp(np.asarray(lam, complex) / d.fs)[None, :]
    A, B = 1.0 / (1.0 - z * om), 1.0 / (1.0 - np.conj(z) * om)
    masks = [np.where(d.record == r, d.inv_u, 0.0) for r in d.records]
    return A, B, masks


def _columns(d: FitLines, lam, powers):
    """(L, n) complex columns of the real unknowns: Re R, Im R of every pole, the residual
    powers' c, then per record with transient terms Re t, Im t of every pole."""
    jw = 2j * np.pi * np.asarray(d.f, float)[:, None]
    lam = np.asarray(lam, complex)[None, :]
    a = 1.0 / (jw - lam)
    b = 1.0 / (jw - np.conj(lam))
    wc = 2 * np.pi * math.sqrt(float(np.min(d.f)) * float(np.max(d.f)))
    res = (jw / wc) ** np.asarray(powers, float)[None, :] if len(powers) else np.zeros((jw.shape[0], 0))
    cols = [a + b, 1j * (a - b), res]
    if d.records:
        A, B, masks = _transient_blocks(d, lam[0])
        for mk in masks:
            cols += [(A + B) * mk[:, None], 1j * (A - B) * mk[:, None]]
        # the transients of the modes outside the band (no pole of their own): smooth over the
        # band, a polynomial in Omega about the band's centre (complex coefficients)
        om = np.exp(-2j * np.pi * (d.f - math.sqrt(float(np.min(d.f)) * float(np.max(d.f)))) / d.fs)
        poly = om[:, None] ** np.arange(TRANSIENT_DEGREE + 1)[None, :]
        for mk in masks:
            cols += [poly * mk[:, None], 1j * poly * mk[:, None]]
    return np.hstack(cols)


def _solve(cols, H, W):
    """Per sensor: real coefficients (n, S) and the weighted complex residual (L, S)."""
    L, S = H.shape
    x = np.zeros((cols.shape[1], S))
    r = np.zeros((L, S), complex)
    for s in range(S):
        A = W[:, s, None] * cols
        Ar = np.vstack([A.real, A.imag])
        b = W[:, s] * H[:, s]
        br = np.concatenate([b.real, b.imag])
        scale = np.linalg.norm(Ar, axis=0)
        scale[scale == 0] = 1.0
        xs = np.linalg.lstsq(Ar / scale, br, rcond=None)[0] / scale
        x[:, s] = xs
        r[:, s] = b - A @ xs
    return x, r


def fit(d: FitLines, modes, pseudo=(), powers=RESIDUAL_POWERS):
    """Least squares of ``modes`` [(f, zeta)] (+ ``pseudo`` poles), residual and transient terms.

    Returns ``(parts, resid, chi2)``: ``parts`` (M, L, S) each mode's FRF part
    (pseudo poles and transients not included), ``resid`` (L, S) the weighted
    residual ``W (H - model)``, ``chi2`` its energy."""
    lam = _poles(modes)
    lam_all = np.concatenate([lam, _poles(pseudo)])
    x, r = _solve(_columns(d, lam_all, powers), d.H, d.W)
    M, Mt = lam.size, lam_all.size
    R = x[:M] + 1j * x[Mt : Mt + M]  # (M, S)
    jw = 2j * np.pi * np.asarray(d.f, float)[:, None]
    a, b = 1.0 / (jw - lam[None, :]), 1.0 / (jw - np.conj(lam)[None, :])
    parts = a.T[:, :, None] * R[:, None, :] + b.T[:, :, None] * np.conj(R)[:, None, :]
    return parts, r, float(np.sum(np.abs(r) ** 2))


def significance(d: FitLines, modes, pseudo=(), powers=RESIDUAL_POWERS):
    """``(rise (M,), resid)``: the rise of chi-square when each mode is left out (the
    others and the pseudo poles held, everything linear refitted), and the full
    fit's weighted residual (L, S)."""
    modes = list(modes)
    _, r, full = fit(d, modes, pseudo, powers)
    out = np.empty(len(modes))
    for m in range(len(modes)):
        out[m] = fit(d, modes[:m] + modes[m + 1 :], pseudo, powers)[2] - full
    return out, r


def _dlam(lam, freq_hz, zeta):
    """(d lam / d log f, d lam / d log zeta) [rad/s]."""
    w = 2 * np.pi * np.asarray(freq_hz, float)
    z = np.asarray(zeta, float)
    return lam, -z * w * (1 + 1j * z / np.sqrt(1 - z**2))


def _residual_jacobian(d: FitLines, freq_hz, zeta, powers, norm):
    """The weighted residual (real, stacked over sensors) and its Jacobian in (log f, log zeta)
    of the poles, by variable projection with Kaufman's approximation: for each
    parameter only its pole's columns move, J = -(I - Q Q^T) (dA/dtheta) x."""
    M = len(freq_hz)
    lam = poles_from_modal(freq_hz, zeta)
    cols = _columns(d, lam, powers)
    jw = 2j * np.pi * np.asarray(d.f, float)[:, None]
    a, b = 1.0 / (jw - lam[None, :]), 1.0 / (jw - np.conj(lam)[None, :])
    d_f, d_z = _dlam(lam, freq_hz, zeta)
    recs = d.records
    if recs:
        A, B, masks = _transient_blocks(d, lam)
        om = np.exp(-2j * np.pi * d.f / d.fs)[:, None]
        z = np.exp(lam / d.fs)[None, :]
    base = 2 * M + len(powers)
    L, S = d.H.shape
    res, jac = [], []
    for s in range(S):
        Aw = d.W[:, s, None] * cols
        Ar = np.vstack([Aw.real, Aw.imag])
        bw = d.W[:, s] * d.H[:, s]
        br = np.concatenate([bw.real, bw.imag])
        scale = np.linalg.norm(Ar, axis=0)
        scale[scale == 0] = 1.0
        Q, Rm = np.linalg.qr(Ar / scale)
        x = np.linalg.lstsq(Rm, Q.T @ br, rcond=None)[0] / scale
        res.append(br - Ar @ x)
        Js = np.empty((2 * L, 2 * M))
        for k, dl in enumerate((d_f, d_z)):
            g = (a * a) * dl[None, :]
            h = (b * b) * np.conj(dl)[None, :]
            dv = (g + h) * x[None, :M] + 1j * (g - h) * x[None, M : 2 * M]  # (L, M)
            for j, mk in enumerate(masks if recs else []):
                dz = z * dl[None, :] / d.fs  # d z / d theta
                gA = A * A * om * dz
                gB = B * B * om * np.conj(dz)
                c0 = base + 2 * M * j
                dv = dv + mk[:, None] * (
                    (gA + gB) * x[None, c0 : c0 + M] + 1j * (gA - gB) * x[None, c0 + M : c0 + 2 * M]
                )
            dv = d.W[:, s, None] * dv
            D = np.vstack([dv.real, dv.imag])
            Js[:, k * M : (k + 1) * M] = -(D - Q @ (Q.T @ D))
        jac.append(Js)
    return np.concatenate(res) / norm, np.vstack(jac) / norm


def refine(d: FitLines, freq_hz, zeta, bounds, powers=RESIDUAL_POWERS):
    """Poles (f [Hz], zeta) minimising the weighted residual, each inside
    ``bounds = ((f_lo, f_hi), (z_lo, z_hi))`` arrays (M,) [Hz, -]; every pole free.

    Returns ``(freq_hz, zeta, at_bound)`` with ``at_bound`` (M,) True where a pole
    ended within 0.5 % of its box's width of an edge (in log)."""
    M = len(freq_hz)
    (flo, fhi), (zlo, zhi) = bounds
    lo = np.log(np.concatenate([flo, zlo]))
    hi = np.log(np.concatenate([fhi, zhi]))
    x0 = np.clip(np.log(np.concatenate([freq_hz, zeta])), lo + 1e-9, hi - 1e-9)
    norm = math.sqrt(float(np.sum(np.abs(d.W * d.H) ** 2))) or 1.0
    cache = {}

    def both(x):
        key = x.tobytes()
        if key not in cache:
            cache.clear()
            cache[key] = _residual_jacobian(d, np.exp(x[:M]), np.exp(x[M:]), powers, norm)
        return cache[key]

    res = least_squares(
        lambda x: both(x)[0],
        x0,
        jac=lambda x: both(x)[1],
        bounds=(lo, hi),
        x_scale=np.full(x0.size, 1e-3),
        xtol=1e-10,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=60 * x0.size,
    )
    x = res.x
    width = hi - lo
    edge = np.minimum(x - lo, hi - x) <= 5e-3 * width
    return np.exp(x[:M]), np.exp(x[M:]), edge[:M] | edge[M:]
