"""Benchmark of the volterra package (not a timed test).

1. Fit time of a 4096-sample record, orders 1-3, (J1, J2, J3) = (2, 2, 6) and
   (6, 4, 4): median (and 10th / 90th percentiles) of repeated runs after a
   warm-up, split into filtering + regressors and the least-squares solve.
2. How the cost grows with J (and with the number of regressors P).
3. Limits: how well the Kautz basis can represent the third-order kernel of a
   resonant (Duffing-type) system at all - the l2-optimal projection of the
   exact kernel, noise-free and data-free (see volterra.model docs).

Usage:
    python benchmarks/bench_volterra.py [--threads N] [--repeat R] [--skip-limits]

``--threads`` sets OPENBLAS_NUM_THREADS / OMP_NUM_THREADS before numpy is
imported.  On a small, busy machine single-threaded BLAS is both faster and far
more predictable for these tall-skinny problems (4096 x 61); run several fits in
parallel processes instead of threading one.
"""

from __future__ import annotations

import argparse
import os
import sys
import time


def _parse():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--threads", type=int, default=None, help="BLAS threads (default: library default)")
    p.add_argument("--repeat", type=int, default=50, help="timed runs per case")
    p.add_argument("--skip-limits", action="store_true", help="skip the representability table")
    return p.parse_args()


ARGS = _parse()
if ARGS.threads is not None:
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(ARGS.threads)

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from volterra import KautzBasis, fit_volterra  # noqa: E402
from volterra.fit import _tall_qr_r  # noqa: E402

FS, N = 1024.0, 4096


def timeit(fn, repeat, warmup=5):
    for _ in range(warmup):
        fn()
    ts = np.empty(repeat)
    for i in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts[i] = time.perf_counter() - t0
    return np.percentile(ts, [10, 50, 90]) * 1e3  # ms


def test_record():
    """A chirp (20 -> 50 Hz, 2 s, then 2 s of rest) through a mildly cubic Kautz
    model: realistic conditioning; the timing does not depend on the data."""
    t = np.arange(N) / FS
    u = 0.1 * np.sin(2 * np.pi * (20 * t + 7.5 * t**2))
    u[t >= 2] = 0
    basis = KautzBasis.from_modal(30.0, 0.01, FS, (2, 0, 2))
    G = basis.regressors(u)
    rng = np.random.default_rng(0)
    y = G @ np.concatenate([[1e-3, 5e-4], 1e-1 * rng.standard_normal(4)])
    return u, y + 1e-3 * np.std(y) * rng.standard_normal(N)


def bench_fit(u, y, repeat):
    print(f"\n1. Fit of one {N}-sample record, orders 1-3 (median [p10, p90] of {repeat} runs after 5 warm-up runs)")
    print(
        f"{'J':>12s} {'P':>4s} {'fit [ms]':>24s} {'regressors [ms]':>18s} {'solve [ms]':>12s} {'components [ms]':>16s}"
    )
    for J in [(2, 2, 6), (6, 4, 4)]:
        basis = KautzBasis.from_modal(30.0, 0.01, FS, J)
        fit = timeit(lambda: fit_volterra(u, y, basis), repeat)
        reg = timeit(lambda: basis.regressor_rows(u), repeat)
        A = np.vstack([basis.regressor_rows(u), y]).T
        qr = timeit(lambda: _tall_qr_r(A), repeat)
        model = fit_volterra(u, y, basis)
        comp = timeit(lambda: model.components(u), repeat)
        print(
            f"{str(J):>12s} {basis.n_params:4d} {fit[1]:8.2f} [{fit[0]:5.2f}, {fit[2]:6.2f}] "
            f"{reg[1]:18.2f} {qr[1]:12.2f} {comp[1]:16.2f}"
        )


