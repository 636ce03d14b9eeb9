"""What the paper's two-stage updating returns: :class:`CalibrationResult` (every
grid, the tables, the ridge, the validation, the timing) with its
calibration.json, and :func:`format_tables`, Tables 1-3 as text.  Apart from
:mod:`bayes_update.models.beam.calibrate` (the procedure) so that a report reads a result without the
grids' machinery."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import fe
from bayes_update.core.problem import Problem
from bayes_update.models.beam.calibration_grid import CalibrationSettings


@dataclass
class CalibrationResult:
    """Everything the two stages produced (paper units in the tables)."""

    final: dict
    linear_grid: list
    eta_scan: list
    nonlinear_grid: list
    refinement: list
    table1: list
    table2: list
    table3: dict
    ridge: dict
    validation: dict
    setup: dict
    timing: dict
    settings: CalibrationSettings
    final_theta: dict = field(repr=False, default=None)  # paper units
    final_params: fe.Parameters = field(repr=False, default=None)  # the same, SI
    velocities: dict = field(repr=False, default_factory=dict)
    problem: Problem | None = field(repr=False, default=None)

    def calibration_json(self) -> dict:
        f = self.final_params
        return {
            "eta": f.eta,
            "c": f.c,
            "F": f.F,
            "k_s": f.k_s,
            "P_eff": self.final["P_eff_N"],
            "e_lin": self.final["e_lin"],
            "e_nlin": self.final["e_nlin"],
            "units": {"eta": "Pa s", "c": "N s/m", "F": "N", "k_s": "N/m", "P_eff": "N"},
            "paper_units": self.table3,
            "ridge": self.ridge,
            "validation": {k: v for k, v in self.validation.items() if not k.startswith("_")},
            "setup": self.setup,
            "timing_s": self.timing,
            "settings": asdict(self.settings),
        }


# ---------------------------------------------------------------------- output


def format_tables(result: CalibrationResult) -> str:
    """Tables 1-3 in the paper's units, as text."""
    lines = [
        "Table 1 (linear stage, low-level chirp): minimum of e_lin per c",
        f"{'c [N s/mm]':>11} {'e_lin [%]':>10} {'F [N]':>8} {'k_s [N/mm]':>11} {'P_eff [N]':>10}",
    ]
    for r in result.table1:
        lines.append(
            f"{r['c_N_s_per_mm']:11g} {100 * r['e_lin']:10.3f} {r['F_N']:8.2f} "
            f"{r['k_s_N_per_mm']:11g} {r['P_eff_N']:10.2f}"
        )
    lines += [
        "",
        f"e_lin against eta: minimum at eta = {result.table3['eta_MPa_s']:.3f} MPa s",
        "",
        "Table 2 (nonlinear stage, high-level chirp): minimum of e_lin + e_nlin per c",
        f"{'c [N s/mm]':>11} {'e_lin+nlin [%]':>15} {'F [N]':>8} {'k_s [N/mm]':>11} {'P_eff [N]':>10}",
    ]
    for r in result.table2:
        lines.append(
            f"{r['c_N_s_per_mm']:11g} {100 * r['e_lin_nlin']:15.3f} {r['F_N']:8.2f} "
            f"{r['k_s_N_per_mm']:11g} {r['P_eff_N']:10.2f}"
        )
    t = result.table3
    lines += [
        "",
        "Table 3 (final, after local refinement)",
        f"eta = {t['eta_MPa_s']:.3f} MPa s, c = {t['c_N_s_per_mm']:.2f} N s/mm, F = {t['F_N']:.2f} N, "
        f"k_s = {t['k_s_N_per_mm']:.1f} N/mm, P_eff = {t['P_eff_N']:.2f} N; "
        f"e_lin = {100 * t['e_lin']:.3f} %, e_nlin = {100 * t['e_nlin']:.2f} %",
        f"k_s along the ridge: min over P_eff of e_lin+nlin stays within "
        f"{100 * result.ridge['rise']:.0f} % of its minimum for k_s in "
        f"{result.ridge['k_s_interval_N_per_mm'][0]:.0f}..{result.ridge['k_s_interval_N_per_mm'][1]:.0f}"
        f" N/mm (c = {result.ridge['c_N_s_per_mm']:g} N s/mm)",
        "",
        "Validation",
    ]
    for name, v in result.validation.items():
        if name.startswith("_"):
            continue
        s = f"  {name:14s} velocity rel. L2 = {100 * v['rel_l2']:.2f} %"
        if "harmonics_db" in v:
            h = ", ".join(f"{k} {'n/a' if d is None else f'{d:+.2f} dB'}" for k, d in v["harmonics_db"].items())
            s += f"; PSD model - data: {h}; RMS over 1-140 Hz {v['psd_db_rms']:.2f} dB"
        lines.append(s)
    lines.append(f"\n{result.setup['n_model_runs']} model runs in {result.timing['total']:.1f} s")
    return "\n".join(lines)
