"""Nonlinear shares of the default data set's six tests (the level choice).

For each test of the embedded data set, on the noise-free output of the
virtual rig (paper-equivalent rig, factor 1.24, Table 3 parameters, 20
elements at 4096 Hz, decimated to 1024 Hz):

* Volterra decomposition (pole: f1 and zeta1 of fe's modal analysis at the
  truth; J = (2, 2, 4) and the volterra package's default (2, 2, 6)):
  nonlinear share ||y2 + y3|| / ||y||, ||y3|| / ||y1||, ||y2|| / ||y1||, and
  the fit's relative residual;
* the physical departure from linear scaling
  ||y(A) - (A / A0) y(A0)|| / ||y(A)|| with A0 = 1e-4 N;
* the Volterra share's floor: the same decomposition at A0 (a linear
  response), which is what the basis, not the physics, puts into y2 + y3.

    python benchmarks/rig_levels.py [--imperfection M] [--noisy]

``--noisy`` also decomposes the shipped (noisy) records.
"""

import argparse
import dataclasses
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine  # noqa: E402

import fe  # noqa: E402
from bayes_update.data import signals
from bayes_update.models.beam.levels import linear_departure, nonlinear_shares  # noqa: E402
from bayes_update.models.beam.virtual_rig import (  # noqa: E402
    PAPER_TESTS,
    VirtualRig,
    load_default_dataset,
)

J_SETS = ((2, 2, 4), (2, 2, 6))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--imperfection", type=float, default=0.0, help="initial bow [m]")
    ap.add_argument("--noisy", action="store_true", help="also decompose the shipped records")
    args = ap.parse_args(argv)
    effects = (fe.InitialImperfection(args.imperfection),) if args.imperfection else ()
    vrig = VirtualRig(effects=effects)
    modes = vrig.modes(2)
    f1, z1 = float(modes.frequencies_hz[0]), float(modes.damping_ratios[0])
    print(f"machine: {machine()}")
    print(
        f"virtual rig: factor {vrig.rig.bending_stiffness_factor}, {vrig.n_elements} elements, "
        f"{vrig.fs_fine:g} Hz x {vrig.substeps} substeps, decimated to {vrig.fs:g} Hz; "
        f"effects {[e.name for e in effects] or 'none'}"
    )
    print(f"truth: {vrig.truth}; P_eff = {vrig.truth.effective_preload(vrig.rig):.2f} N")
    print(
        f"f1 = {f1:.3f} Hz, zeta1 = {100 * z1:.3f} %, f2 = {modes.frequencies_hz[1]:.2f} Hz, "
        f"35 Hz / f1 = {signals.PAPER_SINE_HZ / f1:.4f}"
    )
    print()
    head = (
        f"{'test':<13}{'A [N]':>7}{'peak v':>9}  "
        + "  ".join(
            f"{'J=' + ''.join(map(str, J)):>8}{'share':>7}{'y3/y1':>7}{'y2/y1':>9}{'resid':>7}{'floor':>7}"
            for J in J_SETS
        )
        + f"{'lin.dep.':>10}"
    )
    print(head)
    print("-" * len(head))
    t0 = time.perf_counter()
    for spec in PAPER_TESTS:
        _, f, v = vrig.clean(spec)
        _, f0, v0 = vrig.clean(dataclasses.replace(spec, amplitude_n=1e-4))
        cols = []
        for J in J_SETS:
            s = nonlinear_shares(f, v, f1, z1, vrig.fs, J)
            floor = nonlinear_shares(f0, v0, f1, z1, vrig.fs, J)["share"]
            cols.append(
                f"{'':>8}{s['share']:7.3f}{s['y3_over_y1']:7.3f}{s['y2_over_y1']:9.2e}{s['residual']:7.3f}{floor:7.3f}"
            )
        dep = linear_departure(vrig, spec)
        print(f"{spec.name:<13}{spec.amplitude_n:7.3f}{abs(v).max():9.4f}  " + "  ".join(cols) + f"{dep:10.4f}")
    if args.noisy and not effects:
        print("\nshipped (noisy, 40 dB) records, J = (2, 2, 4):")
        ds = load_default_dataset()
        for rec in ds.tests:
            s = nonlinear_shares(rec.force, rec.velocity, f1, z1, vrig.fs, J_SETS[0])
            print(f"  {rec.name:<13} share {s['share']:.3f}  y3/y1 {s['y3_over_y1']:.3f}  resid {s['residual']:.3f}")
    print(f"\n({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