def bench_growth(u, y, repeat):
    print("\n2. Cost growth with J (median fit time, one 4096-sample record)")
    rows = []
    for J in [
        (2, 2, 2),
        (2, 2, 4),
        (2, 2, 6),
        (2, 2, 8),
        (2, 2, 10),
        (2, 2, 12),
        (2,),
        (4,),
        (8,),
        (16,),
        (32,),
        (4, 4, 4),
        (6, 6, 6),
        (8, 8, 8),
    ]:
        basis = KautzBasis.from_modal(30.0, 0.01, FS, J)
        t = timeit(lambda: fit_volterra(u, y, basis), max(5, repeat // 3), warmup=2)[1]
        rows.append((J, basis.n_params, t))
        print(f"  J = {str(J):>12s}: P = {basis.n_params:4d} regressors, {t:8.2f} ms")
    P = np.array([r[1] for r in rows], float)
    T = np.array([r[2] for r in rows])
    big = P >= 20
    slope = np.polyfit(np.log(P[big]), np.log(T[big]), 1)[0]
    print(
        f"  P = J1 + J2(J2+1)/2 + J3(J3+1)(J3+2)/6 grows like J3^3; the fit time grows like "
        f"P^{slope:.2f} for P >= 20 (QR of an N x P matrix: N P^2 flops), i.e. about J3^{3 * slope:.1f}."
    )


def bench_limits():
    """Best (l2-optimal) Kautz approximation of h3(n1,n2,n3) = -sum_t h(t) h(n1-t) h(n2-t) h(n3-t)."""
    from scipy.signal import fftconvolve

    fn, zeta = 30.0, 0.01
    d = zeta * fn
    print("\n3. Limits: H3 of a resonant system near f1 + f2 + f3 = fn (fn = 30 Hz, zeta = 0.01)")
    print("   exact kernel: discrete Duffing structure with h in the span of J = 2; values are the")
    print("   errors of its l2-OPTIMAL approximation in the basis (no data, no noise)")
    L = 1 << 15
    b1 = KautzBasis.from_modal(fn, zeta, FS, {1: 2})
    w = np.array([1.0, 0.6])
    h = b1.impulse_responses(1, L) @ w
    Hd = lambda f: b1.frequency_response(1, f) @ w  # noqa: E731
    triples = np.array(
        [[fn, fn, -fn], [fn + d, fn, -fn], [fn - 2, fn + 2, -fn], [fn - 5, fn + 5, -fn], [20.0, 20.0, 20.0]]
    ).T
    names = ["(fn,fn,-fn)", "(fn+d,fn,-fn)", "(fn-2,fn+2,-fn)", "(fn-5,fn+5,-fn)", "(20,20,20)*"]
    exact = -Hd(triples[0]) * Hd(triples[1]) * Hd(triples[2]) * Hd(triples.sum(0))
    R = fftconvolve(h, h[::-1])
    energy = np.sum(R**4)
    print(f"   {'J3':>4s} {'energy':>8s} " + " ".join(f"{n:>16s}" for n in names))
    for J3 in (2, 4, 6, 8, 12, 16):
        b3 = KautzBasis.from_modal(fn, zeta, FS, {3: J3})
        psi = b3.impulse_responses(3, L)
        g = np.stack([fftconvolve(psi[:, i], h[::-1])[L - 1 :] for i in range(J3)], axis=-1)
        C = -np.einsum("t,ti,tj,tm->ijm", h, g, g, g, optimize=True)
        P = [b3.frequency_response(3, f) for f in triples]
        H3 = np.einsum("pi,pj,pk,ijk->p", *P, C, optimize=True)
        err = np.abs(H3 / exact - 1)
        cells = " ".join(f"{100 * e:15.0f}%" for e in err)
        print(f"   {J3:4d} {100 * np.sum(C**2) / energy:7.1f}% {cells}")
    print("   * off the ridge (sum 60 Hz), where |H3| is small: relative errors there are large too.")
    print("   On the ridge away from the triple peak the basis misses H3 by ~75-90 % at any J3;")
    print("   identified from records the errors are larger still (tests: 63 ... 4200 %), while y3 in")
    print("   the time domain is matched to 9 % (chirp, y3/y1 = 10 %). Read y2, y3 of a strongly")
    print("   nonlinear record as parts of a truncated fit in this basis, not as true Volterra components.")


def main():
    import platform

    print(
        f"volterra benchmark: python {platform.python_version()}, numpy {np.__version__}, "
        f"{os.cpu_count()} CPU(s), BLAS threads: {os.environ.get('OPENBLAS_NUM_THREADS', 'default')}"
    )
    u, y = test_record()
    bench_fit(u, y, ARGS.repeat)
    bench_growth(u, y, ARGS.repeat)
    if not ARGS.skip_limits:
        bench_limits()


if __name__ == "__main__":
    main()
