"""Figures shared by the commands (matplotlib; each returns a ``Figure`` built
without pyplot, so nothing is shown and no global state is touched).

Templates from the paper: :func:`plot_test` (force and velocity against time,
Fig. 3, 5, 9, 10, 13), :func:`plot_frf` (H1 FRF and coherence, Fig. 7, 11),
:func:`plot_psd` (PSD comparison, Fig. 14).  Units: s, N, m/s, Hz.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure


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


def plot_psd(spectra: dict, f_max: float = 140.0, harmonics_of: float | None = None,
             ylabel: str = "velocity PSD [(m/s)^2/Hz]", title: str | None = None):
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
