"""The figures of a data set's inspection (the report side of ``bayes-update
inspect``; the numbers are :func:`bayes_update.data.inspect.inspect_dataset`).

:func:`write_inspection` writes into a folder:

* ``inspection.json``: the inspection dict;
* ``frf_<sensor>.png``: the H1 FRF of every test from the force to that
  sensor, overlaid by level (tests ordered by the force's rms), with the
  coherence (:func:`bayes_update.data.inspect.frf`);
* ``noise_<channel>.png``: for the force and every sensor, each test's
  spectrum against its noise spectrum as estimated
  (:func:`bayes_update.data.noise_spectrum.noise_spectrum`);
* ``modes.png``: each mode's frequency and damping ratio against the
  test's force level, in % of the linear test's (the ``level_dependence``
  entries).

Figures are built without pyplot (nothing shown, no global state).  Units:
Hz, the channels' SI units, force rms [N].
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy.signal import welch

from bayes_update.data.inspect import frf, inspect_dataset
from bayes_update.data.noise import dataset_noise
from bayes_update.data.noise_spectrum import noise_spectrum


def _by_level(dataset) -> list:
    return sorted(dataset.tests, key=lambda t: float(np.std(t.force)))


def plot_frfs(dataset, sensor: str, inspection: dict) -> Figure:
    """``|H1|`` and coherence from the force to ``sensor``, one line per test, by level."""
    fs = float(dataset.sampling_rate_hz)
    fig = Figure(figsize=(8, 6), constrained_layout=True)
    ax_m, ax_c = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [2, 1]})
    lo, hi = np.inf, 0.0
    for i, t in enumerate(_by_level(dataset)):
        band = inspection["tests"][t.file]["excited_band_hz"]
        est = frf(t, sensor, fs)
        sel = est.band(*band) & np.isfinite(est.h1)
        label = f"{t.name} ({t.level}, {np.std(t.force):.3g} N rms)"
        ax_m.semilogy(est.f[sel], np.abs(est.h1[sel]), lw=0.9, color=f"C{i}", label=label)
        ax_c.plot(est.f[sel], est.coherence[sel], lw=0.8, color=f"C{i}")
        lo, hi = min(lo, band[0]), max(hi, band[1])
    unit = dataset.units[sensor]
    ax_m.set_ylabel(f"|H1| [({unit})/N]")
    ax_m.set_title(f"FRF force -> {sensor}, every test by level")
    ax_m.legend(fontsize=7, loc="best")
    ax_m.grid(True, which="both", alpha=0.3)
    ax_c.set_ylabel("coherence [-]")
    ax_c.set_ylim(0, 1.05)
    ax_c.set_xlabel("frequency [Hz]")
    ax_c.grid(True, alpha=0.3)
    if np.isfinite(lo):
        ax_c.set_xlim(lo, hi)
    return fig


def plot_noise(dataset, channel: str, noise: dict) -> Figure:
    """Each test's spectrum of ``channel`` (solid) against its noise spectrum (dashed)."""
    fs = float(dataset.sampling_rate_hz)
    fig = Figure(figsize=(8, 4.5), constrained_layout=True)
    ax = fig.subplots()
    for i, t in enumerate(_by_level(dataset)):
        x = t.force if channel == "force" else t.channel(channel)
        f, p = welch(x, fs=fs, nperseg=min(x.size, int(4 * fs)), detrend="linear")
        ax.semilogy(f, p, lw=0.8, color=f"C{i}", label=t.name)
        est = noise[t.name][channel]
        spec = noise_spectrum(t, channel, est, fs)
        if spec is not None:
            fn, pn = spec
            if est.method == "fit_residual" and pn.size > 15:  # the LPM's per-line spectrum: smoothed
                pn = np.convolve(pn, np.ones(15) / 15, mode="same")
            ax.semilogy(
                fn, pn, lw=1.6, ls="--", color=f"C{i}", zorder=3, label=f"noise ({est.method}, sd {est.sd:.3g})"
            )
    ax.set_xlim(0, fs / 2)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(f"PSD [({dataset.units[channel]})^2/Hz]")
    ax.set_title(f"{channel}: spectra (solid) and noise as estimated (dashed)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="best", ncol=2)
    return fig


def plot_modes(dataset, inspection: dict) -> Figure:
    """Each mode's frequency and damping ratio against the tests' force rms,
    relative to the linear test's (in %: a shift of a few tenths of a percent,
    what a hardening spring gives, shows; on absolute axes it would not)."""
    level = {t.file: float(np.std(t.force)) for t in dataset.tests}
    fig = Figure(figsize=(8, 5), constrained_layout=True)
    ax_f, ax_z = fig.subplots(2, 1, sharex=True)
    for i, (mode, dep) in enumerate(zip(inspection["modes"], inspection["level_dependence"])):
        files = sorted(dep["freq_hz"], key=level.get)
        x = [level[f] for f in files]
        df = [100.0 * (dep["freq_hz"][f] / mode["freq_hz"] - 1.0) for f in files]
        dz = [100.0 * (dep["damping_ratio"][f] / mode["damping_ratio"] - 1.0) for f in files]
        ax_f.plot(
            x,
            df,
            "o-",
            color=f"C{i}",
            label=f"mode {i + 1}: {mode['freq_hz']:.4g} Hz, zeta {mode['damping_ratio']:.3g} at the linear test",
        )
        ax_z.plot(x, dz, "o-", color=f"C{i}")
        for f, xi, yi in zip(files, x, df):
            ax_f.annotate(Path(f).stem, (xi, yi), fontsize=6, xytext=(3, 3), textcoords="offset points")
    ax_f.set_ylabel("frequency change [%]")
    ax_z.set_ylabel("damping ratio change [%]")
    ax_z.set_xlabel("force rms [N]")
    ax_z.set_xscale("log")
    ax_f.set_title("level dependence of the modes (relative to the linear test)")
    for ax in (ax_f, ax_z):
        ax.grid(True, which="both", alpha=0.3)
    if inspection["modes"]:
        ax_f.legend(fontsize=7)
    return fig


def write_inspection(dataset, out, inspection: dict | None = None, noise: dict | None = None) -> dict:
    """Write ``inspection.json`` and the figures into the folder ``out``;
    returns ``{name: path}``.  ``inspection``, ``noise``: already computed
    results of :func:`inspect_dataset` and :func:`dataset_noise` (default:
    computed here, not strict)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    noise = dataset_noise(dataset, strict=False) if noise is None else noise
    inspection = inspect_dataset(dataset, noise) if inspection is None else inspection
    paths = {"inspection.json": out / "inspection.json"}
    paths["inspection.json"].write_text(json.dumps(inspection, indent=2) + "\n")
    figures = {f"frf_{name}.png": plot_frfs(dataset, name, inspection) for name, _ in dataset.sensors}
    channels = ["force"] + [name for name, _ in dataset.sensors]
    figures.update({f"noise_{ch}.png": plot_noise(dataset, ch, noise) for ch in channels})
    figures["modes.png"] = plot_modes(dataset, inspection)
    for name, fig in figures.items():
        paths[name] = out / name
        fig.savefig(paths[name], dpi=110)
    return paths
