"""The beam's detectability limits, checked by the workflow itself.

    python benchmarks/detectability.py [--effects ...] [--factors 2 0.5]

The discrepancy workflow on the embedded default data set (no hidden effect)
reports, for each of the beam's four candidate effects, the smallest magnitude
these tests would name (``detectable_from``, bayes_update.core.detectability:
linearised about the baseline).  Each limit is then checked: the virtual rig of
the default data set (the same tests, noise and seed) with the effect hidden at
``factor`` times the limit, and the whole workflow run on it; at 2x the effect
must be named, at 0.5x nothing.  Writes benchmarks/results/detectability.md and
.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE), str(HERE.parent)]

from _machine import machine  # noqa: E402

from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy  # noqa: E402
from bayes_update.models.beam.effects import effect_from_si  # noqa: E402
from bayes_update.models.beam.model import EFFECT_PARAMETERS, beam_model  # noqa: E402
from bayes_update.models.beam.virtual_rig import VirtualRig, load_default_dataset, make_dataset  # noqa: E402


def _run(data, log=None):
    return find_discrepancy(
        data, beam_model(data), settings=DiscrepancySettings(), workers=2, progress=False, log=log or (lambda *a: None)
    )


def predicted(ladder, magnitude):
    """The linearised (2 ln B, held-out z) at ``magnitude`` (a fraction of the way to the far
    bound), interpolated in log magnitude between the ladder's rungs: what the limit was read
    from, set beside what the workflow then finds."""
    ms = [r["magnitude"] for r in ladder if r["two_ln_B"] is not None]
    if not ms or not ms[0] <= magnitude <= ms[-1]:
        return None, None
    rows = [r for r in ladder if r["two_ln_B"] is not None]
    lm = np.log(ms)
    return (
        float(np.interp(np.log(magnitude), lm, [r["two_ln_B"] for r in rows])),
        float(np.interp(np.log(magnitude), lm, [r["held_out_z"] or 0.0 for r in rows])),
    )


def _write(limits, rows, wall_s, ladders=None):
    """Write the table so far (after every row: a long run stopped early keeps what it measured)."""
    out = {"machine": machine(), "limits": limits, "rows": rows, "wall_s": wall_s, "ladders": ladders}
    (HERE / "results" / "detectability.json").write_text(json.dumps(out, indent=1, default=float))
    lines = [
        "# Detectability of the beam's candidate effects (benchmarks/detectability.py)",
        "",
        f"{machine()}; {out['wall_s']:.0f} s.  Limits from the workflow on the default data set; each checked by "
        "the workflow on the virtual rig with the effect hidden at a multiple of its limit.",
        "",
        "| effect | detectable from | at | named | 2 ln B of it (linearised) | held-out gain [sd] (linearised) "
        "| as it should |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lim = r["limit_text"]
        if "factor" not in r:
            lines.append(f"| {r['effect']} | {lim} | - | - | - | - | - |")
            continue
        z = r["held_out_z"].get(r["effect"])
        b_lin, z_lin = r.get("predicted", (None, None))
        lines.append(
            f"| {r['effect']} | {lim} | {r['factor']:g}x | {', '.join(r['named']) or 'none'} | "
            f"{r['evidence'].get(r['effect'], float('nan')):.1f} ({_f(b_lin)}) | "
            f"{_f(z)} ({_f(z_lin)}) | {'yes' if r['ok'] else 'NO'} |"
        )
    (HERE / "results" / "detectability.md").write_text("\n".join(lines) + "\n")
    return lines


def _f(v):
    return "-" if v is None else f"{v:.1f}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--effects", nargs="+", default=list(EFFECT_PARAMETERS))
    ap.add_argument("--factors", nargs="+", type=float, default=[2.0, 0.5])
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    default = load_default_dataset()
    base = _run(default)
    limits = {e: d["detectable_from"] for e, d in base.detectability.items()}
    texts = {e: d["text"] for e, d in base.detectability.items()}
    ladders = {e: d["ladder"] for e, d in base.detectability.items()}
    magnitudes = {e: d["magnitude"] for e, d in base.detectability.items()}
    print("limits:", texts, flush=True)
    rows = []
    for effect in a.effects:
        lim = limits.get(effect)
        if lim is None:
            rows.append({"effect": effect, "limit": None, "limit_text": texts[effect]})
            continue
        for factor in a.factors:
            si = [factor * lim[p[0]] * p[4] for p in EFFECT_PARAMETERS[effect]]
            data = make_dataset(rig=VirtualRig(effects=(effect_from_si(effect, si),)))
            res = _run(data)
            row = {
                "effect": effect,
                "limit": lim,
                "limit_text": texts[effect],
                "factor": factor,
                "named": list(res.named),
                "expected": [effect] if factor > 1 else [],
                "evidence": {c["name"]: c["two_ln_B"] for c in res.rounds[0]["candidates"]},
                "held_out_z": {c["name"]: (c["held_out"] or {}).get("z") for c in res.rounds[0]["candidates"]},
                "time_s": res.timing["total"],
                "predicted": predicted(ladders[effect], factor * magnitudes[effect]),
            }
            row["ok"] = row["named"] == row["expected"]
            rows.append(row)
            _write(limits, rows, time.perf_counter() - t0, ladders)
            print(f"{effect} at {factor}x the limit: named {row['named']} -> {'OK' if row['ok'] else 'NO'}", flush=True)
    print("\n".join(_write(limits, rows, time.perf_counter() - t0, ladders)))


if __name__ == "__main__":
    main()
