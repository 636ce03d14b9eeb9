"""The figure ``bayes-update discrepancy --model ...`` draws: where the data and the
model disagree, before and after the named effects (the generic engine's result,
:mod:`bayes_update.core.discrepancy`)."""
from __future__ import annotations

import numpy as np

from bayes_update.core.problem import excited_band

__all__ = ["gap_figure"]


def gap_figure(res):
    """Per test and sensor: amplitude spectra of the measured response and of the
    residual (measured - model) at the baseline's mode and at the final one (with
    the named effects), titled with the output errors.  Where no effect is named
    the two residuals coincide."""
    import matplotlib.pyplot as plt

    problem = res.problem
    tests = list(problem.tests.values()) + list(problem.validation.values())
    fits = {"baseline": res.baseline.theta, "with " + (" + ".join(res.named) or "nothing named"): res.final.theta}
    rows = []
    for t in tests:
        measured = t.response if t.response.ndim == 2 else t.response[:, None]
        runs = {}
        for label, theta in fits.items():
            y = problem.run(theta, t.force)
            runs[label] = y if y.ndim == 2 else y[:, None]
        for j in range(measured.shape[1]):
            rows.append((t.name if measured.shape[1] == 1 else f"{t.name}, sensor {j + 1}", measured[:, j],
                         {k: v[:, j] for k, v in runs.items()}))
    # up to the third harmonic of the highest excited frequency, where the nonlinear content is
    f_top = min(problem.fs / 2, 3 * max(excited_band(t.force, problem.fs)[1] for t in tests))
    fig, axes = plt.subplots(len(rows), 1, figsize=(8, 2.6 * len(rows)), squeeze=False)
    for (title, y, models), ax in zip(rows, axes[:, 0]):
        f = np.fft.rfftfreq(y.size, 1.0 / problem.fs)
        spectrum = np.abs(np.fft.rfft(y))
        ax.semilogy(f, spectrum + 1e-300, lw=0.7, color="0.6", label="measured")
        errors = []
        for (label, y_mod), color in zip(models.items(), ("C3", "C0")):
            r = y - y_mod
            ax.semilogy(f, np.abs(np.fft.rfft(r)) + 1e-300, lw=0.7, color=color, label=f"residual, {label}")
            errors.append(f"{label} {100 * np.linalg.norm(r) / np.linalg.norm(y):.2f} %")
        ax.set_title(f"{title}: output error " + ", ".join(errors), fontsize=9)
        ax.set_xlim(0, f_top)
        ax.set_ylim(bottom=0.1 * np.percentile(spectrum[f <= f_top], 5))
        ax.set_xlabel("frequency [Hz]")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    return fig
