"""Poles of every mode a record shows in the band it excites, and none outside it: :func:`estimate_modes`.

1. The FRF lines and their variance (:mod:`volterra.lines`): period-synchronous
   spectra when the input repeats (the period declared, or found in the input
   by :func:`volterra.find_periods`), the local polynomial method's FRF for a
   rough (random) input, the whole record's Y / U otherwise (its transient
   fitted in 3); each record's mean removed.  Lines outside the band
   (``f_range``, default the excited band, no wider than the coherent lines)
   or incoherent are left out.  Each line is weighted by the inverse sd of its
   estimate (the output noise a running median over 31 lines: a robust
   level, never one line's chance value).
2. Candidates: LSCF fits of all sensors with a common denominator over
   orders 2..``max_order``, in windows of two octaves when the band is wider
   (:func:`volterra.lscf.subband_clusters`), read as stabilisation diagrams;
   a cluster stable at 30 % of its window's orders is a candidate, one stable
   at 3 orders or more a weak one.  A candidate whose half-power band is not
   inside the band (two lines to spare, and one line inside it) cannot be
   told from a mode outside it: it is a *pseudo* pole, fitted and never
   reported, as are the stable clusters just outside the band and a broad
   pole pair beyond each edge (refined there, never entering the band).
3. The modal fit (:mod:`volterra.lsfd`): modes, pseudo poles, residual terms
   for the modes outside the band, and the transient of a record that does not
   start or end at rest.
4. Selection (:mod:`volterra.selection`): each mode's significance is the rise
   of the weighted residual's chi-square when it is left out.  The least
   significant mode is dropped while it is below ``min_significance`` (25, and
   5 per real unknown it adds) times the residual's local level around it
   (at least 1) times the lines neighbouring estimates share (the LPM's
   window): a mode whose energy is small but whose peak stands clear of the
   noise is kept; a pole that only models noise, or the tail of a mode
   outside the band, is not.  ``n_modes`` keeps that many, those with the most
   response energy (topped up by the less stable clusters).
5. ``refine``: the poles that minimise the weighted residual of the fit, all
   sensors jointly (variable projection), each in a box around its start,
   re-centred where a pole ends on it; a mode whose half-power band leaves
   the band or whose damping reaches ``max_damping`` becomes a pseudo pole,
   one that does not settle is dropped; then the selection again, and of two
   overlapping modes of one shape the weaker is dropped (:func:`volterra.selection.overlapped`).  A mode the
   LSCF did not stabilise (weak beside strong ones) leaves a peak in the
   fit's residual: up to 8 such starts are tried, each kept only if it
   survives the selection.

Modes come back sorted by their response energy, the largest first.  What
cannot be trusted raises :class:`PoleEstimationError`, saying what to check.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from . import lsfd
from ._validation import as_record_list
from .kautz import KautzPole
from .lines import record_lines
from .lscf import DEFAULT_MAX_DAMPING, subband_clusters
from .selection import (
    MIN_SIGNIFICANCE,
    PoleEstimationError,
    energies,
    fit_lines,
    inside,
    overlapped,
    peak_mode,
    refine_modes,
    relative_residual,
    residual_peak,
    select,
    weights,
)

# PoleEstimationError is defined in volterra.selection (and exported by the package): listed once
__all__ = ["ModalEstimate", "estimate_modes"]

#: Default lowest coherence of the lines the poles are fitted on (on one sensor at least).
MIN_COHERENCE = 0.5
#: Default highest LSCF model order (number of poles, conjugates included).
MAX_LSCF_ORDER = 40
#: Default largest relative residual of the refined fit (certainty weighted, per sensor).
MAX_RESIDUAL = 0.5
#: starts tried from peaks of the residual, at most, and in a row without a mode (four: a band
#: read wider than the excitation, its coherent skirt below, puts its own residual peaks first;
#: with two, a clear 23.8 Hz mode of a random record behind two such was never tried)
MAX_TRIED, MAX_FAILED = 8, 4
#: a cluster stable at fewer orders than 30 % of its window's, but at this many, is a weak candidate
MIN_STABLE = 3
#: the pseudo pole pairs beyond the band's edges: a factor PSEUDO_STEP outside, damping PSEUDO_ZETA
PSEUDO_STEP, PSEUDO_ZETA = 1.05, 0.03


#: lines x sensors up to which a random record's modes narrower than the LPM's window are
#: fitted on the whole record's lines (Lines.whole_record): that fit's transient terms make
#: it slow on long records (131 072 samples, 3 sensors: over 5 minutes where the LPM's lines
#: take 77 s), whose modes are rarely that narrow in lines
MAX_WHOLE_LINES = 16384


@dataclass(frozen=True)
class ModalEstimate:
    """Result of :func:`estimate_modes`.

    Attributes
    ----------
    poles : tuple of KautzPole, sorted by response energy (largest first)
    energy_shares : (M,) [-] each mode's share of the linear response energy
        (its part of the sensors' FRFs, input-power weighted, every sensor
        normalised by its own energy), same order as ``poles``
    lscf_poles : tuple of KautzPole, the selected LSCF estimates before refinement,
        by frequency
    significance : (M,) [-] the chi-square rise when each mode is left out
    pseudo : ((f Hz, zeta), ...) poles fitted for modes outside the band, not modes
    band : (f_min, f_max) [Hz] of the lines the poles were fitted on
    relative_residual : the refined fit's relative residual over the sensors, each
        line weighted by its certainty (NaN without refinement)
    method : how the lines were read (periodic, whole record, LPM)
    lines : the lines as a :class:`volterra.lsfd.FitLines`, each weighted by the square
        root of the input's power on it (what :func:`volterra.polish.polish` fits)
    f, H, coherence, variance : the lines used [Hz], H (L, n_sensors), coherence
        and the variance of each H
    diagram : [(order, freq_hz, zeta, stable)] of the stabilisation diagrams
    """

    poles: tuple
    energy_shares: np.ndarray
    lscf_poles: tuple
    significance: np.ndarray
    pseudo: tuple
    band: tuple
    relative_residual: float
    method: str
    lines: lsfd.FitLines = field(repr=False)
    f: np.ndarray = field(repr=False)
    H: np.ndarray = field(repr=False)
    coherence: np.ndarray = field(repr=False)
    variance: np.ndarray = field(repr=False)
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
            raise ValueError(
                f"y record {k} must be (n,) or (n, n_sensors) with n = len(u) = {r_u.size}, got shape {r_y.shape}"
            )
        if not np.all(np.isfinite(r_y)):
            raise ValueError(f"y record {k} contains NaN/inf values")
        out.append(r_y - r_y.mean(axis=0))
    S = {r.shape[1] for r in out}
    if len(S) != 1:
        raise ValueError(f"every record needs the same sensors, got {sorted(S)} columns")
    if not all(np.any(r != 0) for r in us):
        raise ValueError("the input u is constant: no mode can be excited")
    return [r - r.mean() for r in us], out


def _fit_data(lines, fs) -> lsfd.FitLines:
    """The lines a modal fit runs on, weighted by their estimates' variance."""
    W = weights(lines.var, lines.H, lines.u_power, lines.var_input)
    return lsfd.FitLines(lines.f, lines.H, W, fs, lines.inv_u, lines.record)


