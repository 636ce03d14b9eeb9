"""Convergence study behind the solver defaults (elements, substeps, rho_inf).

Relative L2 error of the mid-span velocity for the paper's chirp at the low
(0.005 N) and high (0.1 N) level, paper's parameters, against a fine reference
(48 elements, 64 substeps): spatial error at 64 substeps, temporal error at 48
elements, and the combination; plus the algorithmic damping and period error
of the scheme at the first mode.

    python benchmarks/convergence_study.py            # about 3 minutes
"""

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine  # noqa: E402

import fe  # noqa: E402
from bayes_update.data.signals import chirp  # noqa: E402

P = fe.PAPER_PARAMETERS
FS = 1024.0


def velocity(n, m, rho, amp):
    return fe.BeamModel(n_elements=n, substeps=m, rho_inf=rho).simulate(P, chirp(amp), FS).sensor_velocity


def main():
    print(f"machine: {machine()}\n")
    levels = {"low": 0.005, "high": 0.1}
    refs = {k: velocity(48, 64, 0.9, a) for k, a in levels.items()}

    def err(v, level):
        return np.linalg.norm(v - refs[level]) / np.linalg.norm(refs[level])

    print("Spatial error (64 substeps, rho_inf 0.9), relative L2 of the mid-span velocity:\n")
    print("| elements | low | high | f1 error |")
    print("|---|---|---|---|")
    f_ref = fe.BeamModel(n_elements=128).modal_analysis(P, 1).frequencies_hz[0]
    for n in (6, 8, 10, 12, 16, 24):
        f1 = fe.BeamModel(n_elements=n).modal_analysis(P, 1).frequencies_hz[0]
        e = [err(velocity(n, 64, 0.9, levels[k]), k) for k in levels]
        print(f"| {n} | {100 * e[0]:.2f} % | {100 * e[1]:.2f} % | {f1 / f_ref - 1:.1e} |")
    print(
        "\nTemporal error (48 elements), relative L2, and the scheme at f1 = "
        f"{f_ref:.2f} Hz (algorithmic damping ratio, period elongation):\n"
    )
    print("| substeps | rho_inf | low | high | zeta_alg | period error |")
    print("|---|---|---|---|---|---|")
    for m in (1, 2, 4, 8):
        for rho in (0.01, 0.5, 0.9):
            e = [err(velocity(48, m, rho, levels[k]), k) for k in levels]
            z, pe = fe.generalized_alpha_accuracy(rho, 2 * np.pi * f_ref / (FS * m))
            print(f"| {m} | {rho} | {100 * e[0]:.2f} % | {100 * e[1]:.2f} % | {z:.1e} | {pe:.1e} |")
    d = fe.BeamModel()
    e = [err(velocity(d.n_elements, d.substeps, d.rho_inf, levels[k]), k) for k in levels]
    print(
        f"\nDefault ({d.n_elements} elements, {d.substeps} substeps, rho_inf {d.rho_inf}): "
        f"low {100 * e[0]:.2f} %, high {100 * e[1]:.2f} %"
    )
    r = (2 * d.n_elements, 4 * d.substeps)
    e = [err(velocity(*r, d.rho_inf, levels[k]), k) for k in levels]
    print(f"Virtual-rig settings ({r[0]} elements, {r[1]} substeps): low {100 * e[0]:.2f} %, high {100 * e[1]:.2f} %")


if __name__ == "__main__":
    main()
