"""Plots of a Volterra model (matplotlib; every function returns a Figure and
never calls ``plt.show()``).  Figures are built with ``matplotlib.figure.Figure``
so they do not touch the pyplot state; save them with ``fig.savefig(...)`` or
display them in a notebook."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

__all__ = ["plot_components", "plot_h1", "plot_h2", "plot_stabilisation"]


def plot_components(
    model, u, y=None, t=None, labels=("y1", "y2", "y3"), ylabel="output", title=None, figsize=(8, 6)
) -> Figure:
    """Components y1, y2, y3 of the response to ``u`` against time (as the
    paper's Fig. 6 and 12), one panel each; ``y`` (optional) is drawn in the
    first panel for comparison.  ``t`` [s] defaults to ``k / fs``."""
    y1, y2, y3 = model.components(np.asarray(u, float))
    n = y1.size
    t = np.arange(n) / model.fs if t is None else np.asarray(t, float)
    comps = [c for c, order in zip((y1, y2, y3), (1, 2, 3)) if order in model.orders]
    names = [lab for lab, order in zip(labels, (1, 2, 3)) if order in model.orders]
    fig = Figure(figsize=figsize, constrained_layout=True)
    axes = fig.subplots(len(comps), 1, sharex=True, squeeze=False)[:, 0]
    for k, (ax, c, name) in enumerate(zip(axes, comps, names)):
        if k == 0 and y is not None:
            ax.plot(t, np.asarray(y, float), color="0.7", lw=0.8, label="y (data)")
        ax.plot(t, c, lw=0.8, label=name)
        ax.set_ylabel(f"{name} [{ylabel}]" if ylabel else name)
        ax.legend(loc="upper right", fontsize="small")
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    return fig


def plot_h1(model, f_hz=None, reference=None, reference_label="reference", title=None, figsize=(7, 5)) -> Figure:
    """Magnitude and phase of H1(f).  ``f_hz`` defaults to 0 .. fs/2;
    ``reference`` (complex array on ``f_hz``) is drawn for comparison."""
    f = np.linspace(0, model.fs / 2, 2049)[1:] if f_hz is None else np.asarray(f_hz, float)
    H = model.H1(f)
    fig = Figure(figsize=figsize, constrained_layout=True)
    ax_m, ax_p = fig.subplots(2, 1, sharex=True)
    ax_m.semilogy(f, np.abs(H), label="H1 (Volterra)")
    ax_p.plot(f, np.degrees(np.angle(H)))
    if reference is not None:
        ref = np.asarray(reference)
        ax_m.semilogy(f, np.abs(ref), "--", label=reference_label)
        ax_p.plot(f, np.degrees(np.angle(ref)), "--")
        ax_m.legend(fontsize="small")
    ax_m.set_ylabel("|H1|")
    ax_p.set_ylabel("phase [deg]")
    ax_p.set_xlabel("frequency [Hz]")
    for ax in (ax_m, ax_p):
        ax.grid(True, alpha=0.3)
    if title:
        fig.suptitle(title)
    return fig


def plot_h2(model, f_range=None, n_points: int = 161, kind: str = "surface", title=None, figsize=(7, 6)) -> Figure:
    """``|H2(f1, f2)|`` over ``f_range`` x ``f_range`` [Hz] (default: -2 .. 2 x the
    order-2 pole frequency, so that the reliable (f, -f) region is visible), as
    a 3-D surface (``kind="surface"``) or a colour map (``kind="map"``).
    Values near f1 + f2 = +-fn are not representable (see volterra.model)."""
    if 2 not in model.orders:
        raise ValueError("the model has no order-2 kernel")
    if f_range is None:
        fp = model.basis.pole(2).freq_hz
        f_range = (-min(2 * fp, model.fs / 2), min(2 * fp, model.fs / 2))
    f = np.linspace(f_range[0], f_range[1], int(n_points))
    F1, F2 = np.meshgrid(f, f, indexing="ij")
    A = np.abs(model.H2(F1, F2))
    fig = Figure(figsize=figsize, constrained_layout=True)
    if kind == "surface":
        ax = fig.add_subplot(projection="3d")
        ax.plot_surface(F1, F2, A, cmap="viridis", linewidth=0)
        ax.set_zlabel("|H2|")
    elif kind == "map":
        ax = fig.add_subplot()
        m = ax.pcolormesh(F1, F2, A, shading="auto", cmap="viridis")
        fig.colorbar(m, ax=ax, label="|H2|")
    else:
        raise ValueError(f"kind must be 'surface' or 'map', got {kind!r}")
    ax.set_xlabel("f1 [Hz]")
    ax.set_ylabel("f2 [Hz]")
    if title:
        ax.set_title(title)
    return fig


def plot_stabilisation(estimate, title=None, figsize=(8, 5)) -> Figure:
    """Stabilisation diagram of :func:`volterra.estimate_modes`: the physical
    LSCF poles per model order (stable ones filled), the chosen modes as
    vertical lines, over the sensors' ``|H1|`` [y unit / u unit] (log scale)."""
    fig = Figure(figsize=figsize, constrained_layout=True)
    ax = fig.subplots()
    for n, fr, _, ok in estimate.diagram:
        ax.plot(fr[~ok], np.full((~ok).sum(), n), "o", mfc="none", color="0.6", ms=4)
        ax.plot(fr[ok], np.full(ok.sum(), n), "o", color="C0", ms=4)
    for p in estimate.poles:
        ax.axvline(p.freq_hz, color="C3", lw=0.8)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("LSCF model order")
    ax.set_xlim(*estimate.band)
    ax2 = ax.twinx()
    ax2.semilogy(estimate.f, np.abs(estimate.H), color="0.3", lw=0.6)
    ax2.set_ylabel("|H1|")
    if title:
        fig.suptitle(title)
    return fig
