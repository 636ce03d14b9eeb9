"""Poles of several modes from FRFs: LSCF, stabilisation diagram, residues.

* :func:`lscf_poles`: least-squares complex-frequency estimator (Guillaume,
  Verboven, Vanlanduit, Van der Auweraer & Peeters, IMAC 2003), poly-reference
  form with a common denominator for several sensors ("p-LSCF" with one
  input).  For each model order n the FRFs of all sensors are fitted as
  ``H_o(f) ~ B_o(Omega) / A(Omega)``, ``Omega = exp(-j 2 pi f dt)``, by the
  linearised weighted least squares ``min sum |w_o (B_o - H_o A)|^2`` with
  real coefficients; the numerators are eliminated (QR per sensor), the
  denominator's last coefficient is fixed to 1 and the rest solved by a
  least-squares solve (never by inverting normal equations, which square the
  condition number).  ``dt`` maps the top of the fitted band to 0.9 pi: the
  fit's "sampling" is the band's, not the record's, so an oversampled record
  does not make the power basis ill-conditioned.
* :func:`stable_modes`: the stabilisation diagram read automatically: a
  physical pole (stable, 0 < zeta < max_damping, inside the band) is stable
  at order n when order n - 2 has one within ``df`` in frequency and ``dz`` in
  damping; stable poles are clustered in frequency over the orders, and a
  cluster found at enough orders is a mode (its median frequency and
  damping).
* :func:`mode_contributions`: residues of the chosen poles on every sensor
  (least-squares frequency domain, LSFD, with a constant residual term) and
  each mode's part of the FRF, from which the modes' response energies follow.

Why not sdypy-ema (PyPI, MIT): its ``Model.get_poles(method='lscf')`` needs the
FRF on a uniform grid starting at 0 Hz, solves the normal equations with an
explicit inverse (ill-conditioned at the orders needed for six modes), takes
no per-line weights (coherence), and leaves the pole choice to a stabilisation
chart read by hand (matplotlib / Qt); it also pulls pyuff, tqdm and
matplotlib.  What is needed here (a band of selected lines, weights, an
automatic reading of the diagram) is about 150 lines of numpy.

Frequencies in Hz, continuous poles ``s`` in rad/s (upper half plane).
"""

from __future__ import annotations

import numpy as np

__all__ = ["lscf_poles", "stable_modes", "mode_contributions", "DEFAULT_MAX_DAMPING"]

#: Largest damping ratio [-] of a physical mode.
DEFAULT_MAX_DAMPING = 0.3


def _fit_dt(f):
    """Time step [s] of the LSCF basis: the band's top at 0.9 pi."""
    return 0.45 / float(np.max(f))


def lscf_poles(f, H, orders, weights=None):
    """Continuous poles [rad/s] of LSCF fits of ``H`` at several model orders.

    Parameters
    ----------
    f : (L,) frequencies [Hz] of the lines used (any spacing, > 0).
    H : (L,) or (L, S) complex FRFs of S sensors on those lines.
    orders : iterable of int
        Denominator degrees n (number of poles, conjugates included).
    weights : (L,) or (L, S), optional
        Weights of the lines (e.g. 1 / standard deviation of H); default
        ``1 / |H|`` per sensor (a relative fit, so that weak modes count).

    Returns
    -------
    dict {n: complex array of the roots' continuous poles s = log(z) / dt}
    (all roots, conjugates and unstable ones included).
    """
    f = np.asarray(f, float)
    H = np.asarray(H, complex)
    H = H[:, None] if H.ndim == 1 else H
    L, S = H.shape
    if weights is None:
        weights = 1.0 / np.maximum(np.abs(H), 1e-300)
    W = np.broadcast_to(np.asarray(weights, float).reshape(L, -1), (L, S))
    dt = _fit_dt(f)
    orders = sorted(int(n) for n in orders)
    orders = [n for n in orders if not (2 * L * S < 2 * (n + 1) + n or L <= n + 1)]  # too few lines
    if not orders:
        return {}
    top = orders[-1]
    X = np.exp(-2j * np.pi * np.outer(f, np.arange(top + 1)) * dt)  # (L, top+1)
    # per sensor, the numerator's orthonormal basis at the top order: the leading columns of
    # its Q span the numerator of every lower order (QR of leading columns is nested)
    Qs, Ys = [], []
    for o in range(S):
        WX = W[:, o, None] * X
        Qs.append(np.linalg.qr(np.vstack([WX.real, WX.imag]))[0])
        HX = -(W[:, o] * H[:, o])[:, None] * X
        Ys.append(np.vstack([HX.real, HX.imag]))
    out = {}
    for n in orders:
        # the numerators eliminated sensor by sensor; each block reduced to its R factor
        # (the stacked least squares is that of the R factors: never the normal equations)
        blocks = []
        for Q, Yr in zip(Qs, Ys):
            Qn, Yn = Q[:, : n + 1], Yr[:, : n + 1]
            blocks.append(np.linalg.qr(Yn - Qn @ (Qn.T @ Yn), mode="r"))
        Mr = np.vstack(blocks)
        scale = np.linalg.norm(Mr, axis=0)
        scale[scale == 0] = 1.0
        Ms = Mr / scale
        alpha = np.linalg.lstsq(Ms[:, :n], -Ms[:, n], rcond=None)[0] / scale[:n]
        coef = np.append(alpha, 1.0 / scale[n])  # A(Omega) = sum coef_r Omega^r
        # Omega = 1/z: sum_r coef_r z^-r = 0  <=>  sum_r coef_r z^(n-r) = 0
        z = np.roots(coef)
        z = z[z != 0]
        out[n] = np.log(z.astype(complex)) / dt
    return out


