"""Success rate of the discrepancy workflow over hidden-effect data sets.

    python benchmarks/discrepancy_cases.py [--seeds 0 1 2] [--quick] [--cases ...]

For each seed and each case (the four effects hidden in turn, none, and a bow
plus amplitude-dependent damping), a data set from the virtual rig (20
elements at 4096 Hz, 40 dB noise on both channels; the two updating chirps,
the medium chirp and the high sine for validation) with magnitudes drawn
from bayes_update.models.beam.model.HIDDEN_EFFECT_RANGES, then the whole workflow
(deterministic start on coarse grids, baseline, naming, re-update) on the
default FE model (:func:`bayes_update.find_discrepancy` with the beam as a
model of the contract).  A case succeeds when the named effects are the hidden
ones (none for "none"; for the combined case, both or the stronger), e_lin +
e_nlin and the validation misfit shrink by at least 50 %, and every hidden
parameter lies within 2 Laplace sd of its fitted value.  Two more cases on a
structure of another form than its model (``FORM_CASES``: a continuous cantilever
with a compliant clamp fitted by a two-mode model, tests/cantilever_kit.py):
without a catalogue effect nothing may be named; with a tip spring, ``tip_cubic``
must be the decisive candidate and be named exactly when it predicts the held-out
tests better; the gap each leaves is reported.  Three on an electronic oscillator
behind input and output filters fitted by a Duffing model without them
(``CIRCUIT_CASES``, tests/circuit_kit.py), the rig with neither, one or both of a
quadratic stiffness and a velocity-growing damping the model offers as candidates:
named exactly the rig's, each held-out test predicted better, every named parameter
within 2 sd of the rig's, the filters' gap reported.

Writes benchmarks/results/discrepancy_cases.md and
benchmarks/results/discrepancy_cases.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from _machine import machine  # noqa: E402

from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy  # noqa: E402
from bayes_update.core.effects import DECISIVE  # noqa: E402
from bayes_update.models.beam.model import (  # noqa: E402
    beam_model,
    effect_values,
    hidden_effects,  # noqa: E402
)
from bayes_update.models.beam.virtual_rig import PAPER_TESTS, VirtualRig, make_dataset  # noqa: E402

CASES = {
    "initial_imperfection": ["initial_imperfection"],
    "amplitude_dependent_damping": ["amplitude_dependent_damping"],
    "shaker_attachment": ["shaker_attachment"],
    "clamp_compliance": ["clamp_compliance"],
    "none": [],
    "combined": ["initial_imperfection", "amplitude_dependent_damping"],
}
TESTS = [t for t in PAPER_TESTS if t.name in ("chirp_low", "chirp_high", "chirp_medium", "sine_high")]
#: a structure of another form than the model (tests/cantilever_kit.py: a continuous cantilever with a
#: compliant clamp and a tip mass, fitted by a two-mode model): its tip spring k3 [N/m^3], 0 for none
FORM_CASES = {"cantilever_none": 0.0, "cantilever_cubic": 4.0e6}
#: an oscillator behind filters its Duffing model lacks (tests/circuit_kit.py): the rig's quadratic
#: stiffness k2 [1/V] and velocity-growing damping nu [s^2/V^2], the effects named where non-zero
CIRCUIT_CASES = {
    "circuit_none": {"k2": 0.0, "nu": 0.0},
    "circuit_k2": {"k2": -0.1, "nu": 0.0},
    "circuit_both": {"k2": -0.1, "nu": 2.0e-5},
}
CIRCUIT_EFFECTS = {"k2": "quadratic_stiffness", "nu": "velocity_damping"}


def judge(case, effects, res) -> dict:
    hidden = [e.name for e in effects]
    named = list(res.named)
    if case == "none":
        named_ok = named == []
    elif case == "combined":
        named_ok = bool(named) and set(named) <= set(hidden)
    else:
        named_ok = named == hidden
    b, a = res.gap_before, res.gap_after
    # a gap already at the noise floor (the null case: validation beyond its noise is 0) cannot shrink
    shrink_e = 1 - (a["e_lin"] + a["e_nlin"]) / (b["e_lin"] + b["e_nlin"]) if b["e_lin"] + b["e_nlin"] > 0 else 0.0
    shrink_v = (
        1 - a["held_out_error_beyond_noise"] / b["held_out_error_beyond_noise"]
        if b["held_out_error_beyond_noise"] > 0
        else 0.0
    )
    final = res.to_json()["final_mode"]["effects"]
    inside = []
    for e in effects:
        if e.name not in final:
            continue
        for name, t in effect_values(e).items():
            f = final[e.name][name]
            inside.append(
                {
                    "effect": e.name,
                    "parameter": name,
                    "truth": t,
                    "mode": f["mode"],
                    "sd": f["sd"],
                    "inside": abs(f["mode"] - t) <= 2 * f["sd"],
                }
            )
    gap_ok = case == "none" or (shrink_e >= 0.5 and shrink_v >= 0.5)
    return {
        "case": case,
        "hidden": [dict({"name": e.name}, **e.parameters()) for e in effects],
        "named": named,
        "named_ok": named_ok,
        "shrink_e": shrink_e,
        "shrink_validation": shrink_v,
        "parameters": inside,
        "success": named_ok and gap_ok and all(r["inside"] for r in inside),
        "time_s": res.timing["total"],
        "gap_before": b,
        "gap_after": a,
        "evidence": [{k: c[k] for k in ("name", "two_ln_B")} for c in res.rounds[0]["candidates"]],
        "pairs": [
            {k: c[k] for k in ("names", "two_ln_B", "partner_alone", "named")}
            for rnd in res.rounds
            for c in rnd.get("pairs", [])
        ],
    }


def evidence(res) -> list:
    """The first round's candidates: name, 2 ln B and each held-out test's error before / after."""
    return [
        {"name": c["name"], "two_ln_B": c["two_ln_B"], "held_out": (c["held_out"] or {}).get("tests")}
        for c in res.rounds[0]["candidates"]
    ]


def judge_form(case, res) -> dict:
    """A model-form case: with the tip spring, tip_cubic the decisive candidate and named exactly
    when it predicts the held-out tests better (the naming rule: a two-mode model may carry a
    real spring into a held-out test wrongly); without it, nothing named; either way the gap
    that remains reported (a two-mode model of a continuous beam always leaves one)."""
    hidden = ["tip_cubic"] if FORM_CASES[case] else []
    b, a = res.gap_before, res.gap_after
    shrink_v = 1 - a["held_out_error_beyond_noise"] / b["held_out_error_beyond_noise"]
    if hidden:
        best = res.rounds[0]["candidates"][0]
        improves = bool(best["held_out"] and best["held_out"]["improves"])
        named_ok = (
            best["name"] == "tip_cubic"
            and best["two_ln_B"] is not None
            and best["two_ln_B"] > DECISIVE
            and list(res.named) == (hidden if improves else [])
        )
    else:
        named_ok = list(res.named) == []
    success = named_ok and (not res.named or shrink_v > 0)
    k3 = res.to_json()["final_mode"]["effects"].get("tip_cubic", {}).get("k3")
    return {
        "case": case,
        "hidden": [{"name": "tip_cubic", "k3": FORM_CASES[case] / 1e6}] if hidden else [],
        "named": list(res.named),
        "named_ok": named_ok,
        "shrink_e": 1 - a["e_sum"] / b["e_sum"],
        "shrink_validation": shrink_v,
        "parameters": [
            {
                "effect": "tip_cubic",
                "parameter": "k3",
                "truth": FORM_CASES[case] / 1e6,
                "mode": k3["mode"],
                "sd": k3["sd"],
                "inside": abs(k3["mode"] - FORM_CASES[case] / 1e6) <= 2 * k3["sd"],
            }
        ]
        if k3
        else [],
        "success": success,
        "time_s": res.timing["total"],
        "gap_before": b,
        "gap_after": a,
        "gap_sentence": res.gap_sentence(),
        "detectable_from": {e: d["detectable_from"] for e, d in res.detectability.items()},
        "evidence": evidence(res),
        "pairs": [],
    }


def run_circuit_case(case, settings):
    """A circuit case: named exactly the rig's effects, each held-out test predicted better
    where any is named, every named parameter within 2 sd of the rig's, the gap reported."""
    sys.path.insert(0, str(ROOT / "tests"))
    import circuit_kit

    rig = CIRCUIT_CASES[case]
    data = circuit_kit.make_dataset(circuit_kit.SET_A + circuit_kit.HELD_OUT, **rig)
    res = find_discrepancy(
        data, circuit_kit.OscillatorWithCandidates(), settings=settings, workers=2, progress=False, log=lambda *a: None
    )
    hidden = [CIRCUIT_EFFECTS[k] for k, v in rig.items() if v]
    b, a = res.gap_before, res.gap_after
    effects = res.to_json()["final_mode"]["effects"]
    pars = []
    for k, v in rig.items():
        fitted = effects.get(CIRCUIT_EFFECTS[k], {}).get(k)
        if fitted:
            pars.append(
                {
                    "effect": CIRCUIT_EFFECTS[k],
                    "parameter": k,
                    "truth": v,
                    "mode": fitted["mode"],
                    "sd": fitted["sd"],
                    "inside": abs(fitted["mode"] - v) <= 2 * fitted["sd"],
                }
            )
    held = [r["held_out"]["tests"] for rnd in res.rounds for r in rnd["candidates"] if r["name"] in res.named]
    better = all(v["after"] < v["before"] for h in held for v in h.values())
    named_ok = sorted(res.named) == sorted(hidden)
    return {
        "case": case,
        "hidden": [{"name": CIRCUIT_EFFECTS[k], k: v} for k, v in rig.items() if v],
        "named": list(res.named),
        "named_ok": named_ok,
        "shrink_e": 1 - a["e_sum"] / b["e_sum"],
        "shrink_validation": 1 - a["held_out_error_beyond_noise"] / b["held_out_error_beyond_noise"],
        "parameters": pars,
        "success": named_ok and better and all(p["inside"] for p in pars),
        "time_s": res.timing["total"],
        "gap_before": b,
        "gap_after": a,
        "gap_sentence": res.gap_sentence(),
        "evidence": evidence(res),
        "pairs": [],
    }


