"""What ``bayes-update discrepancy`` writes: discrepancy.json, evidence.md, the gap
figure (where the data and the model disagree, before and after the named
effects) and the model's own diagnostics figures, and the text summary
(:mod:`bayes_update.core.discrepancy` finds them)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from bayes_update.core.effects import evidence_table
from bayes_update.data.quiet import excited_band

__all__ = ["format_result", "gap_figure", "write_discrepancy"]


def format_result(res) -> str:
    """The evidence table, the gap before and after, the named effects' values and
    the signature check, as text."""
    from bayes_update.core.fits import GAP_LABELS

    b, a = res.gap_before, res.gap_after
    width = max(len(v) for v in GAP_LABELS.values())
    lines = [evidence_table(res), "", f"{'gap':<{width}}    before      after"]
    for k, label in GAP_LABELS.items():
        if b.get(k) is not None:
            lines.append(f"{label:<{width}} {100 * b[k]:8.3f} %  {100 * a[k]:8.3f} %")
    for e in res.named:
        for n, v in res.final.to_json(res.effects)["effects"][e].items():
            lines.append(
                f"{e}: {n} = {v['mode']:.5g} {v['unit']} (Laplace interval "
                f"{v['interval'][0]:.5g} to {v['interval'][1]:.5g}; null {v['null']:g})"
            )
    for name, s in res.signature.items():
        if s["before"] is not None and s["after"] is not None:
            lines.append(
                f"signature of {name} ({s['signature']}): {s['before']:.4g} -> {s['after']:.4g} "
                f"({'shrank' if s['shrank'] else 'did NOT shrink'})"
            )
    lines += _harmonics_left_lines(res.diagnostics_after)
    return "\n".join(lines)


def _harmonics_left_lines(diagnostics: dict | None) -> list:
    """The distortion the record holds and the final model does not make, where the model's
    diagnostics read it (``harmonics_left``: the modal model's), a line each."""
    left = (diagnostics or {}).get("harmonics_left")
    if not left:
        return [] if left is None else ["harmonics: the final model makes every class of distortion the records hold"]
    return [
        f"harmonics left: {r['test']} {r['sensor']} {r['class']}: record {r['measured_db']:.1f} dB of the output, "
        + ("model at its noise" if r["model_db"] is None else f"model {r['model_db']:.1f} dB")
        for r in left
    ]


def write_discrepancy(res, out, truth: dict | None = None, figures: bool = True) -> dict:
    """Write discrepancy.json, evidence.md and the figures (gap_before_after.png;
    diagnostics_before/after.png where the model draws its own diagnostics) to
    folder ``out``; returns the JSON document."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    doc = res.to_json()
    if res.diagnostics_after is not None and "harmonics_left" in res.diagnostics_after:
        doc["harmonics_left"] = res.diagnostics_after["harmonics_left"]
    if truth is not None:
        doc["truth"] = truth
    (out / "discrepancy.json").write_text(json.dumps(doc, indent=1, default=_json_default))
    (out / "evidence.md").write_text(evidence_table(res) + "\n")
    if figures:
        import matplotlib.pyplot as plt

        fig = gap_figure(res)
        fig.savefig(out / "gap_before_after.png", dpi=110)
        plt.close(fig)
        draw = getattr(res.problem.model, "diagnostics_figure", None)
        if callable(draw) and res.diagnostics_before is not None:
            draw(res.diagnostics_before).savefig(out / "diagnostics_before.png", dpi=100)
            if res.named:
                draw(res.diagnostics_after).savefig(out / "diagnostics_after.png", dpi=100)
    return doc


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return str(o)


def gap_figure(res):
    """Per test and sensor: amplitude spectra of the measured response and of the
    residual (measured - model) at the baseline's mode and at the final one (with
    the named effects), titled with the output errors, in the sensor's unit.
    Where no effect is named the two residuals coincide."""
    import matplotlib.pyplot as plt

    from bayes_update.data.dataset import RESPONSE_UNITS
    from bayes_update.reports.plots import amplitude_spectrum

    problem = res.problem
    sensors = list(problem.sensors)
    tests = list(problem.tests.values()) + list(problem.validation.values())
    fits = {"baseline": res.baseline.theta, "with " + (" + ".join(res.named) or "nothing named"): res.final.theta}
    rows = []
    for t in tests:
        measured = t.response if t.response.ndim == 2 else t.response[:, None]
        runs = {}
        for label, theta in fits.items():
            y = problem.compared_response(problem.run(theta, t.force))  # as prediction_errors compares it
            runs[label] = y if y.ndim == 2 else y[:, None]
        for j in range(measured.shape[1]):
            name, kind = sensors[j]
            rows.append(
                (
                    t.name if measured.shape[1] == 1 else f"{t.name}, {name}",
                    kind,
                    measured[:, j],
                    {k: v[:, j] for k, v in runs.items()},
                )
            )
    # up to the third harmonic of the highest excited frequency, where the nonlinear content is
    f_top = min(problem.fs / 2, 3 * max(excited_band(t.force, problem.fs)[1] for t in tests))
    fig, axes = plt.subplots(len(rows), 1, figsize=(8, 2.8 * len(rows)), squeeze=False)
    for (title, kind, y, models), ax in zip(rows, axes[:, 0]):
        f, spectrum = amplitude_spectrum(y, problem.fs)
        ax.semilogy(f, spectrum + 1e-300, lw=0.7, color="0.6", label=f"measured {kind}")
        errors = []
        for (label, y_mod), color in zip(models.items(), ("C3", "C0")):
            r = y - y_mod
            ax.semilogy(
                f, amplitude_spectrum(r, problem.fs)[1] + 1e-300, lw=0.7, color=color, label=f"residual, {label}"
            )
            errors.append(f"{label} {100 * np.linalg.norm(r) / np.linalg.norm(y):.2f} %")
        ax.set_title(f"{title}: output error " + ", ".join(errors), fontsize=9)
        ax.set_xlim(0, f_top)
        ax.set_ylim(bottom=0.1 * np.percentile(spectrum[f <= f_top], 5))
        ax.set_xlabel("frequency [Hz]")
        ax.set_ylabel(f"{kind} amplitude [{RESPONSE_UNITS[kind]}]", fontsize=8)
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    return fig