def _physical(s, band, max_damping):
    s = s[s.imag > 0]
    wn = np.abs(s)
    fr, zeta = wn / (2 * np.pi), -s.real / np.maximum(wn, 1e-300)
    keep = (zeta > 0) & (zeta < max_damping) & (fr >= band[0]) & (fr <= band[1])
    return fr[keep], zeta[keep]


def stable_modes(poles_by_order, band, max_damping=DEFAULT_MAX_DAMPING, df=0.01, dz=0.1):
    """Read a stabilisation diagram: modes stable over increasing model orders.

    Parameters
    ----------
    poles_by_order : {n: continuous poles [rad/s]} (from :func:`lscf_poles`).
    band : (f_min, f_max) [Hz] where modes are accepted.
    max_damping : float
        Physical poles have 0 < zeta < max_damping [-].
    df, dz : float
        A pole is stable at order n if order n - 2 (the previous order) has a
        pole within ``df`` (relative) in frequency and ``dz`` (relative) in
        damping.

    Returns
    -------
    clusters : list of (freq_hz, zeta, count) sorted by frequency; ``count`` is
        the number of orders at which the cluster is stable (the caller decides
        how many make a mode: :func:`volterra.estimate_modes` asks for 30 % of
        the orders, at least 3).
    diagram : list of (n, freq_hz array, zeta array, stable bool array) for plots.
    """
    orders = sorted(poles_by_order)
    diagram, prev = [], None
    stable_f, stable_z, stable_n = [], [], []
    for n in orders:
        fr, ze = _physical(poles_by_order[n], band, max_damping)
        ok = np.zeros(fr.size, bool)
        if prev is not None and prev[0].size and fr.size:
            rf = np.abs(fr[:, None] / prev[0][None, :] - 1)
            rz = np.abs(ze[:, None] / prev[1][None, :] - 1)
            ok = np.any((rf < df) & (rz < dz), axis=1)
        diagram.append((n, fr, ze, ok))
        stable_f.extend(fr[ok])
        stable_z.extend(ze[ok])
        stable_n.extend([n] * int(ok.sum()))
        prev = (fr, ze)
    if not stable_f:
        return [], diagram
    order = np.argsort(stable_f)
    sf, sz, sn = (np.asarray(a)[order] for a in (stable_f, stable_z, stable_n))
    # clusters: consecutive stable poles closer than df (relative) in frequency
    cuts = np.flatnonzero(np.diff(sf) / sf[:-1] > df) + 1
    modes = []
    for idx in np.split(np.arange(sf.size), cuts):
        count = len(set(sn[idx].tolist()))
        top = idx[sn[idx] >= np.median(sn[idx])]  # the higher orders of the cluster
        modes.append((float(np.median(sf[top])), float(np.median(sz[top])), count))
    return modes, diagram


