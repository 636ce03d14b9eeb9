"""The modal model's diagnostics drawn (``diagnostics_before.png`` and ``diagnostics_after.png``
of the discrepancy workflow): every mode's frequency and damping in every test, record against
model, and each periodic test's distortion on its unexcited lines (:mod:`.signature`)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

__all__ = ["diagnostics_figure"]


def _shown(diagnostics: dict) -> list:
    """The modes some test shows, on either side (a residual mode, out of the band, none)."""
    pairs = zip(diagnostics["measured"], diagnostics["model"], diagnostics["mismatch"])
    return [(i, a, b, m) for i, (a, b, m) in enumerate(pairs) if a["freq_hz"] or b["freq_hz"]]


def _modes_rows(axes, diagnostics: dict) -> None:
    for col, (i, measured, model, mismatch) in enumerate(_shown(diagnostics)):
        files = list(measured["freq_hz"])
        files += [f for f in model["freq_hz"] if f not in files]
        x = np.arange(len(files))
        for side, marker, label in ((measured, "o", "record"), (model, "s", "model")):
            f = [side["freq_hz"].get(k, np.nan) for k in files]
            z = [100 * side["damping_ratio"].get(k, np.nan) for k in files]
            axes[0, col].plot(x, f, marker, ls="none", mfc="none" if label == "model" else None, label=label)
            axes[1, col].plot(x, z, marker, ls="none", mfc="none" if label == "model" else None)
        axes[0, col].set_title(f"mode {i + 1}: mismatch {mismatch:.2g}", fontsize=8)
        axes[1, col].set_xticks(x, [k.rsplit(".", 1)[0] for k in files], rotation=60, fontsize=6)
        axes[0, col].set_xticks(x, [""] * len(files))
    axes[0, 0].set_ylabel("frequency [Hz]")
    axes[1, 0].set_ylabel("damping ratio [%]")
    axes[0, 0].legend(fontsize=7)


def _distortion_row(ax, distortion: dict) -> None:
    labels, measured, model = [], [], []
    for test, sensors in distortion.items():
        for sensor, classes in sensors.items():
            for cls, r in classes.items():
                if cls == "noise":
                    continue
                labels.append(f"{test.rsplit('.', 1)[0]} {sensor} {cls}")
                measured.append(r["measured_db"] if r["measured_detected"] else np.nan)
                model.append(r["model_db"] if r["model_detected"] else np.nan)
    x = np.arange(len(labels))
    ax.plot(x, measured, "o", label="record (blank: at the noise)")
    ax.plot(x, model, "s", mfc="none", label="model")
    ax.set_xticks(x, labels, rotation=60, fontsize=6, ha="right")
    ax.set_ylabel("distortion [dB of the output]")
    ax.set_title("the periodic tests' unexcited lines and the sweeps' harmonics beyond their noise", fontsize=8)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)


def diagnostics_figure(diagnostics: dict) -> Figure:
    """Two rows of panels, one per mode some test shows (frequency, damping ratio per test,
    record and model), and below them the distortion of each periodic test and sweep, sensor and
    class of lines."""
    n = len(_shown(diagnostics))
    has_distortion = bool(diagnostics.get("distortion"))
    fig = Figure(figsize=(max(2.4 * n, 7), 6.5 + 2.8 * has_distortion), constrained_layout=True)
    grid = fig.add_gridspec(2 + has_distortion, max(n, 1))
    axes = np.array([[fig.add_subplot(grid[r, c]) for c in range(n)] for r in range(2)])
    _modes_rows(axes, diagnostics)
    if has_distortion:
        _distortion_row(fig.add_subplot(grid[2, :]), diagnostics["distortion"])
    return fig
