"""The front end on a randomized corpus of records it was not built on (issue 40).

Every record (``front_end_draws.draw(seed)``: a structure of one class, an
excitation, sensors, noise, offsets and drifts, all drawn from the seed) goes
through what ``calibrate``, ``sample``, ``discrepancy`` and ``inspect`` do
first, and is scored against its truth:

* the period of every test: ``volterra.find_periods`` on the force (the
  declared one when the record declares it);
* the noise of every channel of every test:
  ``bayes_update.data.noise.dataset_noise`` (not strict), within 25 % of the
  sd added, or ``unknown`` with a reason;
* the modes of the low-level test: ``bayes_update.data.inspect.find_modes``
  (``volterra.estimate_modes`` as the commands call it), matched one to one
  with the modes in the band (cost: the frequency distance in half-power
  half-widths; a match within max(3 zeta, 1 %) of the frequency), every mode
  within 0.5 % in frequency and 15 % in damping ratio, no other mode found.

A record's modes are *resolvable* (:func:`resolvable`) when every mode in the
band has its half-power band inside it with a half-power half-width to spare
(a mode whose flank leaves the band cannot be told from the tail of one
outside it) and every mode outside has its outside likewise, neighbours are
more than their half-power half-widths apart
(|f_i - f_j| > zeta_i f_i + zeta_j f_j), the record's line spacing is at most
a half-power bandwidth and half the closest spacing, and every mode's peak is
clear (its own response at resonance at least 10 times the noise's power
there on its best sensor, ``front_end_draws.CLEAR_PEAK``).  The success rate
is over resolvable records; the others are scored and listed too.

    python benchmarks/front_end_corpus.py                 # 301 records, seeds 0..300
    python benchmarks/front_end_corpus.py --n 42 --jobs 2

writes ``benchmarks/results/front_end_corpus.{json,md}`` (every record's row
and the table) and prints the table and the command that regenerates it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import traceback
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent)]  # this checkout's packages, not an installed copy

import numpy as np  # noqa: E402
from front_end_draws import CLASSES, CLEAR_PEAK, draw  # noqa: E402
from scipy.optimize import linear_sum_assignment  # noqa: E402

import volterra  # noqa: E402
from bayes_update.data.inspect import find_modes  # noqa: E402
from bayes_update.data.lpm import HOLDS_FORCE_NOISE  # noqa: E402
from bayes_update.data.noise import dataset_noise  # noqa: E402
from volterra import find_periods  # noqa: E402

FREQ_TOL, DAMPING_TOL, NOISE_TOL = 0.005, 0.15, 0.25
#: the exceptions the front end documents as its answer for a record it cannot read
DOCUMENTED = (volterra.PoleEstimationError,)
RESULTS = HERE / "results"


def resolvable(truth, n_samples: int, fs: float, period) -> tuple[bool, str]:
    """(True, "") or (False, why): the module docstring's conditions."""
    lo, hi = truth.band
    modes = truth.modes
    if not modes:
        return False, "no mode in the band"
    for f, z in modes:
        if f * (1 - 2 * z) < lo or f * (1 + 2 * z) > hi:
            return False, f"the half-power band of {f:.4g} Hz is not a half-power half-width inside the band"
    for f, z in truth.outside:
        if f * (1 + 2 * z) >= lo and f * (1 - 2 * z) <= hi:
            return False, f"the half-power band of {f:.4g} Hz (outside) is not a half-power half-width outside"
    df = fs / (period if period else n_samples)
    for (f1, z1), (f2, z2) in zip(modes[:-1], modes[1:]):
        if f2 - f1 <= z1 * f1 + z2 * f2:
            return False, f"{f1:.4g} and {f2:.4g} Hz closer than their half-power half-widths"
        if df > (f2 - f1) / 2:
            return False, f"lines {df:.3g} Hz apart: coarse against {f1:.4g}-{f2:.4g} Hz"
    for (f, z), c in zip(modes, truth.details["clarity"]):
        if df > 2 * z * f:
            return False, f"lines {df:.3g} Hz apart: wider than the half-power band of {f:.4g} Hz"
        if c < CLEAR_PEAK:
            return False, f"the peak of {f:.4g} Hz is {c:.3g}x the noise (< {CLEAR_PEAK:g})"
    return True, ""


