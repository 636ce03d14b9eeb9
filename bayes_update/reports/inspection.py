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
  entries);
* ``distortion_<sensor>.png``: where a test repeats, its excited lines, the
  unexcited odd and even lines and their noise (:func:`plot_distortion`).

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
from volterra.sweep_distortion import SweepDistortion


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


#: how each class of lines is drawn: (marker, colour, label)
LINE_STYLE = {
    "excited": ("o", "k", "excited"),
    "odd": ("v", "C3", "odd (odd-degree distortion)"),
    "even": ("^", "C0", "even (even-degree distortion)"),
    "any": ("v", "C3", "unexcited"),
    "noise": (".", "0.6", "no distortion reaches (noise)"),
}


def read_distortions(dataset, inspection: dict) -> dict:
    """{test file: :class:`volterra.Distortion`} of the tests the inspection read (its
    ``distortion`` entry holds numbers, not the line spectra the figure draws), by level."""
    from volterra.sweep_distortion import record_distortion

    fs = float(dataset.sampling_rate_hz)
    out = {}
    for t in _by_level(dataset):
        if (inspection["tests"][t.file].get("distortion") or {}).get("sensors") is not None:
            names = [n for n, _ in t.sensors]
            out[t.file] = record_distortion(t.force, t.response, fs, t.period_samples, sensors=names)
    return out


def _sweep_harmonics(ax, d, sensor: str, test) -> None:
    """A sweep's harmonics 2 .. at ``sensor`` against the frequency swept, each in dB of the
    output at f0, over their noise (grey: the same frequency in the frames where no harmonic
    is near it)."""
    power, noise = d.harmonics[sensor], d.noise[sensor]
    for i in range(power.shape[1]):
        k = i + 2
        color, marker = ("C3", "v") if k % 2 else ("C0", "^")
        label = f"harmonic {k} ({'odd' if k % 2 else 'even'})"
        with np.errstate(divide="ignore", invalid="ignore"):
            ax.plot(d.f0, 10 * np.log10(power[:, i]), marker, color=color, ms=3, ls="none", label=label)
            ax.plot(d.f0, 10 * np.log10(noise[:, i]), ".", color="0.6", ms=2, label="their noise" if i == 0 else None)
    ax.set_xlim(float(np.min(d.f0)), float(np.max(d.f0)))
    ax.set_title(f"{test.name} ({test.level}), sweep: {d.verdict(sensor)}", fontsize=8)
    ax.set_ylabel("dB of the output at f0")
    ax.set_xlabel("frequency swept f0 [Hz]")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=3, loc="best")


def plot_distortion(dataset, sensor: str, distortions: dict):
    """The lines of every periodic test at ``sensor`` (``distortions``: :func:`read_distortions`):
    the excited lines, the unexcited odd and even lines (the linear response to the force's
    content on them taken out) and the noise of the period mean on every line (grey), in dB of
    ``sensor``'s unit (:func:`volterra.distortion`); a sweep's harmonics against the frequency
    swept (:func:`volterra.sweep_distortion`); None where no test was read."""
    tests = [t for t in _by_level(dataset) if t.file in distortions]
    if not tests:
        return None
    fig = Figure(figsize=(9, 2.6 * len(tests)), constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(len(tests), 1, squeeze=False)[:, 0])
    for ax, t in zip(axes, tests):
        d = distortions[t.file]
        if isinstance(d, SweepDistortion):
            _sweep_harmonics(ax, d, sensor, t)
            continue
        noise_f, noise_p = [], []
        for cls, f in d.lines.items():
            power, noise = d.power[sensor][cls]
            marker, color, label = LINE_STYLE[cls]
            ax.plot(f, 10 * np.log10(np.maximum(power, 1e-300)), marker, color=color, ms=3, ls="none", label=label)
            noise_f.append(f)
            noise_p.append(noise)
        order = np.argsort(np.concatenate(noise_f))
        ax.plot(
            np.concatenate(noise_f)[order],
            10 * np.log10(np.maximum(np.concatenate(noise_p)[order], 1e-300)),
            color="0.5",
            lw=0.8,
            label="noise of the period mean",
        )
        ax.set_title(f"{t.name} ({t.level}): {d.verdict(sensor)}", fontsize=8)
        ax.set_ylabel(f"dB ({dataset.units[sensor]})^2")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7, ncol=3, loc="best")
    axes[-1].set_xlabel("frequency [Hz]")
    return fig


def write_inspection(
    dataset, out, inspection: dict | None = None, noise: dict | None = None, remove_offsets: bool = True
) -> dict:
    """Write ``inspection.json`` and the figures into the folder ``out``;
    returns ``{name: path}``.  ``inspection``, ``noise``: already computed
    results of :func:`inspect_dataset` and :func:`dataset_noise` (default:
    computed here, not strict); ``remove_offsets``: how the modes are read
    (:func:`inspect_dataset`)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    noise = dataset_noise(dataset, strict=False) if noise is None else noise
    inspection = inspect_dataset(dataset, noise, remove_offsets) if inspection is None else inspection
    paths = {"inspection.json": out / "inspection.json"}
    paths["inspection.json"].write_text(json.dumps(inspection, indent=2) + "\n")
    figures = {f"frf_{name}.png": plot_frfs(dataset, name, inspection) for name, _ in dataset.sensors}
    channels = ["force"] + [name for name, _ in dataset.sensors]
    figures.update({f"noise_{ch}.png": plot_noise(dataset, ch, noise) for ch in channels})
    figures["modes.png"] = plot_modes(dataset, inspection)
    distortions = read_distortions(dataset, inspection)
    for name, _ in dataset.sensors:
        fig = plot_distortion(dataset, name, distortions)
        if fig is not None:
            figures[f"distortion_{name}.png"] = fig
    for name, fig in figures.items():
        paths[name] = out / name
        fig.savefig(paths[name], dpi=110)
    return paths
