"""Figures shared by the commands (matplotlib; each returns a ``Figure`` built
without pyplot, so nothing is shown and no global state is touched).

Templates from the paper: :func:`plot_test` (force and velocity against time,
Fig. 3, 5, 9, 10, 13), :func:`plot_frf` (H1 FRF and coherence, Fig. 7, 11),
:func:`plot_psd` (PSD comparison, Fig. 14).  Units: s, N, m/s, Hz.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

#: a spectrum's axis reaches down to this fraction of the measured spectrum's 99th percentile
SPECTRUM_DEPTH = 1e-4


def amplitude_spectrum(y, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """(f [Hz], amplitude per frequency line, in y's unit): ``2 |FFT(y)| / n``,
    a sine of amplitude A on a line shows as A."""
    y = np.asarray(y, float)
    return np.fft.rfftfreq(y.size, 1.0 / fs), 2.0 * np.abs(np.fft.rfft(y)) / y.size


def spectrum_limits(measured, *others) -> tuple[float, float]:
    """y range of a log spectrum axis where the data are: from :data:`SPECTRUM_DEPTH`
    x the measured spectrum's 99th percentile to twice the highest line of any."""
    measured = np.asarray(measured, float)
    top = max(float(np.max(measured)), *(float(np.max(o)) for o in others)) if others else float(np.max(measured))
    p99 = float(np.percentile(measured, 99))
    bottom = SPECTRUM_DEPTH * p99 if p99 > 0 else (SPECTRUM_DEPTH * top if top > 0 else 1e-300)
    return bottom, 2.0 * max(top, bottom)


def response_label(kind: str, name: str | None = None) -> str:
    """``displacement [m]`` (``tip (acceleration) [m/s^2]`` with a sensor name that is not its kind)."""
    from bayes_update.data.dataset import RESPONSE_UNITS

    unit = RESPONSE_UNITS.get(kind, "")
    what = kind if not name or name == kind else f"{name} ({kind})"
    return f"{what} [{unit}]" if unit else what


def plot_test(test, simulated=None, title: str | None = None):
    """Force and velocity of one test; the simulated velocity overlaid if given."""
    fig = Figure(figsize=(8, 5), constrained_layout=True)
    ax_f, ax_v = fig.subplots(2, 1, sharex=True)
    ax_f.plot(test.time, test.force, lw=0.7, color="C0")
    ax_f.set_ylabel("force [N]")
    ax_v.plot(test.time, test.velocity, lw=0.7, color="C1", label="data")
    if simulated is not None:
        ax_v.plot(test.time, simulated, lw=0.7, color="C2", label="model")
        ax_v.legend(loc="upper right")
    ax_v.set_ylabel("velocity [m/s]")
    ax_v.set_xlabel("time [s]")
    ax_f.set_title(title or test.name)
    return fig


def plot_frf(estimates: dict, f_range=(15.0, 60.0), reference=None, title: str | None = None):
    """H1 FRF magnitude and phase and the coherence (the paper's Fig. 7 and 11).

    ``estimates``: ``{label: spectral.FRFEstimate}`` (e.g. data and model, or
    the three chirp levels); ``reference``: optional ``(label, f [Hz], H)``
    drawn as a dashed line (e.g. the FE model's linear FRF).  FRF unit:
    (m/s)/N.
    """
    fig = Figure(figsize=(8, 7), constrained_layout=True)
    ax_m, ax_p, ax_c = fig.subplots(3, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1, 1]})
    for i, (label, est) in enumerate(estimates.items()):
        sel = est.band(*f_range)
        color = f"C{i}"
        ax_m.semilogy(est.f[sel], abs(est.h1[sel]), lw=1.0, color=color, label=label)
        ax_p.plot(est.f[sel], np.degrees(np.angle(est.h1[sel])), lw=1.0, color=color)
        ax_c.plot(est.f[sel], est.coherence[sel], lw=1.0, color=color)
    if reference is not None:
        label, f, h = reference
        f = np.asarray(f)
        sel = (f >= f_range[0]) & (f <= f_range[1])
        ax_m.semilogy(f[sel], abs(np.asarray(h)[sel]), "k--", lw=0.9, label=label)
        ax_p.plot(f[sel], np.degrees(np.angle(np.asarray(h)[sel])), "k--", lw=0.9)
    ax_m.set_ylabel("|H1| [(m/s)/N]")
    ax_m.legend(loc="upper right", fontsize=8)
    ax_m.grid(True, which="both", alpha=0.3)
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_ylim(-190, 190)
    ax_p.set_yticks([-180, -90, 0, 90, 180])
    ax_p.grid(True, alpha=0.3)
    ax_c.set_ylabel("coherence [-]")
    ax_c.set_ylim(0, 1.05)
    ax_c.grid(True, alpha=0.3)
    ax_c.set_xlabel("frequency [Hz]")
    ax_c.set_xlim(*f_range)
    first = next(iter(estimates.values()), None)
    if first is not None:
        ax_c.set_title(first.method, fontsize=7, loc="left")
    ax_m.set_title(title or "H1 FRF and coherence")
    return fig