def match(truth_modes, found):
    """[(i_true, j_found)] one to one, within max(3 zeta, 1 %) of the true frequency."""
    if not truth_modes or not found:
        return []
    ft = np.array([f for f, _ in truth_modes])
    zt = np.array([z for _, z in truth_modes])
    ff = np.array([f for f, _ in found])
    cost = np.abs(ff[None, :] - ft[:, None]) / (zt * ft)[:, None]
    rows, cols = linear_sum_assignment(cost)
    gate = np.maximum(3 * zt, 0.01) * ft
    return [(int(i), int(j)) for i, j in zip(rows, cols) if abs(ff[j] - ft[i]) <= gate[i]]


def score(seed: int, cls: str | None = None) -> dict:
    """One record's row (JSON-ready)."""
    t0 = time.perf_counter()
    data, truth, _ = draw(seed, cls)
    fs = data.sampling_rate_hz
    lin = data.by_role("linear")[0]
    row = {
        "seed": seed,
        "class": truth.details["class"],
        "excitation": truth.details["excitation"],
        "form": truth.details["form"],
        "fs": fs,
        "n": lin.n_samples,
        "band": list(truth.band),
        "kinds": truth.details["kinds"],
        "modes_true": truth.modes,
        "outside": truth.outside,
    }
    ok, why = resolvable(truth, lin.n_samples, fs, truth.period[lin.name])
    row.update(resolvable=ok, why=why)
    row["periods"] = {}
    for t in data.tests:
        found = find_periods(t.force, t.period_samples)
        row["periods"][t.name] = {
            "true": truth.period[t.name],
            "found": None if isinstance(found, str) else found.period,
        }
    try:
        noise = dataset_noise(data, strict=False)
        eff = truth.details["effective_noise"]
        row["noise"] = [
            {
                "test": t,
                "channel": ch,
                "true": truth.noise[t][ch],
                "effective": eff[t].get(ch),
                "sd": e.sd,
                "method": e.method,
                "detail": e.detail,
            }
            for t, ests in noise.items()
            for ch, e in ests.items()
        ]
    except Exception as exc:  # a crash: a bug to report
        row["noise_crash"] = f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"
        row["noise"] = []
    try:
        found = find_modes(lin.force, lin.response, fs, lin.period_samples)
        row["modes_found"] = found
    except DOCUMENTED as exc:
        row["modes_found"], row["error"] = [], f"{type(exc).__name__}: {exc}"
    except Exception as exc:
        row["modes_found"], row["crash"] = [], f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}"
    pairs = match(truth.modes, row["modes_found"])
    row["errors"] = [
        {
            "f": truth.modes[i][0],
            "df": row["modes_found"][j][0] / truth.modes[i][0] - 1,
            "dz": row["modes_found"][j][1] / truth.modes[i][1] - 1,
        }
        for i, j in pairs
    ]
    row["missed"] = len(truth.modes) - len(pairs)
    row["spurious"] = len(row["modes_found"]) - len(pairs)
    row["success"] = (
        row["missed"] == 0
        and row["spurious"] == 0
        and all(abs(e["df"]) <= FREQ_TOL and abs(e["dz"]) <= DAMPING_TOL for e in row["errors"])
    )
    row["seconds"] = time.perf_counter() - t0
    return row


def noise_target(item) -> float:
    """The truth an estimate is scored against: the noise added to the channel, or, for an
    estimate that says it holds the force noise's response too (a fit's residual where
    the force's own noise is unknown: what the weights then need), that sum as added."""
    if HOLDS_FORCE_NOISE in item["detail"] and item.get("effective") is not None:
        return item["effective"]
    return item["true"]


def noise_error(item) -> float:
    return item["sd"] / noise_target(item) - 1


def noise_ok(item) -> bool:
    if item["sd"] is None:
        return bool(item["detail"])
    return abs(noise_error(item)) <= NOISE_TOL


def _pct(x, q):
    return f"{np.percentile(x, q) * 100:.3g}" if len(x) else "-"