def _refined(d, modes, pseudo, band, spacing, fixed, min_significance, corr, max_damping):
    """(modes, significance, pseudo) after refinement and selection again.  A mode whose
    refined half-power band leaves the band, or whose damping reaches ``max_damping``
    (a smooth trend, the tail of modes outside the band, not a resonance), becomes a
    pseudo pole; a mode that does not settle in its box (two starts for one mode, a
    pole the data do not hold) is dropped and the others refined again.  Raises
    PoleEstimationError when no mode settles."""
    dk = d.take(fit_lines(d.f, modes, spacing))
    for _ in range(len(modes)):
        refined, pseudo_r, stuck = refine_modes(dk, modes, pseudo, band, spacing)
        if not stuck:
            break
        modes = [m for i, m in enumerate(modes) if i not in stuck]
        if not modes:
            raise PoleEstimationError(
                f"refining the poles: no mode settles (the one near {refined[stuck[0]][0]:.4g} Hz ran to the "
                "edge of its search range, re-centred three times): the record is not essentially linear, "
                "or its modes are not in it. Check f_range, offsets and slow drifts in u and y, that the "
                "record is low-level, and n_modes."
            )
    modes, pseudo = refined, pseudo_r
    good = [inside(*m, band, spacing) and m[1] < max_damping for m in modes]
    demoted = [m for m, g in zip(modes, good) if not g]
    modes = [m for m, g in zip(modes, good) if g]
    modes, sig = select(dk, modes, pseudo + demoted, fixed, min_significance, spacing, corr)
    one = None if fixed else overlapped(dk, modes, sig, pseudo + demoted)
    if one is not None:  # two modes the record cannot tell from one: the weaker is the other's misfit
        rest = modes[:one] + modes[one + 1 :]
        return _refined(d, rest, pseudo + demoted, band, spacing, fixed, min_significance, corr, max_damping)
    return modes, sig, pseudo + demoted


