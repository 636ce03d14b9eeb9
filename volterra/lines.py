"""The FRF lines a record supports, each with the variance of its estimate.

:func:`record_lines` reads every sensor's FRF from the input to it on the
excited lines of one or several records, with no window and no leakage:

* a periodic excitation (the period declared, or found in the input by
  :func:`volterra.find_periods`): period-synchronous spectra over the periods
  every sensor has settled in (:func:`volterra.periods.steady_periods`: the
  transient first period and any period that still differs dropped),
  ``H = mean Y / mean U`` on the excited lines, its variance from the
  scatter between periods (Pintelon & Schoukens 2012, sec. 2.4:
  ``(s_Y^2 + |H|^2 s_U^2 - 2 Re(conj(H) s_YU)) / (P |U|^2)``);
* a record whose input is rough (random excitation): the local polynomial
  method's FRF and its variance (:mod:`volterra.lpm`: its local polynomials
  take the record's transient and any other leakage), and beside it the
  whole record's lines (below): a mode whose half-power band is narrower than
  the LPM's window is bent by its polynomials, and
  :func:`volterra.estimate_modes` then fits on those (:meth:`Lines.whole_record`);
* any other record (a sweep, bursts, an impact, whether or not it ends at
  rest): the whole record's ``H = Y / U``, its variance ``v / |U|^2`` with v
  the LPM's noise of Y on that line; a record that does not start or end at
  rest leaks, and the modal fit takes the transient as a term of its own
  (:mod:`volterra.lsfd`).  (The LPM cannot tell ``G U`` from the transient
  where U is smooth over its window, as a sweep's is.)

Lines with no input (a periodic record's unexcited lines), outside the band
(``f_range``, default the excited band) or incoherent on every sensor (the
running median of the best sensor's coherence over 15 lines below
``min_coherence``) are left out; without ``f_range`` the band is then that of
the coherent lines (a force sensor's coloured noise lifts the input's
spectrum below or above the excitation, not the output's coherence).  Frequencies Hz; H in output unit per input unit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import median_filter, uniform_filter1d

from .frf import excited_band
from .lpm import DEFAULT_HALF_WIDTH as LPM_HALF_WIDTH
from .lpm import local_polynomial
from .periods import PeriodLayout, find_periods, steady_periods

__all__ = ["Lines", "period_spectra", "record_lines"]

#: input lines of a periodic record count as excited above this fraction of the strongest, and
#: this power ratio above their own scatter between periods (noise on an unexcited line: about 1)
PERIODIC_LINE_LEVEL = 1e-3
PERIODIC_LINE_SNR = 100.0
#: the LPM's FRF detects the modes where the 90th percentile over the band of its variance
#: times |U|^2 over its noise is below this (a rough, random input: about 1; a sweep: 1e3-1e5)
LPM_CONDITION = 10.0
#: lines of the running median of the coherence that decides which lines the output follows
COHERENCE_LINES = 15


@dataclass(frozen=True)
class Lines:
    """Estimated FRF lines: ``f`` (L,) [Hz], ``H`` (L, S), ``var`` (L, S) the variance of
    each H, ``coherence`` (L, S) [-], ``u_power`` (L,) the input's power per line
    (DFT / sqrt(N)), ``inv_u`` (L,) 1 / U where the record's transient is to be
    fitted (0 on periodic lines), ``record`` (L,) the record of each line;
    ``detect`` and ``detect_var``: the FRF to read the stabilisation diagram on
    (the LPM's, free of the transient, for a rough input; else ``H``); ``band``
    (lo, hi) [Hz], ``spacing`` [Hz] the records' line spacing (the coarsest),
    ``method`` in words, ``layouts`` the period layout of each record (None
    where not periodic); ``n_band`` the lines in the band before the coherence
    test and ``band_coherence`` the largest coherence among them; ``correlated``
    the lines over which neighbouring estimates share their data (the LPM's
    window; 1 for period-synchronous and whole-record lines); ``whole``: where
    the LPM read a record, the whole record's (H, var, inv_u) on the same lines
    (:meth:`whole_record`), else None; ``var_input`` (L, S): the part of ``var``
    that the force's own noise gives, line by line, where ``var`` leaves it out
    (a sweep's whole-record lines, :func:`_force_noise_power`), else zeros."""

    f: np.ndarray
    H: np.ndarray
    var: np.ndarray
    coherence: np.ndarray
    u_power: np.ndarray
    inv_u: np.ndarray
    record: np.ndarray
    detect: np.ndarray
    detect_var: np.ndarray
    band: tuple
    spacing: float
    method: str
    layouts: tuple
    n_band: int = 0
    band_coherence: float = float("nan")
    correlated: int = 1
    whole: tuple | None = None
    var_input: np.ndarray | None = None

    def whole_record(self) -> "Lines":
        """The same lines read from the whole record, ``H = Y / U`` with the record's
        transient left to the modal fit (as for a sweep), in place of the LPM's: a mode
        whose half-power band is narrower than the LPM's window of 2 R + 1 lines is
        bent by its local polynomials (a linear oscillator at 3.3 lines per half-power
        band: split in two or 0.5 % off in 23 of 50 noise seeds; the whole record's
        lines, 0 of 50, within 9e-5 and 0.7 %).  Itself when there are none."""
        if self.whole is None:
            return self
        H, var, inv_u = self.whole
        return replace(
            self,
            H=H,
            var=var,
            inv_u=inv_u,
            correlated=1,
            whole=None,
            var_input=np.zeros(H.shape),
            method=self.method.replace("local polynomial method", "whole record, transient fitted"),
        )


def period_spectra(r_u, r_y, layout: PeriodLayout):
    """Spectra (DFT / sqrt(N)) of the periods every sensor of ``r_y`` ((n, S)) has settled in
    (:func:`~volterra.periods.steady_periods`): ``U`` (P, K) of the input ``r_u``, ``Y``
    (S, P, K), and the excited lines (K,) bool: an input at least
    :data:`PERIODIC_LINE_LEVEL` of the strongest line's power and :data:`PERIODIC_LINE_SNR`
    above its own scatter between periods (line 0 never; none with fewer than two periods)."""
    first, last = steady_periods(r_y, layout)
    N, P = layout.period, last - first
    a = layout.start + first * N
    U = np.fft.rfft(r_u[a : a + P * N].reshape(P, N), axis=1) / np.sqrt(N)  # (P, K)
    Y = np.fft.rfft(r_y[a : a + P * N].T.reshape(r_y.shape[1], P, N), axis=2) / np.sqrt(N)
    upow = np.abs(U.mean(axis=0)) ** 2
    if P < 2:  # no scatter to judge a line by
        return U, Y, np.zeros(upow.size, bool)
    s_u = np.sum(np.abs(U - U.mean(axis=0)) ** 2, axis=0) / (P - 1)
    excited = (upow >= PERIODIC_LINE_LEVEL * upow[1:].max()) & (upow >= PERIODIC_LINE_SNR * s_u / P)
    excited[0] = False
    return U, Y, excited


def _periodic(r_u, r_y, layout: PeriodLayout, fs):
    """Lines of the periods every sensor has settled in (:func:`period_spectra`)."""
    U, Y, excited = period_spectra(r_u, r_y, layout)
    N, P = layout.period, U.shape[0]
    Um, Ym = U.mean(axis=0), Y.mean(axis=1)
    upow = np.abs(Um) ** 2
    dU, dY = U - Um, Y - Ym[:, None, :]
    s_u = np.sum(np.abs(dU) ** 2, axis=0) / (P - 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        H = (Ym / Um).T  # (K, S)
        s_y = np.sum(np.abs(dY) ** 2, axis=1).T / (P - 1)
        s_yu = np.sum(dY * np.conj(dU)[None], axis=1).T / (P - 1)
        var = (s_y + np.abs(H) ** 2 * s_u[:, None] - 2 * np.real(np.conj(H) * s_yu)) / (P * upow[:, None])
        suy = np.sum(Y * np.conj(U)[None], axis=1).T
        coh = np.abs(suy) ** 2 / (np.sum(np.abs(U) ** 2, axis=0)[:, None] * np.sum(np.abs(Y) ** 2, axis=1).T)
    f = np.arange(N // 2 + 1) * fs / N
    e = excited
    return dict(
        f=f[e],
        H=H[e],
        var=np.maximum(var[e], 0.0),
        coh=coh[e],
        upow=upow[e],
        inv_u=np.zeros(e.sum(), complex),
        detect=H[e],
        detect_var=np.maximum(var[e], 0.0),
        spacing=fs / N,
        periods=P,
    )


def _whole(r_u, r_y, fs, lo, hi):
    """The whole record's Y / U (its transient fitted later), its variance from the LPM's
    noise of Y, and the FRF to detect modes on: the LPM's where it separates G U from
    the transient (a rough input), else the whole record's."""
    n = r_u.size
    f_all = np.fft.rfftfreq(n, 1.0 / fs)
    R = LPM_HALF_WIDTH
    k = np.flatnonzero((f_all >= lo) & (f_all <= hi))
    k = k[(k >= R) & (k <= f_all.size - R - 1)]
    lp = local_polynomial(r_u, r_y, R, lines=k)
    U = np.fft.rfft(r_u)[k] / np.sqrt(n)
    Y = np.fft.rfft(r_y, axis=0)[k] / np.sqrt(n)
    with np.errstate(divide="ignore", invalid="ignore"):
        H = Y / U[:, None]
        var = lp.noise / np.abs(U[:, None]) ** 2
        # the share of the output's power on the LPM's window that is not its noise (its local fit
        # explains some of any output by chance: 1 - its residual's variance per degree of
        # freedom over the output's mean power, not the share its fit explains)
        power = uniform_filter1d(np.abs(Y) ** 2, 2 * R + 1, axis=0, mode="nearest")
        coh = np.clip(1.0 - lp.noise / power, 0.0, 1.0)
        # the LPM's G is free of the transient where its local fit is well conditioned: its
        # variance then is ~ its noise / |U|^2; a smooth input (a sweep) makes G U and the
        # transient indistinguishable over the window and the ratio huge on most lines
        cond = lp.var_g * lp.u_power[:, None] / lp.noise
    rough = k.size > 0 and float(np.nanpercentile(cond, 90)) < LPM_CONDITION
    if rough:
        # the LPM's FRF, its transient (and any other leakage) taken by its local polynomials; the
        # whole record's lines kept beside it for modes narrower than its window (Lines.whole_record)
        return dict(
            f=f_all[k],
            H=lp.G,
            var=lp.var_g,
            coh=coh,
            upow=lp.u_power,
            inv_u=np.zeros(k.size, complex),
            detect=lp.G,
            detect_var=lp.var_g,
            spacing=fs / n,
            rough=True,
            H_whole=H,
            var_whole=var,
            inv_u_whole=1.0 / U,
            var_input=np.zeros(H.shape),
        )
    # the local polynomials of a smooth input take G U into the transient: their noise of Y leaves out
    # the force noise's response G N_u, largest at a strong mode's peak (on a plate swept with 30 dB of
    # force noise the weighted residual of the true modes was 18x its level there, and "modes" came
    # out of it); it is added line by line from the force's own noise, read above the band
    with np.errstate(divide="ignore", invalid="ignore"):
        var_input = np.abs(H) ** 2 * _force_noise_power(r_u, fs) / np.abs(U[:, None]) ** 2
    return dict(
        f=f_all[k],
        H=H,
        var=var + var_input,
        coh=coh,
        upow=lp.u_power,
        inv_u=1.0 / U,
        detect=H,
        detect_var=var + var_input,
        spacing=fs / n,
        rough=False,
        var_input=var_input,
    )


#: the force's noise is read on lines from this factor times the top of its excited band to 0.45 fs ...
QUIET_FROM = 1.5
#: ... where at least this many lines lie there (else it is taken as zero, as before)
QUIET_LINES = 64


def _force_noise_power(r_u, fs) -> float:
    """The force's noise power per line (DFT / sqrt(N)) where its spectrum above the excited band
    (from :data:`QUIET_FROM` times its top to 0.45 fs) holds it: the median of ``|U|^2`` there over
    ln 2 (a white noise line's power is exponential); 0 where that band holds fewer than
    :data:`QUIET_LINES` lines."""
    f = np.fft.rfftfreq(r_u.size, 1.0 / fs)
    quiet = (f >= QUIET_FROM * excited_band(r_u, fs)[1]) & (f <= 0.45 * fs)
    if quiet.sum() < QUIET_LINES:
        return 0.0
    p = np.abs(np.fft.rfft(r_u)[quiet]) ** 2 / r_u.size
    return float(np.median(p) / np.log(2.0))


def record_lines(us, ys, fs: float, f_range=None, period_samples=None, min_coherence: float = 0.5) -> Lines:
    """The FRF lines of centred records ``us`` (1-D) and ``ys`` ((n, S)); see the module docstring.

    ``period_samples``: the period [samples] when known; None looks for one in each
    record's input.  A declared period the input does not confirm is not used
    (the record is read as not periodic, and ``method`` says so)."""
    layouts, notes = [], []
    for r_u in us:
        lay = find_periods(r_u, period_samples)
        if isinstance(lay, str) and period_samples is not None:
            notes.append(f"the declared period was not used: {lay}")
        layouts.append(lay if isinstance(lay, PeriodLayout) else None)
    periodic = all(lay is not None for lay in layouts)
    if periodic and len({lay.period for lay in layouts}) > 1:
        periodic = False
        notes.append("the records repeat with different periods: read as not periodic")
    if periodic:
        parts = [_periodic(r_u, r_y, lay, fs) for r_u, r_y, lay in zip(us, ys, layouts)]
        method = (
            f"periodic: {min(p['periods'] for p in parts)}+ steady periods of {layouts[0].period} samples"
            f"{' (declared)' if layouts[0].declared else ' (found in the input)'}"
        )
        f_all = np.concatenate([p["f"] for p in parts])
        if f_all.size == 0:
            raise ValueError("the periodic input excites no line 20 dB above its own noise")
        lo, hi = (f_all.min(), f_all.max()) if f_range is None else map(float, f_range)
        correlated = 1
    else:
        lo, hi = excited_band(us, fs) if f_range is None else map(float, f_range)
        parts = [_whole(r_u, r_y, fs, lo, hi) for r_u, r_y in zip(us, ys)]
        rough = [p["rough"] for p in parts]
        method = (
            "local polynomial method"
            if all(rough)
            else "whole record, transient fitted"
            if not any(rough)
            else "local polynomial method / whole record, transient fitted"
        )
        correlated = 2 * LPM_HALF_WIDTH + 1 if any(rough) else 1
    if f_range is not None and not lo < hi:
        raise ValueError(f"f_range must be (f_min, f_max) with f_min < f_max, got {f_range!r}")
    cat = {
        key: np.concatenate([p[key] for p in parts])
        for key in ("f", "H", "var", "coh", "upow", "inv_u", "detect", "detect_var")
    }
    cat["record"] = np.concatenate([np.full(p["f"].size, j) for j, p in enumerate(parts)])
    cat["var_input"] = np.concatenate([p.get("var_input", np.zeros(p["H"].shape)) for p in parts])
    for key in ("H", "var", "inv_u"):
        cat[key + "_whole"] = np.concatenate([p.get(key + "_whole", p[key]) for p in parts])
    spacing = max(p["spacing"] for p in parts)
    order = np.argsort(cat["f"], kind="stable")
    cat = {key: v[order] for key, v in cat.items()}
    f, H, coh = cat["f"], cat["H"], cat["coh"]
    keep = (f >= lo) & (f <= hi) & (f > 0) & np.all(np.isfinite(H), axis=1)
    if keep.sum() < 4:
        raise ValueError(
            f"the band ({lo:.4g}, {hi:.4g}) Hz holds fewer than 4 frequency lines "
            f"(spacing {spacing:.3g} Hz); widen it or give a longer record"
        )
    # a line counts when the output follows the input around it, not by one line's chance
    # coherence: the running median of the sensors' best over COHERENCE_LINES lines
    best = np.nan_to_num(coh).max(axis=1)
    smooth = np.zeros_like(best)
    smooth[keep] = median_filter(best[keep], size=min(COHERENCE_LINES, int(keep.sum())) | 1, mode="nearest")
    good = keep & (smooth >= min_coherence)
    if f_range is None and good.sum() >= 4:
        # the band the data excite: no wider than the coherent lines (an input sensor's coloured
        # noise lifts its spectrum beside the excitation, not the output's coherence with it)
        lo, hi = max(lo, float(f[good].min())), min(hi, float(f[good].max()))
    note = f"; {'; '.join(notes)}" if notes else ""
    g = {key: v[good] for key, v in cat.items()}
    whole = (g["H_whole"], g["var_whole"], g["inv_u_whole"]) if correlated > 1 else None
    return Lines(
        g["f"],
        g["H"],
        g["var"],
        g["coh"],
        g["upow"],
        g["inv_u"],
        g["record"],
        g["detect"],
        g["detect_var"],
        (float(lo), float(hi)),
        spacing,
        method + note,
        tuple(layouts),
        int(keep.sum()),
        float(np.nan_to_num(coh[keep]).max()),
        correlated,
        whole,
        g["var_input"],
    )
