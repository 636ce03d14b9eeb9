"""What ``bayes-update calibrate`` writes for the beam: the paper's tables (CSV), the
grids, figures (PNG), calibration.json and report.txt."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from bayes_update.data.dataset import Dataset
from bayes_update.models.beam.calibrate import CalibrationResult, format_tables
from bayes_update.reports import plots


def _write_csv(path: Path, rows: list, columns: list) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow(
                [
                    ("" if r.get(c) is None else (f"{r[c]:.6g}" if isinstance(r.get(c), float) else r.get(c)))
                    for c in columns
                ]
            )


def write_result(result: CalibrationResult, dataset: Dataset, out) -> Path:
    """Write tables (CSV), figures (PNG), calibration.json and report.txt to ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    pcols = ["c_N_s_per_mm", "F_N", "k_s_N_per_mm", "P_eff_N", "eta_MPa_s"]
    _write_csv(out / "table1_linear.csv", result.table1, pcols + ["e_lin"])
    _write_csv(out / "table2_nonlinear.csv", result.table2, pcols + ["e_lin_nlin", "e_lin", "e_nlin"])
    _write_csv(out / "table3_final.csv", [result.table3], list(result.table3))
    _write_csv(out / "grid_linear.csv", result.linear_grid, pcols + ["e_lin", "error"])
    _write_csv(out / "grid_nonlinear.csv", result.nonlinear_grid, pcols + ["e_lin", "e_nlin", "e_lin_nlin", "error"])
    _write_csv(out / "eta_scan.csv", result.eta_scan, ["eta_MPa_s", "e_lin"])
    _write_csv(out / "refinement.csv", result.refinement, pcols + ["e_lin", "e_nlin", "e_lin_nlin"])
    (out / "calibration.json").write_text(json.dumps(result.calibration_json(), indent=2) + "\n")
    (out / "report.txt").write_text(format_tables(result) + "\n")
    figs = plots.calibration_figures(result, dataset)
    for name, fig in figs.items():
        fig.savefig(out / f"{name}.png", dpi=110)
    return out