def _one_blas_thread(func):
    """``func`` with one BLAS thread: its fits' matrices are a few hundred rows of a few dozen
    columns, where threads only contend (the four tests of the lab records' inspection took 58 s
    with two OpenBLAS threads on 2 cores, 14 s with one; in two test workers at once, 175 s)."""

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        from threadpoolctl import threadpool_limits

        with threadpool_limits(1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper


@_one_blas_thread
def estimate_modes(
    u,
    y,
    fs: float,
    f_range=None,
    n_modes: int | None = None,
    refine: bool = True,
    period_samples: int | None = None,
    min_coherence: float = MIN_COHERENCE,
    max_damping: float = DEFAULT_MAX_DAMPING,
    max_order: int = MAX_LSCF_ORDER,
    min_significance: float = MIN_SIGNIFICANCE,
    max_residual: float = MAX_RESIDUAL,
) -> ModalEstimate:
    """Poles of every mode of the excited, coherent band of a linear record (module docstring).

    Parameters
    ----------
    u : 1-D array (input, e.g. force), or a list of records.
    y : (n,) or (n, n_sensors) response(s) to ``u`` (a list for several records).
    fs : sampling rate [Hz].
    f_range : (f_min, f_max) [Hz], optional; default the excited band.
    n_modes : int, optional: that many modes, the candidates with the most response
        energy (no significance test, no search for more).
    refine : bool: refine the poles on the modal fit (then the residual check).
    period_samples : int, optional: the excitation's period [samples]; default
        looked for in the input (:func:`volterra.find_periods`).
    min_coherence, max_damping, max_order, min_significance, max_residual : see
        the module constants (0.5, 0.3, 40, 25, 0.5).
    """
    if n_modes is not None and (not isinstance(n_modes, (int, np.integer)) or n_modes < 1):
        raise ValueError(f"n_modes must be a positive integer, got {n_modes!r}")
    us, ys = _records(u, y)
    lines = record_lines(us, ys, fs, f_range, period_samples, min_coherence)
    lo, hi = band = lines.band
    spacing = lines.spacing
    if lines.f.size < 4:
        raise PoleEstimationError(
            f"fewer than 4 frequency lines in ({lo:.4g}, {hi:.4g}) Hz have a coherence of {min_coherence:g} "
            f"or more (largest {lines.band_coherence:.3g}): the output does not follow the input there, it is "
            "noise. Check that y is the response to u (channels, units, synchronisation), the noise level, "
            "and f_range."
        )
    f, H = lines.f, lines.H
    d = _fit_data(lines, fs)
    Wd = weights(lines.detect_var, lines.detect, lines.u_power, lines.var_input)
    orders = range(2, int(max_order) + 1, 2)
    clusters, outside, diagram = subband_clusters(f, lines.detect, Wd, band, orders, max_damping)
    strong = [c for c in clusters if c[2] >= c[3]]
    pseudo = [(c[0], c[1]) for c in outside if c[2] >= c[3]]
    pseudo += [(c[0], c[1]) for c in strong if not inside(c[0], c[1], band, spacing)]
    # a broad pole pair beyond each edge of the band, refined there: the modes just outside it
    # whose tails the residual terms cannot follow (it never enters the band)
    pseudo += [(lo / PSEUDO_STEP, PSEUDO_ZETA), (hi * PSEUDO_STEP, PSEUDO_ZETA)]
    cand = [(c[0], c[1]) for c in strong if inside(c[0], c[1], band, spacing)]
    weak = sorted(
        (c for c in clusters if MIN_STABLE <= c[2] < c[3] and inside(c[0], c[1], band, spacing)), key=lambda c: -c[2]
    )
    if n_modes is None:
        # a cluster stable at few orders (a weak mode beside a strong one) is a candidate too:
        # the selection keeps it only if it stands out
        cand += [(c[0], c[1]) for c in weak]
    if n_modes is not None and len(cand) < n_modes:
        # topped up by the most stable other clusters, however few their orders; one mode: the
        # largest peak when no cluster is left (a strong nonlinearity's record blurs the diagram)
        rest = [(c[0], c[1]) for c in clusters if c[2] < c[3] and inside(c[0], c[1], band, spacing)]
        if rest:
            # the other clusters by the response energy their modes carry (their stability is poor)
            idx = fit_lines(f, cand + rest, spacing)
            parts, _, _ = lsfd.fit(d.take(idx), cand + rest, pseudo)
            shares = energies(H[idx], lines.u_power[idx], parts)[len(cand) :]
            cand += [rest[i] for i in np.argsort(-shares)[: n_modes - len(cand)]]
        peak = peak_mode(f, lines.detect) if not cand and n_modes == 1 else None
        if peak is not None and inside(*peak, band, spacing):
            cand = [peak]
        if len(cand) < n_modes:
            raise PoleEstimationError(
                f"n_modes = {n_modes}, but the stabilisation diagram holds only {len(cand)} stable "
                "pole cluster(s) in the band. Check the band (f_range), the coherence and the record length "
                "(frequency resolution), or ask for fewer modes."
            )
    elif n_modes is not None and len(cand) > n_modes:
        parts, _, _ = lsfd.fit(d.take(fit_lines(f, cand, spacing)), cand, pseudo)
        idx = fit_lines(f, cand, spacing)
        shares = energies(H[idx], lines.u_power[idx], parts)
        cand = [cand[i] for i in np.sort(np.argsort(-shares)[:n_modes])]
    if not cand:
        peak = peak_mode(f, lines.detect)
        cand = [] if peak is None or not inside(*peak, band, spacing) else [peak]
    no_mode = (
        f"no mode stands out of the noise in ({lo:.4g}, {hi:.4g}) Hz (lines read: {lines.method}, "
        f"{spacing:.3g} Hz apart): check that y is the response to u (channels, units, synchronisation), "
        "the noise level, f_range, offsets or slow drifts in u and y, and that the record is long enough: "
        f"a mode whose half-power band (2 zeta f) is narrower than the lines' spacing ({spacing:.3g} Hz) "
        "is not resolved (record more periods or a longer record)."
    )
    fixed = n_modes is not None

    def fit_on(lines, d, pseudo):
        """(modes, significance, pseudo, the LSCF's modes, relative residual) on ``lines``."""
        corr = lines.correlated
        modes, sig = select(d.take(fit_lines(f, cand, spacing)), cand, pseudo, fixed, min_significance, spacing, corr)
        lscf = list(modes)
        resid = float("nan")
        if refine and modes:
            modes, sig, pseudo = _refined(d, modes, pseudo, band, spacing, fixed, min_significance, corr, max_damping)
            tried, failed = [], 0
            while not fixed and len(tried) < MAX_TRIED and failed < MAX_FAILED:
                # a mode the LSCF did not stabilise (weak beside strong ones) leaves a peak in the fit's
                # residual; a start that does not become a mode is not tried again
                start = residual_peak(d, modes, pseudo, band, spacing, min_significance, tried, corr)
                if start is None:
                    break
                tried.append(start)
                try:
                    trial = _refined(
                        d, modes + [start], pseudo, band, spacing, fixed, min_significance, corr, max_damping
                    )
                except PoleEstimationError:
                    trial = ([],)
                if len(trial[0]) > len(modes):
                    modes, sig, pseudo = trial
                    failed = 0
                else:
                    failed += 1
        if not modes:
            raise PoleEstimationError(no_mode)
        if refine:
            resid = relative_residual(d, modes, pseudo)
            if not resid <= max_residual:
                raise PoleEstimationError(
                    f"the refined modal fit leaves {100 * resid:.3g} % of the response unexplained (more than "
                    f"{100 * max_residual:.3g} %): y does not follow u linearly. Check that y is the response to u, "
                    "the noise level, slow drifts of y, that the record is low-level (not strongly nonlinear), and "
                    "that n_modes (if given) is not below the number of modes in the band."
                )
        return modes, sig, pseudo, lscf, resid

    fitted = None
    if (
        lines.whole is not None
        and lines.H.size <= MAX_WHOLE_LINES
        and any(2 * z * fr < lines.correlated * spacing for fr, z in cand)
    ):
        # a mode narrower than the LPM's window: fitted on the whole record's lines, its transient
        # a term of the fit (Lines.whole_record); the diagram above stays the LPM's.  Where no mode
        # holds there (a two-period multisine at 1024 samples: its lines between the excited ones
        # are noise), the LPM's lines as before
        whole = lines.whole_record()
        try:
            fitted = fit_on(whole, _fit_data(whole, fs), pseudo)
            lines, H, d = whole, whole.H, _fit_data(whole, fs)
        except PoleEstimationError:
            fitted = None
    modes, sig, pseudo, lscf, resid = fitted or fit_on(lines, d, pseudo)
    parts, _, _ = lsfd.fit(d, modes, pseudo)
    shares = energies(H, lines.u_power, parts)
    order = np.argsort(-shares)
    poles = [KautzPole.from_modal(fr, ze, fs) for fr, ze in modes]
    starts = tuple(KautzPole.from_modal(fr, ze, fs) for fr, ze in sorted(lscf))
    return ModalEstimate(
        poles=tuple(poles[i] for i in order),
        energy_shares=shares[order],
        lscf_poles=starts,
        significance=np.asarray(sig)[order],
        pseudo=tuple((float(a), float(b)) for a, b in pseudo),
        band=band,
        relative_residual=resid,
        method=lines.method,
        lines=lsfd.FitLines(f, H, np.sqrt(lines.u_power)[:, None] * np.ones(H.shape[1]), fs, lines.inv_u, lines.record),
        f=f,
        H=H,
        coherence=lines.coherence,
        variance=lines.var,
        diagram=diagram,
    )
