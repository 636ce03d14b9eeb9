"""The commands that take no model: ``inspect`` (a first look at a data set) and
``cache`` (what the run cache holds, and clearing it).  Apart from
:mod:`.commands`, whose commands run a model: these read a data set or a folder
of kept runs only."""

from __future__ import annotations

import json
from pathlib import Path

from bayes_update.cli.options import add_common, add_data_out
from bayes_update.data.folder import read_dataset


def add_inspect_command(sub) -> None:
    """The ``inspect`` command's parser."""
    p = sub.add_parser(
        "inspect",
        help="a first look at a data set, no model needed",
        description="The noise of every channel of every test and how it was found, the "
        "excited band, the modes of the linear test, how each mode's frequency and "
        "damping move with the level, and warnings (offsets, drift, clipping, "
        "coherence). Writes inspection.json and figures (FRF per sensor by level "
        "with coherence, noise spectra against the response, the modes' level "
        "dependence). Without --data: the beam's embedded default data set.",
    )
    add_data_out(p)
    add_common(p, seed=False)
    p.set_defaults(func=cmd_inspect)


def add_cache_command(sub) -> None:
    """The ``cache`` command's parser."""
    p = sub.add_parser(
        "cache",
        help="what the run cache holds; --clear to free it",
        description="The folder of kept model runs (--cache DIR, else $BAYES_UPDATE_CACHE, else "
        "~/.cache/bayes-update), how many runs of how many models, and their size. "
        "With --clear, delete them (all, or with --older-than DAYS those last written "
        "before); a command run afterwards makes its runs again.",
    )
    p.add_argument("--cache", type=Path, default=None, metavar="DIR", help="the cache folder (default: as above)")
    p.add_argument("--clear", action="store_true", help="delete the kept runs")
    p.add_argument(
        "--older-than",
        type=float,
        default=None,
        metavar="DAYS",
        help="with --clear: only the runs last written more than DAYS days ago",
    )
    p.set_defaults(func=cmd_cache)


def cmd_cache(args) -> int:
    from bayes_update.core.runs import clear_runs, default_root, runs_usage

    if args.older_than is not None and not args.clear:
        raise ValueError("--older-than goes with --clear")
    root = args.cache if args.cache is not None else default_root()
    if args.clear:
        n, freed = clear_runs(root, args.older_than)
        print(f"deleted {n} runs ({freed / 1e6:.1f} MB) from {Path(root) / 'runs'}")
    u = runs_usage(root)
    age = "" if u["oldest_days"] is None else f", the oldest {u['oldest_days']:.1f} days old"
    print(f"{u['folder']}: {u['runs']} runs of {u['models']} model(s), {u['bytes'] / 1e6:.1f} MB{age}")
    return 0


def cmd_inspect(args) -> int:
    from bayes_update.reports.inspection import write_inspection

    if args.data is None:
        from bayes_update.models.beam.virtual_rig import load_default_dataset

        data = load_default_dataset()
    else:
        data = read_dataset(args.data)
    paths = write_inspection(data, args.out)
    doc = json.loads(paths["inspection.json"].read_text())
    for name, t in doc["tests"].items():
        noise = ", ".join(
            f"{ch} {v['sd']:.3g} ({v['method']})" if v["sd"] is not None else f"{ch} unknown"
            for ch, v in t["noise"].items()
        )
        band = t.get("excited_band_hz")
        print(f"{name}: band {band[0]:.1f}-{band[1]:.1f} Hz; noise sd: {noise}" if band else f"{name}: {noise}")
        if t.get("distortion") and "sensors" in t["distortion"]:
            print(f"  {_distortion_line(t['distortion'])}")
    print(
        "modes of the linear test: "
        + (", ".join(f"{m['freq_hz']:.3f} Hz (zeta {m['damping_ratio']:.4f})" for m in doc["modes"]) or "none found")
    )
    for w in doc["warnings"]:
        print(f"WARNING: {w}")
    print(f"wrote {args.final_out}")
    return 0


def _distortion_line(d: dict) -> str:
    """One line on a periodic test's unexcited lines or a sweep's harmonics: each class's level
    where detected."""
    found = [
        f"{sensor} {cls} {r['level_db']:.0f} dB"
        for sensor, classes in d["sensors"].items()
        for cls, r in classes.items()
        if r["detected"] and cls != "noise"
    ]
    classes = "/".join(c for c in d["classes"] if c != "noise")
    what = ", ".join(found) if found else "at the noise on every sensor"
    if "sweep" in d:
        lo, hi = d["sweep"]["f0_hz"]
        return f"distortion in the sweep's {classes} harmonics ({lo:.1f}-{hi:.1f} Hz; dB of the output): {what}"
    return f"distortion on the unexcited {classes} lines ({d['periods']} periods; dB of the output): {what}"
