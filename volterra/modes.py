"""Poles of every resolvable mode of a record: :func:`estimate_modes`.

1. H1 of every sensor: for a periodic excitation (``period_samples``),
   period-synchronous spectra without leakage (:func:`volterra.periodic_h1`);
   for a transient record (input and response at rest over its last 10 %: a
   chirp or burst and its free decay) the whole record's spectra, also
   leakage free; otherwise Welch averages (:func:`volterra.estimate_h1`),
   whose Hann windows would smear a transient.  Each record's and
   channel's mean is removed first (sensor offsets).
2. The lines used: inside the excited band (``f_range`` narrows it) and
   coherent (``min_coherence`` on at least one sensor).
3. LSCF fits of all sensors with a common denominator over increasing model
   orders, read as a stabilisation diagram (:mod:`volterra.lscf`): a mode is
   a cluster of physical poles (0 < zeta < ``max_damping``, in the band)
   stable in frequency (1 %) and damping (10 %) from one order to the next,
   at 30 % of the orders or more.  ``n_modes`` takes that many of them, the
   most energetic first.  Modes with less than ``min_share`` of the response
   energy (their LSFD part of the FRFs, weighted by the input spectrum) are
   dropped.
4. ``refine``: the poles that minimise the relative residual of the
   record's linear fit in the basis itself (feed-through plus J1 = 2 per
   mode, :mod:`volterra.gobf`, an h0 per sensor), all sensors jointly:
   bounded nonlinear least squares (variable projection: the linear
   coefficients are solved at every step) over log frequency and log
   damping, each mode inside a neighbourhood of its LSCF start.

Modes come back sorted by their response energy, the largest first.  What
cannot be trusted raises :class:`PoleEstimationError`, saying what to check.
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np
from scipy.optimize import least_squares
from scipy.signal import welch

from ._validation import as_record_list
from .frf import _segment_lengths, _welch_kw, estimate_h1, excited_band, periodic_h1
from .gobf import gobf_filter_rows
from .kautz import KautzPole
from .lscf import DEFAULT_MAX_DAMPING, lscf_poles, mode_contributions, stable_modes

__all__ = ["PoleEstimationError", "ModalEstimate", "estimate_modes"]

#: Default lowest coherence of the lines the poles are fitted on (on one sensor at least).
MIN_COHERENCE = 0.5
#: Default highest LSCF model order (number of poles, conjugates included).
MAX_LSCF_ORDER = 40
#: A cluster is a mode when it is stable at this fraction of the orders (and at least 3).
MIN_STABLE_FRACTION = 0.3
#: Default smallest share of the response energy of a mode.
MIN_SHARE = 1e-3
#: Default largest relative residual of the refined linear fit.
MAX_RESIDUAL = 0.5
#: Input lines of a periodic record count as excited above this fraction of the strongest.
PERIODIC_LINE_LEVEL = 1e-3


class PoleEstimationError(ValueError):
    """No trustworthy pole could be estimated from the data; the message says
    what to check (band, coherence, offsets and drifts, level of the record)."""


@dataclass(frozen=True)
class ModalEstimate:
    """Result of :func:`estimate_modes`.

    Attributes
    ----------
    poles : tuple of KautzPole, sorted by response energy (largest first)
    energy_shares : (M,) [-] each mode's share of the linear response energy
        (LSFD parts of the sensors' FRFs, input spectrum weighted, every
        sensor normalised by its own energy), same order as ``poles``
    lscf_poles : tuple of KautzPole, the LSCF estimates before refinement
    band : (f_min, f_max) [Hz] of the lines the poles were fitted on
    relative_residual : ||Y - Y_fit|| / ||Y|| of the refined linear fit over
        all sensors (NaN without refinement)
    f, H, coherence : the lines used [Hz], H1 (L, n_sensors), coherence (L, n_sensors)
    diagram : [(order, freq_hz, zeta, stable)] of the stabilisation diagram
    """

    poles: tuple
    energy_shares: np.ndarray
    lscf_poles: tuple
    band: tuple
    relative_residual: float
    f: np.ndarray = field(repr=False)
    H: np.ndarray = field(repr=False)
    coherence: np.ndarray = field(repr=False)
    diagram: list = field(repr=False)


def _records(u, y):
    """(list of centred 1-D inputs, list of centred (n, S) outputs)."""
    single = np.ndim(u) == 1 and not isinstance(u, (list, tuple))
    us, _ = as_record_list(u, "u")
    ys = [y] if single else list(y)
    if len(ys) != len(us):
        raise ValueError(f"got {len(us)} input record(s) but {len(ys)} output record(s); pass one y per u")
    out = []
    for k, (r_u, r_y) in enumerate(zip(us, ys)):
        r_y = np.asarray(r_y, float)
        r_y = r_y[:, None] if r_y.ndim == 1 else r_y
        if r_y.ndim != 2 or r_y.shape[0] != r_u.size:
            raise ValueError(f"y record {k} must be (n,) or (n, n_sensors) with n = len(u) = {r_u.size}, "
                             f"got shape {r_y.shape}")
        if not np.all(np.isfinite(r_y)):
            raise ValueError(f"y record {k} contains NaN/inf values")
        out.append(r_y - r_y.mean(axis=0))
    S = {r.shape[1] for r in out}
    if len(S) != 1:
        raise ValueError(f"every record needs the same sensors, got {sorted(S)} columns")
    return [r - r.mean() for r in us], out


def _is_transient(us, ys, tail=0.1):
    """True when every record ends at rest: the input and the response over the
    last ``tail`` of the record are below 10 % / 20 % of their rms (a chirp,
    burst or impact followed by a free decay)."""
    for r_u, r_y in zip(us, ys):
        k = max(1, int(tail * r_u.size))
        if np.sqrt(np.mean(r_u[-k:] ** 2)) > 0.1 * np.sqrt(np.mean(r_u ** 2)):
            return False
        if np.any(np.sqrt(np.mean(r_y[-k:] ** 2, axis=0)) > 0.2 * np.sqrt(np.mean(r_y ** 2, axis=0))):
            return False
    return True


def _h1_lines(us, ys, fs, f_range, period_samples, nperseg, min_coherence):
    """(f, H (L, S), coherence (L, S), input power (L,)) on the excited, coherent lines."""
    if period_samples is None and _is_transient(us, ys):
        # one leakage-free spectrum per record (boxcar): Welch's windows smear a transient
        N = max(r.size for r in us)
        U = np.stack([np.fft.rfft(r, n=N) for r in us])                      # (R, K)
        Y = np.stack([np.fft.rfft(r, n=N, axis=0) for r in ys])             # (R, K, S)
        upow = np.sum(np.abs(U) ** 2, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            H = np.einsum("rks,rk->ks", Y, U.conj()) / upow[:, None]
            Syy = np.sum(np.abs(Y) ** 2, axis=0)
            coh = np.abs(np.einsum("rks,rk->ks", Y, U.conj())) ** 2 / (upow[:, None] * Syy)
        if len(us) == 1:
            coh = np.ones_like(H, dtype=float)   # one spectrum: no averaging, no coherence
        f = np.arange(upow.size) * fs / N
        lo, hi = excited_band(us, fs, nperseg=nperseg) if f_range is None else map(float, f_range)
        inband = (f >= lo) & (f <= hi)
        excited = upow >= 1e-2 * upow[inband].max() if inband.any() else inband
        line_spacing = fs / N
    elif period_samples is not None:
        f, H, coh, upow = periodic_h1(us, ys, fs, period_samples)
        excited = upow >= PERIODIC_LINE_LEVEL * upow[1:].max()
        excited[0] = False
        lo, hi = (f[excited].min(), f[excited].max()) if f_range is None else map(float, f_range)
        line_spacing = fs / period_samples
    else:
        seg = max(_segment_lengths(us, nperseg))
        cols = [estimate_h1(us, [r[:, s] for r in ys], fs, nperseg=nperseg, nfft=seg, return_coherence=True)
                for s in range(ys[0].shape[1])]
        f = cols[0][0]
        H = np.stack([c[1] for c in cols], axis=1)
        coh = np.stack([c[2] for c in cols], axis=1)
        upow = sum(welch(r, **_welch_kw(fs, "hann", n, seg))[1]
                   for r, n in zip(us, _segment_lengths(us, nperseg)))
        excited = np.ones(f.size, bool)
        lo, hi = excited_band(us, fs, nperseg=nperseg) if f_range is None else map(float, f_range)
        line_spacing = fs / seg
    if not lo < hi:
        raise ValueError(f"f_range must be (f_min, f_max) with f_min < f_max, got {f_range!r}")
    band = excited & (f >= lo) & (f <= hi) & (f > 0) & np.all(np.isfinite(H), axis=1)
    if band.sum() < 4:
        raise ValueError(f"the band ({lo:.4g}, {hi:.4g}) Hz holds fewer than 4 frequency lines "
                         f"(spacing {line_spacing:.3g} Hz); widen it or give a longer record")
    good = band & (coh.max(axis=1) >= min_coherence)
    if good.sum() < 4:
        raise PoleEstimationError(
            f"fewer than 4 frequency lines in ({lo:.4g}, {hi:.4g}) Hz have a coherence of "
            f"{min_coherence:g} or more (largest {coh[band].max():.3g}): the output does not follow "
            "the input there, it is noise. Check that y is the response to u (channels, units, "
            "synchronisation), the noise level, and f_range."
        )
    return f[good], H[good], coh[good], upow[good]


def _pick_modes(clusters, n_orders, n_modes, energy):
    """Clusters that make modes: stable at >= 30 % of the orders (>= 3); with
    ``n_modes``, the n_modes of those with the most response energy (``energy``:
    a function of a list of clusters), topped up by the most stable others."""
    need = max(3, int(math.ceil(MIN_STABLE_FRACTION * (n_orders - 1))))
    strong = [c for c in clusters if c[2] >= need]
    if n_modes is None:
        return strong
    if len(clusters) < n_modes:
        raise PoleEstimationError(
            f"n_modes = {n_modes}, but the stabilisation diagram holds only {len(clusters)} "
            "stable pole cluster(s) in the band. Check the band (f_range), the coherence and the "
            "record length (frequency resolution), or ask for fewer modes."
        )
    if len(strong) >= n_modes:
        shares = energy(strong)
        return [strong[i] for i in np.argsort(-shares)[:n_modes]]
    weak = sorted((c for c in clusters if c[2] < need), key=lambda c: -c[2])
    return strong + weak[:n_modes - len(strong)]


def _energies(f, H, upow, s):
    parts = mode_contributions(f, H, s)                          # (M, L, S)
    norm = np.sum(upow[:, None] * np.abs(H) ** 2, axis=0)        # per sensor
    e = np.sum(upow[None, :, None] * np.abs(parts) ** 2, axis=1) / norm
    e = e.sum(axis=1)
    return e / e.sum()


def estimate_modes(u, y, fs: float, f_range=None, n_modes: int | None = None, refine: bool = True,
                   period_samples: int | None = None, nperseg: int | None = None,
                   min_coherence: float = MIN_COHERENCE, max_damping: float = DEFAULT_MAX_DAMPING,
                   max_order: int = MAX_LSCF_ORDER, min_share: float = MIN_SHARE,
                   max_residual: float = MAX_RESIDUAL, feedthrough: bool = True) -> ModalEstimate:
    """Poles of every mode of the excited, coherent band of a linear record.

    Parameters
    ----------
    u : 1-D array (input, e.g. force), or a list of records.
    y : (n,) or (n, n_sensors) response(s) to ``u`` (a list for several records).
    fs : sampling rate [Hz].
    f_range : (f_min, f_max) [Hz], optional; default the excited band.
    n_modes : int, optional
        Number of modes to return: of the clusters stable at 30 % of the
        orders, those with the most response energy (topped up by the most
        stable other clusters when there are fewer); default: every cluster
        stable at 30 % of the orders with ``min_share`` of the energy.
    refine : bool
        Polish the poles on the time-domain linear fit (see module docstring).
    period_samples : int, optional
        Period of a periodic excitation [samples]: H1 from period-synchronous
        FFTs, the first (transient) period dropped, and the time-domain
        refinement fitted from the second period on.
    nperseg : Welch segment length [samples] (non-periodic records).
    min_coherence, max_damping, max_order, min_share, max_residual : see the
        module constants (0.5, 0.3, 40, 1e-3, 0.5).
    feedthrough : bool
        Whether the linear fit the poles are refined on has the input's own term
        (the basis's order-1 form they will be used in).

    Raises
    ------
    PoleEstimationError
        No coherent line, no stable mode, a refined pole at the edge of its
        neighbourhood, or a refined linear fit that leaves more than
        ``max_residual`` of the response unexplained.
    """
    fs = float(fs)
    us, ys = _records(u, y)
    f, H, coh, upow = _h1_lines(us, ys, fs, f_range, period_samples, nperseg, min_coherence)
    c2 = np.clip(coh, 0.0, 0.9999)
    weights = np.sqrt(c2 / (1.0 - c2)) / np.maximum(np.abs(H), 1e-300)
    orders = list(range(2, int(max_order) + 1, 2))
    band = (float(f.min()), float(f.max()))
    fits = lscf_poles(f, H, orders, weights)
    clusters, diagram = stable_modes(fits, band, max_damping)
    def energy(cands):
        return _energies(f, H, upow, np.array([KautzPole.from_modal(fr, ze, fs).s for fr, ze, _ in cands]))

    chosen = _pick_modes(clusters, len(fits), n_modes, energy)
    no_stable = (
        f"no mode is stable over the LSCF model orders in ({band[0]:.4g}, {band[1]:.4g}) Hz "
        f"(a physical pole, 0 < zeta < {max_damping:g}, stable in frequency and damping at 30 % of the "
        "orders): the response looks like noise, or has no resonance in the band. Check that y is the "
        "response to u, the noise level, offsets or slow drifts of y, and f_range.")
    fallback = not chosen
    if not chosen and refine and n_modes in (None, 1):
        # a lightly damped mode whose record does not end at rest (a chirp with a short decay)
        # gives a leaky H1 on which no LSCF order is stable: one mode from the peak and
        # half-power width, refined in the time domain, is what the record still supports
        peak = _peak_mode(f, H)
        if peak is not None:
            # the leaky peak's width overstates the damping several-fold: start a quarter of
            # it, so that the refinement's range (a tenth to ten times the start) holds the truth
            chosen = [(peak[0], peak[1] / 4.0, 0)]
    if not chosen:
        raise PoleEstimationError(no_stable)
    lscf = [KautzPole.from_modal(fr, ze, fs) for fr, ze, _ in chosen]
    shares = _energies(f, H, upow, np.array([p.s for p in lscf]))
    keep = np.ones(len(lscf), bool) if n_modes is not None else shares >= min_share
    lscf = [p for p, k in zip(lscf, keep) if k]
    poles, resid = lscf, float("nan")
    if refine:
        skip = 0 if period_samples is None else int(period_samples)
        try:
            poles, resid = refine_modes(us, ys, lscf, skip=skip, max_residual=max_residual,
                                        feedthrough=feedthrough)
        except PoleEstimationError as err:
            if not fallback:
                raise
            # the peak was the last resort: the record's own failure is the first message
            raise PoleEstimationError(f"{no_stable} (The largest H1 peak, {lscf[0].freq_hz:.4g} Hz, "
                                      f"could not be refined either: {err})") from None
    shares = _energies(f, H, upow, np.array([p.s for p in poles]))
    order = np.argsort(-shares)
    return ModalEstimate(poles=tuple(poles[i] for i in order), energy_shares=shares[order],
                         lscf_poles=tuple(lscf[i] for i in order), band=band, relative_residual=resid,
                         f=f, H=H, coherence=coh, diagram=diagram)


def _peak_mode(f, H):
    """(f, zeta) of the largest peak of the sensors' summed |H|^2 on the lines:
    the peak and its half-power width (None without two half-power points)."""
    p = np.sum(np.abs(H) ** 2, axis=1)
    i = int(np.argmax(p))
    half = p[i] / 2.0
    lo = next((k for k in range(i, -1, -1) if p[k] <= half), None)
    hi = next((k for k in range(i, len(p)) if p[k] <= half), None)
    if lo is None or hi is None or not 0 < i < len(p) - 1:
        return None
    zeta = (f[hi] - f[lo]) / (2.0 * f[i])
    return (float(f[i]), float(min(max(zeta, 1e-4), 0.3)))


# ------------------------------------------------------------ time-domain refinement
def _bounds(poles):
    """Box per mode in (log f, log zeta): f0 (1 +- max(4 zeta0, 5 %)), cut halfway to
    the neighbouring modes; zeta0 / 10 .. min(10 zeta0, 0.95)."""
    f0 = np.array([p.freq_hz for p in poles])
    z0 = np.array([p.damping_ratio for p in poles])
    span = np.maximum(4.0 * z0, 0.05)
    lo, hi = f0 / (1.0 + span), f0 * (1.0 + span)
    order = np.argsort(f0)
    for a, b in zip(order[:-1], order[1:]):
        mid = math.sqrt(f0[a] * f0[b])
        hi[a], lo[b] = min(hi[a], mid), max(lo[b], mid)
    hi = np.minimum(hi, 0.45 * poles[0].fs)
    zlo, zhi = z0 / 10.0, np.minimum(10.0 * z0, 0.95)
    return np.log(np.concatenate([lo, zlo])), np.log(np.concatenate([hi, zhi]))


def _poles_of(x, fs):
    M = x.size // 2
    return [KautzPole.from_modal(math.exp(x[m]), math.exp(x[M + m]), fs) for m in range(M)]


def _residual(x, us, ys, fs, skip, ynorm, feedthrough=True):
    """Residual of the linear fit (J1 = 2 per mode + h0, and the feed-through), all sensors, scaled."""
    modes = _poles_of(x, fs)
    G, Y = [], []
    for r_u, r_y in zip(us, ys):
        rows = gobf_filter_rows(r_u, modes, feedthrough=feedthrough)[:, skip:]
        G.append(np.vstack([rows, np.ones((1, rows.shape[1]))]).T)
        Y.append(r_y[skip:])
    G, Y = np.vstack(G), np.vstack(Y) / ynorm
    Q, _ = np.linalg.qr(G)
    return (Y - Q @ (Q.T @ Y)).ravel()


def refine_modes(us, ys, poles, skip: int = 0, max_residual: float = MAX_RESIDUAL, feedthrough: bool = True):
    """Refine several poles on the records' linear fit (see the module docstring).

    ``us``: centred 1-D inputs; ``ys``: centred (n, S) outputs; ``skip``:
    leading samples of every record left out of the fit (a periodic record's
    first period).  Returns (poles, relative residual).
    """
    fs = poles[0].fs
    ynorm = np.sqrt(sum(np.sum(r[skip:] ** 2, axis=0) for r in ys))
    if not np.all(ynorm > 0):
        raise PoleEstimationError("a sensor's response is identically zero (after its mean is removed)")
    lo, hi = _bounds(poles)
    x0 = np.log([p.freq_hz for p in poles] + [p.damping_ratio for p in poles])
    x0 = np.clip(x0, lo + 1e-9, hi - 1e-9)
    res = least_squares(_residual, x0, bounds=(lo, hi), args=(us, ys, fs, skip, ynorm, feedthrough),
                        x_scale=np.full(x0.size, 1e-3), xtol=1e-10, ftol=1e-12, gtol=1e-12,
                        max_nfev=100 * x0.size)
    x = res.x
    refined = _poles_of(x, fs)
    width = hi - lo
    for m in range(x.size):
        if min(x[m] - lo[m], hi[m] - x[m]) <= 5e-3 * width[m]:
            p = refined[m % len(refined)]
            what = "frequency" if m < len(refined) else "damping ratio"
            raise PoleEstimationError(
                f"refining the poles: the {what} of the mode near {p.freq_hz:.4g} Hz ran to the edge "
                f"of its search range ({math.exp(lo[m]):.4g} .. {math.exp(hi[m]):.4g}) around the LSCF "
                "start: the record is not essentially linear, or that mode is not in it. Check "
                "f_range, offsets and slow drifts in u and y, that the record is low-level, and n_modes."
            )
    rel = float(np.linalg.norm(_residual(x, us, ys, fs, skip, ynorm)) / math.sqrt(ys[0].shape[1]))
    if not rel <= max_residual:
        raise PoleEstimationError(
            f"the refined linear fit leaves {100 * rel:.3g} % of ||y|| unexplained (more than "
            f"{100 * max_residual:.3g} %): y does not follow u linearly. Check that y is the response "
            "to u, the noise level, slow drifts of y, that the record is low-level (not strongly "
            "nonlinear), and that n_modes (if given) is not below the number of modes in the band."
        )
    return refined, rel