def table(rows) -> str:
    """The per-class table (markdown)."""
    head = (
        "| class | records | resolvable | success (resolvable) | freq. error % p50 / p95 / max | "
        "damping error % p50 / p95 / max | spurious (records / modes) | missed (records / modes) | "
        "pole errors / crashes | noise: channels, within 25 % or unknown, unknown, error % p50 / p95 | "
        "periods found / periodic, found where none |"
    )
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for cls in list(CLASSES) + ["all"]:
        rs = [r for r in rows if cls == "all" or r["class"] == cls]
        if not rs:
            continue
        res = [r for r in rs if r["resolvable"]]
        errs = [e for r in res for e in r["errors"]]
        df = np.abs([e["df"] for e in errs])
        dz = np.abs([e["dz"] for e in errs])
        nz = [x for r in rs for x in r["noise"]]
        known = [abs(noise_error(x)) for x in nz if x["sd"] is not None]
        per = [p for r in rs for p in r["periods"].values() if p["true"]]
        false = sum(p["found"] is not None for r in rs for p in r["periods"].values() if not p["true"])
        lines.append(
            f"| {cls} | {len(rs)} | {len(res)} | {sum(r['success'] for r in res)} / {len(res)} "
            f"({100 * np.mean([r['success'] for r in res]) if res else float('nan'):.1f} %) | "
            f"{_pct(df, 50)} / {_pct(df, 95)} / {_pct(df, 100)} | {_pct(dz, 50)} / {_pct(dz, 95)} / {_pct(dz, 100)} | "
            f"{sum(r['spurious'] > 0 for r in rs)} / {sum(r['spurious'] for r in rs)} | "
            f"{sum(r['missed'] > 0 for r in rs)} / {sum(r['missed'] for r in rs)} | "
            f"{sum('error' in r for r in rs)} / {sum('crash' in r or 'noise_crash' in r for r in rs)} | "
            f"{len(nz)}, {100 * np.mean([noise_ok(x) for x in nz]) if nz else float('nan'):.1f} %, "
            f"{sum(x['sd'] is None for x in nz)}, {_pct(known, 50)} / {_pct(known, 95)} | "
            f"{sum(p['found'] == p['true'] for p in per)} / {len(per)}, {false} |"
        )
    return "\n".join(lines)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=301, help="records (seeds seed0 .. seed0 + n - 1)")
    ap.add_argument("--seed0", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1, help="worker processes")
    ap.add_argument("--name", default="front_end_corpus", help="results file stem")
    args = ap.parse_args(argv)
    seeds = range(args.seed0, args.seed0 + args.n)
    t0 = time.perf_counter()
    rows = []

    def done(row):
        rows.append(row)
        flag = "ok" if row["success"] else ("not resolvable" if not row["resolvable"] else "FAILED")
        print(
            f"[{len(rows)}/{len(seeds)}] seed {row['seed']} {row['class']} {row['excitation']}: modes {flag}, "
            f"noise {sum(noise_ok(x) for x in row['noise'])}/{len(row['noise'])}, {row['seconds']:.1f} s",
            flush=True,
        )

    if args.jobs > 1:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(args.jobs) as pool:
            for row in pool.map(score, seeds):
                done(row)
    else:
        for s in seeds:
            done(score(s))
    wall = time.perf_counter() - t0
    command = f"python benchmarks/front_end_corpus.py --n {args.n} --seed0 {args.seed0}"
    text = table(rows)
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(
        json.dumps({"command": command, "wall_s": wall, "rows": rows}, indent=1, default=float)
    )
    (RESULTS / f"{args.name}.md").write_text(f"{text}\n\nRegenerate: `{command}` ({wall:.0f} s)\n")
    print(text)
    for r in rows:
        if not r["success"] and r["resolvable"] or "crash" in r or "noise_crash" in r:
            print(
                f"seed {r['seed']} {r['class']} {r['excitation']}: found {r['modes_found']} "
                f"true {r['modes_true']} {r.get('error', '')[:200]} {r.get('crash', '')[:300]}"
            )
    print(f"\nregenerate: {command}   ({wall:.0f} s)")


if __name__ == "__main__":
    main()
