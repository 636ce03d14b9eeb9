"""Speed of ``ModalModel.simulate`` (bayes_update.models.modal): 70 000 samples, six modes, three
sensors (acceleration, velocity, displacement), median of 7 after one warm-up call; the
parameters at the middle of their priors.

    python benchmarks/bench_modal.py

writes ``benchmarks/results/bench_modal.md``.  Cases: every mode linear (exact discretisation);
a cubic spring in mode 1 (RK4 on that mode); a cubic spring and cubic damper in mode 2; a cubic
spring at the driving point (a joint: RK4 on the six coupled modes); a friction in mode 1 and a
clearance at the driving point (their RK4 steps sized on the steepest slope their priors allow); a
Jenkins element in mode 1 and at the driving point.
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent)]

import numpy as np  # noqa: E402
from _machine import machine, median_time  # noqa: E402

from bayes_update.models.modal import ModalModel, Nonlinearity  # noqa: E402

MODES = [(7.3, 0.021), (19.1, 0.017), (33.4, 0.012), (51.8, 0.026), (88.2, 0.015), (140.5, 0.02)]
FS, N = 2048.0, 70_000
SENSORS = [("acc", "acceleration"), ("vel", "velocity"), ("dis", "displacement")]


def main():
    rng = np.random.default_rng(5)
    C = np.abs(rng.standard_normal((6, 3))) + 0.1  # positive at the driving point ("acc")
    u = rng.standard_normal(N)
    cases = [
        ("every mode linear", {}),
        ("k3 in mode 1", dict(nonlinear=[("k3", 1)], bounds={"k3_1": (-1e6, 1e6)})),
        ("k3 + c3 in mode 2", dict(nonlinear=[("k3", 2), ("c3", 2)], bounds={"k3_2": (-1e6, 1e6), "c3_2": (0, 10.0)})),
        (
            "k3 at the driving point (six coupled modes)",
            dict(nonlinear=[Nonlinearity("k3", at="acc")], driving_point="acc", bounds={"k3_at_acc": (-1e6, 1e6)}),
        ),
        (
            "friction in mode 1 (v0 = 1e-3 m/s)",
            dict(nonlinear=[Nonlinearity("friction", 1, v0=1e-3)], bounds={"friction_1": (0.0, 0.05)}),
        ),
        (
            "clearance at the driving point (gap 1e-4 m; six coupled modes)",
            dict(
                nonlinear=[Nonlinearity("clearance", at="acc", gap=1e-4)],
                driving_point="acc",
                bounds={"clearance_at_acc": (0.0, 2e3)},
            ),
        ),
        (
            "Jenkins in mode 1 (slip 1e-5 m)",
            dict(nonlinear=[Nonlinearity("jenkins", 1, slip=1e-5)], bounds={"jenkins_1": (0.0, 1e3)}),
        ),
        (
            "Jenkins at the driving point (slip 1e-5 m; six coupled modes)",
            dict(
                nonlinear=[Nonlinearity("jenkins", at="acc", slip=1e-5)],
                driving_point="acc",
                bounds={"jenkins_at_acc": (0.0, 1e3)},
            ),
        ),
    ]
    rows = []
    for label, kw in cases:
        model = ModalModel(MODES, C, sensors=SENSORS, residual=[1e-3, 1e-7, 2e-6], **kw)
        theta = {p.name: 0.5 * (p.low + p.high) for p in model.parameters}
        seconds = median_time(lambda: model.simulate(theta, u, FS))
        rows.append(f"| {label} | {1e3 * seconds:.1f} |")
        print(rows[-1], flush=True)
    text = (
        f"`ModalModel.simulate`, {N} samples, six modes, three sensors; median of 7 after warm-up; "
        f"{machine()}\n\n| case | ms |\n|---|---|\n"
        + "\n".join(rows)
        + "\n\nRegenerate: `python benchmarks/bench_modal.py`\n"
    )
    (HERE / "results" / "bench_modal.md").write_text(text)
    print(text)


if __name__ == "__main__":
    main()
