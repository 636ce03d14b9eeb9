"""Benchmark of the several-mode basis (not a timed test): 6 modes, 3 sensors, 1e5 samples.

A record like a ground-vibration test: six modes between 3.4 and 9.2 Hz
(zeta 1-2 %), band-limited random force 2.5-10 Hz sampled at fs = 25 Hz
(2.5 x the top of the band), three sensors (sums of the six modes with seeded
gains), 40 dB noise on force and responses.  Measured:

1. ``KautzBasis.from_data`` (LSCF over orders 2..40, stabilisation diagram,
   time-domain refinement of the 12 pole parameters on the 3 x 1e5 samples);
2. the factored projector (``VolterraProjector``: filtering, regressors, QR,
   SVD) and its memory, and the cost of one evaluation, ``components(y)`` of
   a new response (what the metrics pay per model run and sensor), against
   today's one-mode default J = (2, 2, 6) without feed-through (61
   regressors) on the same input;
3. a full ``fit_volterra`` of one sensor, both bases.

Medians of repeated runs after a warm-up, BLAS on one thread (the default
here; ``--threads`` to change it).  Memory: peak of numpy's allocations
(tracemalloc) while the object is built.

Measured (AMD EPYC, 2 cores shared with three other engineers' jobs, load
average 4-4.5, Python 3.11.7, Linux, one BLAS thread, 11 runs; two runs of
the script, the spread shows the shared machine):

  from_data: 6 modes found, 5.4-6.4 s, peak 267 MB; largest errors against
  the simulated modes 0.001 % (frequency) and 0.05 % (damping).
  Basis: 13 functions at order 1, orders 2-3 from the dominant mode (3 and
  7 functions): 13 + 6 + 84 = 103 regressors.

                         P   projector build   build peak   fit_volterra (one sensor)
  today (2,2,6), 1 mode  61     0.71-0.88 s      244 MB          0.17-0.24 s
  6 modes, feed-through 103     1.88-1.97 s      412 MB          0.37-0.39 s

  components(y), one sensor, 33 alternating runs: today 5.9-6.4 ms, six modes
  9.1-9.2 ms: 1.45-1.55 x today's (target: within 2 x), below the ratio of
  the regressor counts (1.69); three sensors 18-19 ms against 27-28 ms.

Both evaluations are two passes over a (P, N) matrix, so the cost grows like
P.  Orders 2 and 3 on all six modes at J = (2, 2, 6) per mode would take
13 + 91 + 9139 = 9243 regressors (37 functions at order 3, C(39, 3)):
hence the dominant-mode rule of ``KautzBasis.from_data``
(``nonlinear_modes=1``).

Usage:
    python benchmarks/bench_multimode.py [--threads N] [--repeat R]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
import tracemalloc


def _parse():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--threads", type=int, default=1, help="BLAS threads (default 1)")
    p.add_argument("--repeat", type=int, default=7, help="timed runs per case")
    return p.parse_args()


ARGS = _parse()
for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = str(ARGS.threads)

import numpy as np  # noqa: E402
from scipy.signal import butter, cont2discrete, lfilter, sosfilt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, ".."))
sys.path.insert(0, HERE)
from _machine import machine  # noqa: E402

from volterra import KautzBasis, VolterraProjector, fit_volterra  # noqa: E402

FS = 25.0
N = 100_000
MODES = [(3.4, 0.012), (4.3, 0.018), (5.5, 0.011), (6.6, 0.016), (7.9, 0.014), (9.2, 0.02)]


def record(seed=2025):
    """(force (N,), responses (N, 3)) with 40 dB noise on every channel."""
    rng = np.random.default_rng(seed)
    sos = butter(4, (2.5, 10.0), "bandpass", fs=FS, output="sos")
    u = sosfilt(sos, rng.standard_normal(N))
    gains = rng.uniform(0.3, 1.0, (3, len(MODES))) * rng.choice([-1, 1], (3, len(MODES)))
    y = np.zeros((N, 3))
    for m, (fn, zeta) in enumerate(MODES):
        w = 2 * np.pi * fn
        num, den, _ = cont2discrete(([w * w], [1.0, 2 * zeta * w, w * w]), 1 / FS, method="zoh")
        x = lfilter(np.ravel(num), np.ravel(den), u)
        y += x[:, None] * gains[:, m]
    add = lambda a: a + 0.01 * np.std(a, axis=0) * rng.standard_normal(a.shape)  # noqa: E731
    return add(u), add(y)


def median_s(fn, repeat):
    fn()
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


def peak_mb(fn):
    tracemalloc.start()
    out = fn()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return out, peak / 1e6


def main():
    print(f"# {machine()}; BLAS threads {ARGS.threads}; median of {ARGS.repeat} runs after a warm-up")
    u, y = record()
    t = median_s(lambda: KautzBasis.from_data(u, y, FS), max(3, ARGS.repeat // 2))
    basis, mem = peak_mb(lambda: KautzBasis.from_data(u, y, FS))
    fr = sorted((p.freq_hz, p.damping_ratio) for p in basis.poles[1])
    ef = max(abs(a[0] / b[0] - 1) for a, b in zip(fr, MODES))
    ez = max(abs(a[1] / b[1] - 1) for a, b in zip(fr, MODES))
    print(
        f"from_data: {len(fr)} modes, {t:.2f} s, peak {mem:.0f} MB; "
        f"largest errors: frequency {100 * ef:.3f} %, damping {100 * ez:.2f} %"
    )
    print(basis.describe())
    today = KautzBasis.from_modal(basis.pole(1).freq_hz, basis.pole(1).damping_ratio, FS, (2, 2, 6), feedthrough=False)
    bases = {"today (2,2,6), 1 mode": today, "6 modes, feed-through": basis}
    print(f"\n{'basis':>24s} {'P':>4s} {'projector [s]':>14s} {'memory [MB]':>12s} {'fit [s]':>8s}")
    projs = {}
    for name, b in bases.items():
        build = median_s(lambda: VolterraProjector(u, b), max(3, ARGS.repeat // 2))
        projs[name], mem = peak_mb(lambda: VolterraProjector(u, b))
        fit = median_s(lambda: fit_volterra(u, y[:, 0], b), max(3, ARGS.repeat // 2))
        print(f"{name:>24s} {b.n_params:4d} {build:14.2f} {mem:12.0f} {fit:8.2f}")
    # one evaluation = components of a new response on the factored projector; the two
    # bases are timed in alternation so that both see the same load of a shared machine
    times = {name: [] for name in bases}
    for name in bases:
        projs[name].components(y[:, 0])
    for _ in range(3 * ARGS.repeat):
        for name, proj in projs.items():
            t0 = time.perf_counter()
            proj.components(y[:, 0])
            times[name].append(time.perf_counter() - t0)
    a, b = (np.array(times[name]) for name in bases)
    print(
        f"\ncomponents(y) of one sensor, {3 * ARGS.repeat} alternating runs: today "
        f"{1e3 * np.median(a):.1f} ms, 6 modes {1e3 * np.median(b):.1f} ms; ratio of medians "
        f"{np.median(b) / np.median(a):.2f}, median of paired ratios {np.median(b / a):.2f} "
        f"(P ratio {basis.n_params / today.n_params:.2f}); x 3 sensors: "
        f"{3e3 * np.median(a):.0f} / {3e3 * np.median(b):.0f} ms"
    )


if __name__ == "__main__":
    main()
