"""Cost of one modal-ROM run: the default data set's high-level chirp (4096
samples, recorded force), paper-equivalent rig, paper's parameters, 3 modes.

Median (and minimum) of runs after JIT warm-up, one core (BLAS pinned to one
thread: on a shared machine a multi-threaded OpenBLAS can turn the 0.1 ms
eigenproblem into milliseconds).  "Excluding" reuses the basis cached for
the run's P_eff; "including" clears the cache first, so the run pays the
per-parameter precomputation (partial eigenproblem, projections) as every new
point of a DOE or an MCMC chain does.  The full FE at its defaults (10
elements, 4 substeps) runs in the same process, interleaved with the ROM in
rounds so that both see the same load of a shared machine, for the ratio.

    python benchmarks/bench_rom.py > benchmarks/results/bench_rom.md
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine  # noqa: E402

import fe  # noqa: E402
from bayes_update.models.beam.rig import rig_of  # noqa: E402
from bayes_update.models.beam.virtual_rig import load_default_dataset  # noqa: E402

PARAMS = fe.PAPER_PARAMETERS
DATA = load_default_dataset()
FORCE = next(t for t in DATA.tests if t.file == "chirp_high.csv").force
FS = DATA.sampling_rate_hz


def median_time(fn, repeats):
    fn()  # warm-up (JIT, caches)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def interleaved_times(rom, full, rounds=15, rom_repeats=7):
    """Median and minimum [s] of: ROM excluding / including the per-parameter
    precomputation, the precomputation alone, and the full FE, measured in
    interleaved rounds so that all four see the same machine load."""

    def excl():
        rom.simulate(PARAMS, FORCE, FS)

    def incl():
        rom.cache_clear()
        rom.simulate(PARAMS, FORCE, FS)

    def pre():
        rom.cache_clear()
        rom.reduced(PARAMS)

    def run_fe():
        full.simulate(PARAMS, FORCE, FS)

    jobs = {"excl": (excl, rom_repeats), "incl": (incl, rom_repeats), "pre": (pre, rom_repeats), "fe": (run_fe, 1)}
    for fn, _ in jobs.values():
        fn()  # warm-up (JIT, caches)
    times = {k: [] for k in jobs}
    for _ in range(rounds):
        for key, (fn, reps) in jobs.items():
            for _ in range(reps):
                t0 = time.perf_counter()
                fn()
                times[key].append(time.perf_counter() - t0)
    return {k: (float(np.median(v)), float(np.min(v))) for k, v in times.items()}


def rom_times(rom, repeats=51):
    excl = median_time(lambda: rom.simulate(PARAMS, FORCE, FS), repeats)

    def fresh():
        rom.cache_clear()
        rom.simulate(PARAMS, FORCE, FS)

    return excl, median_time(fresh, repeats)


def prior_box_times(rom, n_points=40, seed=0):
    """Median cost at random points of the default prior box (a new P_eff each time)."""
    rng = np.random.default_rng(seed)
    times = []
    rom.simulate(PARAMS, FORCE, FS)
    for _ in range(n_points):
        p = fe.Parameters(
            eta=rng.uniform(1e6, 6e6), c=rng.uniform(0, 30e3), F=rng.uniform(60, 95), k_s=rng.uniform(0, 600e3)
        )
        t0 = time.perf_counter()
        rom.simulate(p, FORCE, FS)
        times.append(time.perf_counter() - t0)
    return float(np.median(times)), float(np.max(times))


def opensees_time(full, repeats=3):
    """Median seconds of one OpenSeesPy run on the full FE's mesh and step, in
    this process (so under the same load as the rows above); None without openseespy."""
    try:
        from opensees_model import run_opensees_transient
    except ImportError:
        return None
    try:
        run_opensees_transient(full, PARAMS, FORCE[:64], FS)
    except Exception:
        return None
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run_opensees_transient(full, PARAMS, FORCE, FS)
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def first_call_seconds():
    code = (
        "import time; t0 = time.perf_counter(); import fe, numpy as np; "
        "r = fe.ModalROM(rig=fe.Rig(bending_stiffness_factor=1.24)); "
        "r.simulate(fe.PAPER_PARAMETERS, np.sin(np.arange(4096) / 5.0)); "
        "print(time.perf_counter() - t0)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(out.stdout.strip())


def main():
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(
        f"machine: {machine()}; BLAS threads: {os.environ['OPENBLAS_NUM_THREADS']}; "
        f"load average at start {load} (a shared machine: medians absorb some of it)\n"
    )
    print(
        f"Force: default data set, chirp_high ({FORCE.size} samples at {FS:g} Hz), "
        f"rig factor {rig_of(DATA).bending_stiffness_factor}, paper's parameters.\n"
    )
    rom = fe.ModalROM(rig=rig_of(DATA))
    t0 = time.perf_counter()
    model_setup = fe.ModalROM(rig=rig_of(DATA)).rig_matrices
    setup = time.perf_counter() - t0
    full = fe.BeamModel(rig=rig_of(DATA))
    t = interleaved_times(rom, full)
    substeps = rom.choose_substeps(PARAMS, FS)
    print(
        f"ModalROM ({rom.n_modes} modes, shapes from {rom.n_elements} elements, "
        f"{substeps} RK4 substep(s) per sample); median (minimum) of interleaved runs:\n"
    )
    fe_med, fe_min = t["fe"]
    print("| | ms per run | full FE / ROM (medians) |")
    print("|---|---|---|")
    for key, label in (
        ("excl", "ROM, excluding per-parameter precomputation"),
        ("incl", "ROM, including per-parameter precomputation"),
    ):
        med, low = t[key]
        print(f"| {label} | {1e3 * med:.3f} ({1e3 * low:.3f}) | {fe_med / med:.0f}x |")
    med, low = t["pre"]
    print(f"| per-parameter precomputation alone (eigenproblem + projections) | {1e3 * med:.3f} ({1e3 * low:.3f}) | |")
    print(
        f"| full FE ({full.n_elements} elements, {full.substeps} substeps) | "
        f"{1e3 * fe_med:.1f} ({1e3 * fe_min:.1f}) | 1x |"
    )
    os_med = opensees_time(full)
    if os_med is not None:
        inc = t["incl"][0]
        print(
            f"| OpenSeesPy, the full FE's mesh and step (corotational, HHTGeneralized; 3 runs) | "
            f"{1e3 * os_med:.0f} | {os_med / fe_med:.0f}x the full FE, {os_med / inc:.0f}x the ROM |"
        )
    print()
    print(
        f"Per-model setup (FE matrices of {model_setup.mass.shape[0]} free transverse dofs, "
        f"Cholesky, buckling load; once per ModalROM): {1e3 * setup:.1f} ms (first call, "
        "includes the effect checks)\n"
    )
    med, worst = prior_box_times(fe.ModalROM(rig=rig_of(DATA)))
    print(
        f"Random points of the prior box (a new P_eff each, precomputation included, "
        f"40 points): median {1e3 * med:.3f} ms, max {1e3 * worst:.3f} ms\n"
    )
    print("Cost against the number of modes (substeps chosen automatically):\n")
    print("| modes | substeps | ms excl. | ms incl. | us per RK4 step |")
    print("|---|---|---|---|---|")
    for n in (1, 2, 3, 4, 5, 7):
        r = fe.ModalROM(rig=rig_of(DATA), n_modes=n)
        e, i = rom_times(r, repeats=31)
        m = r.choose_substeps(PARAMS, FS)
        print(f"| {n} | {m} | {1e3 * e:.3f} | {1e3 * i:.3f} | {1e6 * e / ((FORCE.size - 1) * m):.3f} |")
    print()
    print(
        f"first call in a fresh process (import + numba cache load + setup + one run): "
        f"{first_call_seconds():.2f} s (numba cache warm)"
    )


if __name__ == "__main__":
    main()
