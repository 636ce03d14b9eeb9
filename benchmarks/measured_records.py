"""Measured records: a first look (``inspect``), then ``calibrate`` against a
direct output-error fit of the same model, on laboratory-like records.

The records and the user's model are those of the acceptance tests
(``tests/lab_records.py``: a 3-DOF chain with a cubic ground spring, three
accelerometers 10x apart in noise, coloured noise on the force, offsets,
drifts, quiet sections, sampled at 2.5x the band's top; ``LabChain`` in
``tests/test_measured_records.py``: the same chain written independently,
RK4 at 8 steps per sample on the recorded force).  Two data sets: the
model's physics, and records with a quadratic damper the model lacks.

Writes ``docs/measured_records/`` (the inspection figures of the first data
set) and ``benchmarks/results/measured_records.json`` (every number of
docs/measured_records.md), and prints a summary.

    python benchmarks/measured_records.py
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent / "tests")]

import test_measured_records as acceptance  # noqa: E402
from _machine import machine  # noqa: E402

from bayes_update.data.inspect import inspect_dataset  # noqa: E402
from bayes_update.reports.inspection import write_inspection  # noqa: E402

FIGURES = HERE.parent / "docs" / "measured_records"
RESULTS = HERE / "results" / "measured_records.json"
SHOWN = ("frf_acc1.png", "modes.png", "noise_acc3.png")  # of the inspection's figures, those the docs show


def main() -> None:
    results = {"machine": machine(), "date": time.strftime("%Y-%m-%d")}
    with tempfile.TemporaryDirectory() as tmp:
        for label, options in (("exact", {}), ("damper", {"quadratic_damping": acceptance.QUADRATIC_DAMPER})):
            records = acceptance.lab_tests(**options)
            data = acceptance.read_back(records, Path(tmp) / label)
            if label == "exact":
                t0 = time.perf_counter()
                inspection = inspect_dataset(data)
                out = Path(tmp) / "inspect"
                write_inspection(data, out, inspection)
                FIGURES.mkdir(parents=True, exist_ok=True)
                for png in SHOWN:
                    shutil.copy(out / png, FIGURES / png)
                results["inspect_s"] = time.perf_counter() - t0
                results["modes_hz"] = [m["freq_hz"] for m in inspection["modes"]]
                results["modes_true_hz"] = [float(f) for f in acceptance.lab.lab_modes()[0]]
            cal, numbers = acceptance.compare(records, data, label)
            numbers["noise"] = cal.calibration_json()["noise"]
            numbers["noise_added"] = {r.file[:-4]: r.noise_sd for r in records}
            numbers["disagreement"] = cal.disagreement
            numbers["fit_warnings"] = cal.fit_warnings
            numbers["basis_modes_hz"] = {n: [m.freq_hz for m in cal.problem.basis.modes(n)] for n in (1, 2, 3)}
            results[label] = numbers
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(results, indent=1, default=float))
    print(f"wrote {RESULTS} and {FIGURES}/")


if __name__ == "__main__":
    main()