def plot_psd(
    spectra: dict,
    f_max: float = 140.0,
    harmonics_of: float | None = None,
    ylabel: str = "velocity PSD [(m/s)^2/Hz]",
    title: str | None = None,
):
    """PSD comparison (the paper's Fig. 14, 0-140 Hz).

    ``spectra``: ``{label: (f [Hz], P)}``; ``harmonics_of``: mark multiples
    of this frequency [Hz] (e.g. the 35 Hz excitation).
    """
    fig = Figure(figsize=(8, 4), constrained_layout=True)
    ax = fig.subplots()
    for i, (label, (f, p)) in enumerate(spectra.items()):
        f = np.asarray(f)
        sel = f <= f_max
        ax.semilogy(f[sel], np.asarray(p)[sel], lw=0.9, color=f"C{i}", label=label)
    if harmonics_of:
        for k in range(1, int(f_max // harmonics_of) + 1):
            ax.axvline(k * harmonics_of, color="0.6", lw=0.6, ls=":")
    ax.set_xlim(0, f_max)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(title or "power spectral density")
    return fig


# ------------------------------------------------------------------ calibration
def _grid_panels(rows, key, c_values, label, best_rows, title):
    """One panel per c: the metric over (F, k_s) on the (P_eff, k_s) grid."""
    n = len(c_values)
    ncol = min(3, n)
    nrow = int(np.ceil(n / ncol))
    fig = Figure(figsize=(4.2 * ncol, 3.4 * nrow), constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(nrow, ncol, squeeze=False)).ravel()
    vals = np.array([r[key] for r in rows], float)
    finite = vals[np.isfinite(vals)]
    vmin, vmax = np.log10(finite.min()), np.log10(np.percentile(finite, 95))
    for ax, c, best in zip(axes, c_values, best_rows):
        sub = [r for r in rows if r["c_N_s_per_mm"] == c]
        # P_eff is recomputed from (F, k_s): round so one grid column is one value
        ks = sorted({round(r["k_s_N_per_mm"], 6) for r in sub})
        ps = sorted({round(r["P_eff_N"], 6) for r in sub})
        F = np.full((len(ks), len(ps)), np.nan)
        Z = np.full_like(F, np.nan)
        for r in sub:
            i, j = ks.index(round(r["k_s_N_per_mm"], 6)), ps.index(round(r["P_eff_N"], 6))
            F[i, j], Z[i, j] = r["F_N"], np.log10(r[key])
        K = np.repeat(np.array(ks)[:, None], len(ps), axis=1)
        m = ax.pcolormesh(F, K, Z, shading="nearest", cmap="viridis_r", vmin=vmin, vmax=vmax)
        ax.plot(best["F_N"], best["k_s_N_per_mm"], "r*", ms=10)
        ax.set_ylim(bottom=max(ax.get_ylim()[0], 0.0))
        ax.set_title(f"c = {c:g} N s/mm: min {100 * best[key]:.2f} %", fontsize="medium")
        ax.set_xlabel("F [N]")
        ax.set_ylabel("k_s [N/mm]")
    for ax in axes[n:]:
        ax.set_visible(False)
    fig.colorbar(m, ax=axes[:n].tolist(), label=f"log10 {label}")
    fig.suptitle(title)
    return fig


def calibration_figures(result, dataset) -> dict:
    """The paper's figures for a calibration (Fig. 4, 8, 12, 13, 14 analogues),
    plus the k_s profile along the ridge.  Returns {name: Figure}."""
    from bayes_update.data.spectral import psd

    figs = {}
    c_values = result.settings.c_values
    figs["fig4_e_lin_grid"] = _grid_panels(
        result.linear_grid,
        "e_lin",
        c_values,
        "e_lin",
        result.table1,
        f"e_lin over (F, k_s), low-level chirp, eta = {result.setup['eta_pre_scan_MPa_s']:.2f} MPa s (Fig. 4)",
    )
    figs["table2_e_lin_nlin_grid"] = _grid_panels(
        result.nonlinear_grid,
        "e_lin_nlin",
        c_values,
        "(e_lin + e_nlin)",
        result.table2,
        f"e_lin + e_nlin over (F, k_s), eta = {result.table3['eta_MPa_s']:.2f} MPa s (Table 2)",
    )

    fig = Figure(figsize=(6, 4), constrained_layout=True)
    ax = fig.subplots()
    ax.plot([r["eta_MPa_s"] for r in result.eta_scan], [100 * r["e_lin"] for r in result.eta_scan], "o-")
    ax.axvline(result.table3["eta_MPa_s"], color="r", ls="--", label=f"estimate {result.table3['eta_MPa_s']:.2f} MPa s")
    ax.set_xlabel("eta [MPa s]")
    ax.set_ylabel("e_lin [%]")
    ax.set_title("e_lin against the material viscosity (Fig. 8)")
    ax.legend()
    ax.grid(True, alpha=0.3)
    figs["fig8_e_lin_eta"] = fig

    fig = Figure(figsize=(6, 4), constrained_layout=True)
    ax = fig.subplots()
    r = result.ridge
    ax.plot(r["k_s_N_per_mm"], [100 * v for v in r["min_e_lin_nlin"]], "o-")
    ax.axvline(result.table3["k_s_N_per_mm"], color="r", ls="--", label="estimate")
    ax.set_xlabel("k_s [N/mm] (F following the ridge)")
    ax.set_ylabel("min over P_eff of e_lin + e_nlin [%]")
    ax.set_title(f"How well the high level pins k_s (c = {r['c_N_s_per_mm']:g} N s/mm)")
    ax.legend()
    ax.grid(True, alpha=0.3)
    figs["ridge_k_s_profile"] = fig

    prob = result.problem
    if prob is not None and "nonlinear" in prob.tests:
        test = prob.tests["nonlinear"]
        ref = prob.reference_components("nonlinear")
        mod = prob.components("nonlinear", result.velocities[test.name])
        t = np.arange(test.force.size) / prob.fs
        fig = Figure(figsize=(8, 5.5), constrained_layout=True)
        axes = fig.subplots(2, 1, sharex=True)
        for ax, (lab, a, b) in zip(axes, [("y1", ref[1], mod[1]), ("y2 + y3", ref[2] + ref[3], mod[2] + mod[3])]):
            ax.plot(t, a, lw=0.7, label=f"{lab} data")
            ax.plot(t, b, lw=0.7, ls="--", label=f"{lab} model")
            ax.set_ylabel(f"{lab} [m/s]")
            ax.legend(loc="upper right", fontsize="small")
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel("time [s]")
        fig.suptitle(f"Volterra components, {test.name}, updated model (Fig. 12)")
        figs["fig12_components_high"] = fig

    val = {k: v for k, v in result.validation.items() if not k.startswith("_")}
    chirps = [dataset.test(n) for n, v in val.items() if v["signal"] != "sine"]
    for test in chirps:
        v = result.velocities[test.name]
        fig = plot_test(
            test,
            v,
            title=f"{test.name}: data and updated model, rel. L2 = {100 * val[test.name]['rel_l2']:.1f} % (Fig. 13)",
        )
        figs[f"fig13_{test.name}"] = fig
    sines = [dataset.test(n) for n, v in val.items() if v["signal"] == "sine"]
    if sines:
        fig = Figure(figsize=(8, 3 * len(sines)), constrained_layout=True)
        axes = np.atleast_1d(fig.subplots(len(sines), 1, sharex=True, squeeze=False)).ravel()
        fs = dataset.sampling_rate_hz
        for ax, test in zip(axes, sines):
            f, pd = psd(test.velocity, fs)
            _, pm = psd(result.velocities[test.name], fs)
            sel = f <= 140
            ax.semilogy(f[sel], pd[sel], lw=0.9, label="data")
            ax.semilogy(f[sel], pm[sel], lw=0.9, ls="--", label="model")
            h = val[test.name]["harmonics_db"]
            ax.set_title(
                f"{test.name}: model - data at 1x/2x/3x = "
                + ", ".join("n/a" if d is None else f"{d:+.1f} dB" for d in h.values()),
                fontsize="medium",
            )
            ax.set_ylabel("PSD [(m/s)^2/Hz]")
            ax.legend(fontsize="small")
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel("frequency [Hz]")
        figs["fig14_sine_psd"] = fig
    return figs