def mode_contributions(f, H, s_poles, weights=None):
    """Each mode's part of the FRFs: least-squares residues (LSFD).

    ``H(f) ~ sum_m [R_m / (j w - s_m) + conj(R_m) / (j w - conj s_m)] + C``
    per sensor (w = 2 pi f, complex residues R_m, a complex constant C for the
    modes outside the band), solved jointly for all sensors.

    Returns
    -------
    parts : (M, L, S) complex, mode m's FRF on every line and sensor.
    """
    f = np.asarray(f, float)
    H = np.asarray(H, complex)
    H = H[:, None] if H.ndim == 1 else H
    s = np.asarray(s_poles, complex)
    jw = 2j * np.pi * f[:, None]
    a = 1.0 / (jw - s[None, :])
    b = 1.0 / (jw - s.conj()[None, :])
    # real unknowns per sensor: Re R, Im R of every mode, Re C, Im C
    cols = np.hstack([a + b, 1j * (a - b), np.ones((f.size, 1)), 1j * np.ones((f.size, 1))])
    W = np.ones(f.size) if weights is None else np.asarray(weights, float)
    A = np.vstack([(W[:, None] * cols).real, (W[:, None] * cols).imag])
    rhs = np.vstack([(W[:, None] * H).real, (W[:, None] * H).imag])
    x = np.linalg.lstsq(A, rhs, rcond=None)[0]
    M = s.size
    R = x[:M] + 1j * x[M : 2 * M]  # (M, S)
    return (a.T[:, :, None] * R[:, None, :]) + (b.T[:, :, None] * R.conj()[:, None, :])


#: a band wider than this ratio is fitted in overlapping windows of this ratio (two octaves),
#: each stepped by its square root: the LSCF's power basis resolves a window's modes, not a
#: mode at a tenth of a wide band's top next to one at its top
SUBBAND_RATIO = 4.0
#: lines of a window fitted (evenly thinned beyond: a window of two octaves keeps a line every
#: 0.15 % in frequency, six in the half-power band of a mode damped at 0.2 %)
MAX_WINDOW_LINES = 2048


def subbands(lo: float, hi: float, ratio: float = SUBBAND_RATIO) -> list:
    """``[(fit_lo, fit_hi, core_lo, core_hi), ...]`` [Hz]: windows of ``ratio`` stepped by its
    square root (adjusted to tile ``(lo, hi)`` exactly); a window's modes count in its core
    (its middle half in log frequency; the first core starts at ``lo``, the last ends at ``hi``)."""
    if hi / lo <= ratio:
        return [(lo, hi, lo, hi)]
    n = int(np.ceil(np.log(hi / lo) / np.log(np.sqrt(ratio)))) - 1
    step = (hi / lo) ** (1.0 / (n + 1))
    out = []
    for j in range(n):
        a = lo * step**j
        out.append((a, a * step * step, lo if j == 0 else a * step**0.5, hi if j == n - 1 else a * step**1.5))
    return out


def subband_clusters(f, H, W, band, orders, max_damping=DEFAULT_MAX_DAMPING, outside=2.0):
    """Stable pole clusters of LSCF fits of each :func:`subbands` window.

    Returns ``(clusters, pseudo, diagram)``: ``clusters`` [(freq_hz, zeta, count,
    needed)] in the band, each from the window whose core holds it (``needed``:
    30 % of that window's fitted orders, at least 3); ``pseudo`` [(freq_hz, zeta,
    count, needed)] clusters of the first and last windows outside the band (up to
    a factor ``outside`` beyond it: the modes just outside, which the band's
    edges see); ``diagram`` the windows' diagrams together."""
    lo, hi = band
    clusters, pseudo, diagram = [], [], []
    for a, b, c0, c1 in subbands(lo, hi):
        sel = np.flatnonzero((f >= a) & (f <= b))
        if sel.size < 8:
            continue
        sel = sel[:: max(1, -(-sel.size // MAX_WINDOW_LINES))]  # evenly thinned: speed
        Wsel = None if W is None else np.asarray(W)[sel]
        poles = lscf_poles(f[sel], H[sel], orders, Wsel)
        if not poles:
            continue
        wide = (a / outside if c0 == lo else c0, b * outside if c1 == hi else c1)
        found, diag = stable_modes(poles, wide, max_damping)
        need = max(3, int(np.ceil(0.3 * (len(poles) - 1))))
        diagram.extend(diag)
        for fr, ze, count in found:
            if c0 <= fr <= c1:
                clusters.append((fr, ze, count, need))
            elif fr < lo or fr > hi:
                pseudo.append((fr, ze, count, need))
    return clusters, pseudo, diagram