def run_form_case(case, settings):
    sys.path.insert(0, str(ROOT / "tests"))
    import cantilever_kit

    data = cantilever_kit.make_dataset(k3=FORM_CASES[case])
    res = find_discrepancy(
        data, cantilever_kit.TwoModes(), settings=settings, workers=2, progress=False, log=lambda *a: None
    )
    return judge_form(case, res)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--cases", nargs="+", default=list(CASES) + list(FORM_CASES) + list(CIRCUIT_CASES))
    ap.add_argument(
        "--resume",
        action="store_true",
        help="keep the cases already in results/discrepancy_cases.json (an interrupted run)",
    )
    args = ap.parse_args(argv)
    settings = DiscrepancySettings.quick() if args.quick else DiscrepancySettings()
    saved = ROOT / "benchmarks" / "results" / "discrepancy_cases.json"
    rows = json.loads(saved.read_text()) if args.resume and saved.exists() else []
    done = {(r["seed"], r["case"]) for r in rows}
    t_all = time.perf_counter() - sum(r["time_s"] for r in rows)
    for seed in args.seeds:
        for case in args.cases:
            if (seed, case) in done:
                continue
            if case in FORM_CASES:
                row = run_form_case(case, settings)
            elif case in CIRCUIT_CASES:
                row = run_circuit_case(case, settings)
            else:
                effects = hidden_effects(CASES[case], seed=seed)
                data = make_dataset(rig=VirtualRig(effects=effects), tests=TESTS, seed=100 + seed)
                res = find_discrepancy(
                    data, beam_model(data), settings=settings, workers=2, progress=False, log=lambda *a: None
                )
                row = judge(case, effects, res)
                row["gap_sentence"] = res.gap_sentence()
            row["seed"] = seed
            rows.append(row)
            print(
                f"seed {seed} {case}: named {row['named']}, e shrink {100 * row['shrink_e']:.0f} %, validation "
                f"shrink {100 * row['shrink_validation']:.0f} %, parameters inside "
                f"{[r['inside'] for r in row['parameters']]}, {row['time_s']:.0f} s -> "
                f"{'OK' if row['success'] else 'FAIL'}",
                flush=True,
            )
            (ROOT / "benchmarks" / "results" / "discrepancy_cases.json").write_text(
                json.dumps(rows, indent=1, default=float)
            )
    ok = sum(r["success"] for r in rows)
    lines = [
        "# Discrepancy workflow over hidden-effect data sets",
        "",
        f"`python benchmarks/discrepancy_cases.py --seeds {' '.join(map(str, args.seeds))}"
        f"{' --quick' if args.quick else ''}`; {machine()}; {time.perf_counter() - t_all:.0f} s",
        "",
        f"**{ok} of {len(rows)} cases succeed** (the beam's: named right, both gaps shrink >= 50 %, hidden "
        "parameters within 2 sd; the cantilever's, a structure of another form than its two-mode model: nothing "
        "named without the tip spring; with it, tip_cubic the decisive candidate and named exactly when it "
        "predicts the held-out tests better; the circuit's, an oscillator behind filters its model lacks: named "
        "exactly the rig's effects, each held-out test better, parameters within 2 sd)",
        "",
        "| seed | case | hidden | named | 2 ln B of the best | e_lin+e_nlin before -> after | held-out error "
        "beyond noise before -> after | parameters (truth / fitted +- sd) | time | result |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        hid = (
            "; ".join(
                ", ".join(
                    f"{k} {v:.3g}"
                    for k, v in h.items()
                    if k not in ("name", "kind", "velocity_scale", "friction_force")
                )
                for h in r["hidden"]
            )
            or "-"
        )
        pars = "; ".join(
            f"{p['parameter']} {p['truth']:.3g} / {p['mode']:.3g} +- {p['sd']:.2g}" for p in r["parameters"]
        )
        b, a = r["gap_before"], r["gap_after"]
        lines.append(
            f"| {r['seed']} | {r['case']} | {hid} | {', '.join(r['named']) or 'none'} | "
            f"{r['evidence'][0]['two_ln_B']:.1f} ({r['evidence'][0]['name']}) | "
            f"{100 * (b['e_lin'] + b['e_nlin']):.2f} % -> {100 * (a['e_lin'] + a['e_nlin']):.2f} % | "
            f"{100 * b['held_out_error_beyond_noise']:.2f} % -> "
            f"{100 * a['held_out_error_beyond_noise']:.2f} % | {pars or '-'} | "
            f"{r['time_s']:.0f} s | {'OK' if r['success'] else 'FAIL'} |"
        )
    lines += ["", "What each case leaves (the workflow's own sentence):", ""]
    lines += [f"- {r['case']}: {r['gap_sentence']}" for r in rows if r.get("gap_sentence")]
    lines += [
        f"- {r['case']}, {e['name']} on the held-out tests: "
        + ", ".join(f"{t} {100 * v['before']:.1f} -> {100 * v['after']:.1f} %" for t, v in e["held_out"].items())
        for r in rows
        for e in r["evidence"]
        if r["case"] not in CASES and e.get("held_out")
    ]
    (ROOT / "benchmarks" / "results" / "discrepancy_cases.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
