"""What ``bayes-update calibrate`` writes for a model of the contract:
calibration.json, report.txt and a figure of the fit on every test."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from bayes_update.core.calibrate import Calibration
from bayes_update.core.numbers import format_sd, format_value

__all__ = ["fit_figure", "format_calibration", "write_calibration"]


def format_calibration(cal: Calibration) -> str:
    """A plain-text table of the calibrated values (with the digits their sd resolves,
    :mod:`bayes_update.core.numbers`), the metrics and the prediction errors.  The sd
    column is the posterior's Laplace sd (``sd``), or, where that was off or failed,
    the fit's white-noise Gauss-Newton sd (``GN sd*``, footnoted: not an interval)."""
    laplace = cal.sd_method == "laplace"
    sd_label = "sd" if laplace else "GN sd*"
    lines = [
        f"two-stage calibration, metric set {cal.metric_set!r}, J = {cal.n_functions}, {cal.n_model_runs} model runs",
        f"linear parameters (screen): {', '.join(cal.linear_parameters)}",
        f"{'parameter':>12} {'stage 1':>14} {'final':>14} {sd_label:>10}  unit",
    ]
    for name, value in cal.theta.items():
        # the digits the final value's sd resolves, in both columns
        sd = (cal.sd or {}).get(name, math.nan)
        lines.append(
            f"{name:>12} {format_value(cal.stage1[name], sd):>14} {format_value(value, sd):>14} "
            f"{format_sd(sd):>10}  {cal.units[name]}"
        )
    if laplace:
        lines.append(
            "sd: the posterior's Laplace approximation at its mode (noise replicates with the force's "
            "noise, model error, the tests' disagreement); `bayes-update sample` for the posterior itself"
        )
    else:
        lines.append(
            "GN sd*: the fit's Gauss-Newton sd under white noise of the measured level and no model "
            "error: the digits' scale, not an interval (it can be 10-100x too small)"
        )
    lines.append(", ".join(f"{k} {100 * v:.3f} %" for k, v in cal.metrics.items()))
    for test, err in cal.prediction_errors.items():
        lines.append(f"prediction error on validation test {test}: {100 * err:.3f} %")
    if not cal.prediction_errors:
        lines.append("no validation test (role 'validation'): no prediction error to report")
    for w in cal.fit_warnings:
        lines.append(f"WARNING: {w}")
    for stage, dirs in cal.unidentified.items():
        for d in dirs:
            lines.append(
                f"UNIDENTIFIED after the {stage} stage: "
                + ", ".join(f"{k} {v:+.2f}" for k, v in d["direction"].items())
                + f" (prior-range units; sd {d['sd_over_range']:.2g} of the range)"
            )
    return "\n".join(lines)


def fit_figure(cal: Calibration, sensors=None):
    """Measured and calibrated responses of every test and sensor: against time, and
    their amplitude spectra with the difference (each axis labelled with its
    quantity and unit; a spectrum's y range where the data are,
    :func:`~bayes_update.reports.plots.spectrum_limits`).
    ``sensors``: the data set's ``[(name, kind), ...]`` (default: the problem's)."""
    import matplotlib.pyplot as plt

    from bayes_update.data.dataset import RESPONSE_UNITS
    from bayes_update.reports.plots import amplitude_spectrum, response_label, spectrum_limits

    problem = cal.problem
    sensors = list(sensors or problem.sensors)
    tests = [(st, t) for st, t in problem.tests.items()] + [("validation", t) for t in problem.validation.values()]
    rows = []
    for role, t in tests:
        y_mod = problem.compared_response(problem.run(cal.theta, t.force))  # as the records: offsets removed
        measured = t.response if t.response.ndim == 2 else t.response[:, None]
        model = y_mod if y_mod.ndim == 2 else y_mod[:, None]
        for j in range(measured.shape[1]):
            name, kind = sensors[j]
            where = f", {name}" if measured.shape[1] > 1 or name != kind else ""
            rows.append((f"{t.name} ({role}){where}", name, kind, measured[:, j], model[:, j]))
    fig, axes = plt.subplots(len(rows), 2, figsize=(11, 2.8 * len(rows)), squeeze=False)
    for (title, name, kind, y, y_mod), (ax_t, ax_f) in zip(rows, axes):
        unit = RESPONSE_UNITS[kind]
        time = np.arange(y.size) / problem.fs
        ax_t.plot(time, y, lw=0.6, label="measured")
        ax_t.plot(time, y_mod, lw=0.6, alpha=0.8, label="calibrated model")
        ax_t.set_title(title, fontsize=9)
        ax_t.set_xlabel("time [s]")
        ax_t.set_ylabel(response_label(kind, name), fontsize=8)
        spectra = {}
        for z, lab in ((y, "measured"), (y_mod, "model"), (y - y_mod, "difference")):
            f, spectra[lab] = amplitude_spectrum(z, problem.fs)
            ax_f.semilogy(f, spectra[lab], lw=0.6, label=lab)
        ax_f.set_ylim(*spectrum_limits(spectra["measured"], spectra["model"]))
        ax_f.set_xlabel("frequency [Hz]")
        ax_f.set_ylabel(f"amplitude [{unit}]", fontsize=8)
        ax_f.set_xlim(0, problem.fs / 2)
    axes[0, 0].legend(fontsize=8)
    axes[0, 1].legend(fontsize=8)
    fig.tight_layout()
    return fig


def write_calibration(cal: Calibration, out, sensors=None) -> Path:
    """calibration.json, report.txt and calibration_fit.png into ``out`` (``sensors``: the
    data set's, for the figure's titles)."""
    import matplotlib.pyplot as plt

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "calibration.json").write_text(json.dumps(cal.calibration_json(), indent=2, default=float) + "\n")
    (out / "report.txt").write_text(format_calibration(cal) + "\n")
    fig = fit_figure(cal, sensors)
    fig.savefig(out / "calibration_fit.png", dpi=110)
    plt.close(fig)
    return out
