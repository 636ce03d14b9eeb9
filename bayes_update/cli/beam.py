"""The beam's part of the command line: its model options (--model fe|rom, mesh,
integrator, bending-stiffness factor), the rig a command runs on, and the
beam's own commands (``simulate``, ``make-dataset``, ``plot-data``,
``reproduce``).  The options and the rig are held in :mod:`.beam_model` and
handed on here."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

import fe
from bayes_update.cli.beam_model import (
    BEAM_MODELS,
    FAILURES,
    add_model_options,
    fe_model_for,
    model_for,
    rig_for,
    stated_factor,
)
from bayes_update.data import signals
from bayes_update.data.dataset import Dataset, Record, SensorError, is_single_velocity
from bayes_update.data.folder import read_dataset, write_dataset
from bayes_update.models.beam.rig import rig_of

__all__ = [
    "BEAM_MODELS",
    "DEFAULT_CHIRP_AMPLITUDE",
    "FAILURES",
    "add_commands",
    "add_model_options",
    "add_parameter_options",
    "check_parameters",
    "cmd_make_dataset",
    "cmd_plot_data",
    "cmd_reproduce",
    "cmd_simulate",
    "default_dataset",
    "fe_model_for",
    "model_for",
    "rig_for",
    "stated_factor",
]

# the paper's high-level chirp on the default (locking-free) rig [N]
DEFAULT_CHIRP_AMPLITUDE = 0.1


def add_parameter_options(p: argparse.ArgumentParser) -> None:
    """The beam's parameters, in the units its model declares (the paper's)."""
    from bayes_update.models.beam.model import UNITS

    d = fe.PAPER_PARAMETERS
    for name, value in (("eta", d.eta / 1e6), ("c", d.c / 1e3), ("F", d.F), ("k-s", d.k_s / 1e3)):
        key = name.replace("-", "_")
        p.add_argument(
            f"--{name}", type=float, default=value, help=f"{key} [{UNITS[key]}] (default {value:g}, the paper's)"
        )


def default_dataset() -> Dataset:
    force = signals.chirp(DEFAULT_CHIRP_AMPLITUDE)
    t = np.arange(force.size) / signals.PAPER_FS
    test = Record("chirp_high.csv", "chirp", "high", "nonlinear", t, force, np.zeros_like(force))
    return Dataset("paper-chirp", signals.PAPER_FS, fe.Rig(), [test])


def _require_beam_sensor(data: Dataset) -> None:
    """Before any beam run: the data set's sensor is the beam's (one velocity sensor), else a
    :class:`SensorError` saying what ``simulate`` needs and what to run instead."""
    if not is_single_velocity(data.sensors):
        raise SensorError(
            f"{data.source or data.name}: `simulate` runs the beam, whose one sensor measures "
            f"velocity; this data set's sensors are {list(data.sensors)}: give it a data set of "
            "the beam rig, or run a model of your own on these records with `bayes-update "
            "calibrate --model file.py:NAME`"
        )


def check_parameters(values: dict) -> list[str]:
    """The beam's parameters as given on the command line (paper units), against its
    prior (the model checks their signs): a ValueError for a value more than 100 prior
    widths above it (a unit slip: eta given in Pa s where the option is MPa s is 1e6 times too large);
    the returned warnings name the values outside the prior but near it (simulated
    as asked: a user may look outside it on purpose)."""
    from bayes_update.models.beam.model import PRIOR, UNITS

    warnings = []
    for name, value in values.items():
        lo, hi = PRIOR[name]
        opt = f"--{name.replace('_', '-')} {value:g}"
        if value > hi + 100 * (hi - lo):
            raise ValueError(
                f"{opt}: {value / hi:.3g} times the prior's upper bound {hi:g} {UNITS[name]}; the option "
                f"is in {UNITS[name]} (the paper's unit): is the value in another unit?"
            )
        if not lo <= value <= hi:
            warnings.append(f"{opt} is outside the prior ({lo:g} .. {hi:g} {UNITS[name]}): simulated as asked")
    return warnings


def cmd_simulate(args) -> int:
    from bayes_update.models.beam.forward import simulate_dataset
    from bayes_update.reports.plots import plot_test

    for warning in check_parameters({"eta": args.eta, "c": args.c, "F": args.F, "k_s": args.k_s}):
        print(f"bayes-update: {warning}", file=sys.stderr)

    data = read_dataset(args.data) if args.data else default_dataset()
    _require_beam_sensor(data)
    rig = rig_for(data, args)
    if rig != rig_of(data):
        import dataclasses

        data = dataclasses.replace(data, rig=rig)
    beam = model_for(args, rig)
    model = beam.fe_model
    params = beam.fe_parameters({"eta": args.eta, "c": args.c, "F": args.F, "k_s": args.k_s})
    start = time.perf_counter()
    out = simulate_dataset(data, model, params)
    elapsed = time.perf_counter() - start
    out.extra["model"] = {**beam.describe(), "parameters_si": params.to_dict()}
    write_dataset(out, args.out)
    for measured, simulated in zip(data.tests, out.tests):
        has_data = args.data is not None
        fig = plot_test(
            measured if has_data else simulated,
            simulated.velocity if has_data else None,
            title=f"{simulated.name}: model at eta={args.eta:g} MPa s, c={args.c:g} N s/mm, "
            f"F={args.F:g} N, k_s={args.k_s:g} N/mm",
        )
        fig.savefig(Path(args.out) / f"{simulated.name}.png", dpi=110)
    modes = model.modal_analysis(params, n_modes=2)
    summary = {
        "elapsed_s": elapsed,
        "tests": [t.file for t in out.tests],
        "P_eff_N": params.effective_preload(rig_of(data)),
        "f1_hz": float(modes.frequencies_hz[0]),
        "zeta1": float(modes.damping_ratios[0]),
    }
    (Path(args.out) / "simulate.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(
        f"simulated {len(out.tests)} test(s) in {elapsed:.2f} s; P_eff = {summary['P_eff_N']:.2f} N, "
        f"f1 = {summary['f1_hz']:.2f} Hz; wrote {args.final_out}"
    )
    return 0


def cmd_reproduce(args) -> int:
    from bayes_update.cli.options import read_config, settings_replaced
    from bayes_update.core.discrepancy import DiscrepancySettings
    from bayes_update.core.posterior import PosteriorSettings
    from bayes_update.models.beam.calibrate import CalibrationSettings
    from bayes_update.reports.beam_study import REPRODUCE_SAMPLE, reproduce

    # --config's tables change the study's own settings (before this, reproduce ignored them)
    quick = args.quick
    study = {
        "calibrate": CalibrationSettings.quick() if quick else CalibrationSettings(),
        "sample": PosteriorSettings.quick() if quick else PosteriorSettings(**REPRODUCE_SAMPLE),
        "discrepancy": DiscrepancySettings.quick() if quick else DiscrepancySettings(),
    }
    settings = {}
    for section, base in study.items():
        table = read_config(args.config, section)
        if table:
            settings[section] = settings_replaced(base, table)
    reproduce(
        args.out,
        quick=args.quick,
        workers=args.workers,
        discrepancy=not args.no_discrepancy,
        cache_dir=args.cache_dir,
        settings=settings,
    )
    print(f"wrote {args.final_out / 'report.md'}")
    return 0


def cmd_make_dataset(args) -> int:
    from bayes_update.models.beam.virtual_rig import DEFAULT_SEED, DEFAULT_SNR_DB, make_dataset

    out = args.out
    start = time.perf_counter()
    rig = None
    if args.hidden:
        from bayes_update.models.beam.model import hidden_effects
        from bayes_update.models.beam.virtual_rig import VirtualRig

        rig = VirtualRig(effects=hidden_effects(args.hidden, args.hidden_seed))
    ds = make_dataset(
        out,
        rig=rig,
        seed=DEFAULT_SEED if args.seed is None else args.seed,
        snr_force_db=DEFAULT_SNR_DB if args.snr_force is None else args.snr_force,
        snr_velocity_db=(DEFAULT_SNR_DB if args.snr_velocity is None else args.snr_velocity),
        imperfection=args.imperfection,
    )
    elapsed = time.perf_counter() - start
    lin = ds.extra["truth"]["linearised"]
    size = sum(f.stat().st_size for f in Path(out).iterdir() if f.is_file())
    print(
        f"wrote {len(ds.tests)} tests to {args.final_out} ({size / 1e6:.2f} MB) in {elapsed:.1f} s; "
        f"f1 = {lin['f1_hz']:.2f} Hz, 35 Hz / f1 = {lin['sine_frequency_over_f1']:.3f}"
    )
    return 0


def cmd_plot_data(args) -> int:

    from bayes_update.data import spectral
    from bayes_update.models.beam.virtual_rig import load_default_dataset
    from bayes_update.reports.plots import plot_frf, plot_psd, plot_test

    data = read_dataset(args.data) if args.data else load_default_dataset()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fs = data.sampling_rate_hz
    written = []

    def save(fig, name):
        fig.savefig(out / name, dpi=110)
        written.append(name)

    chirps, sines = {}, {}
    for t in data.tests:
        save(plot_test(t, title=f"{data.name}: {t.name} ({t.role})"), f"{t.name}.png")
        if t.signal == "chirp":
            est = spectral.transient_frf(t.force, t.velocity, fs)
            chirps[t.name] = est
            save(plot_frf({t.name: est}, title=f"{t.name}: H1 FRF and coherence"), f"{t.name}_frf.png")
        elif t.signal == "sine":
            spec = {f"{t.name} velocity": spectral.psd(t.velocity, fs)}
            sines[t.name] = spec
            freq = t.meta.get("frequency_hz")
            save(plot_psd(spec, harmonics_of=freq, title=f"{t.name}: velocity PSD"), f"{t.name}_psd.png")
    if len(chirps) > 1:
        save(plot_frf(chirps, title="chirp tests: H1 FRF by level (distortion = nonlinearity)"), "chirp_frf.png")
    if len(sines) > 1:
        merged = {name: next(iter(spec.values())) for name, spec in sines.items()}
        freqs = {t.meta.get("frequency_hz") for t in data.tests if t.signal == "sine"}
        save(
            plot_psd(
                merged, harmonics_of=freqs.pop() if len(freqs) == 1 else None, title="sine tests: velocity PSD by level"
            ),
            "sine_psd.png",
        )
    print(f"wrote {len(written)} figure(s) to {args.final_out}")
    return 0


def add_commands(sub) -> None:
    """The beam's commands: simulate, reproduce, make-dataset, plot-data."""
    from bayes_update.cli.options import add_common, add_data_out

    p = sub.add_parser(
        "simulate",
        help="run the beam's FE model on the recorded forces of a data set",
        description="Drive the beam model with each test's recorded force and write the "
        "responses as a data-set folder of the same form, plus a plot per test. "
        "Without --data: the paper's 4 s chirp at the paper's parameters. "
        "Parameters in the units the beam declares (MPa s, N s/mm, N, N/mm).",
    )
    add_data_out(p)
    add_parameter_options(p)
    p.add_argument("--model", default="fe", choices=BEAM_MODELS, help="fe (full FE, default) or rom")
    add_model_options(p)
    add_common(p, seed=False)
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser(
        "reproduce",
        help="the whole beam study on the embedded default data set, with a report",
        description="Deterministic updating (Tables 1-3) with the data set's bending "
        "stiffness factor and with a locking-free beam, f1 against the "
        "preload, the posterior for both, and report.md with every table "
        "and figure, then the discrepancy workflow on a variant of the rig "
        "with a hidden bow. About 10 minutes on 2 cores (--quick: about 2).",
    )
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--quick", action="store_true", help="the modal ROM, coarse grids and small posterior settings")
    p.add_argument(
        "--no-discrepancy",
        action="store_true",
        help="skip the discrepancy workflow on the hidden-effect variant (about 2 minutes)",
    )
    add_common(p, seed=False)
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser(
        "make-dataset",
        help="make a beam data set with the virtual rig",
        description="Run the virtual rig (paper-equivalent rig, bending stiffness "
        "factor 1.24, the paper's Table 3 parameters, 20 elements at "
        "4096 Hz, filtered and decimated to 1024 Hz, noisy) on the "
        "paper's six tests and write the data-set folder. With the "
        "defaults it reproduces the embedded data set byte for byte.",
    )
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--seed", type=int, default=None, help="noise seed (default 2017)")
    p.add_argument(
        "--snr-force", type=float, default=None, metavar="DB", help="force-channel SNR [dB re RMS] (default 40)"
    )
    p.add_argument(
        "--snr-velocity", type=float, default=None, metavar="DB", help="velocity-channel SNR [dB re RMS] (default 40)"
    )
    p.add_argument(
        "--imperfection",
        type=float,
        default=0.0,
        metavar="M",
        help="initial bow of the beam at mid-span [m] (hidden effect; default 0)",
    )
    p.add_argument(
        "--hidden",
        action="append",
        default=[],
        metavar="EFFECT",
        help="hide an effect in the data (initial_imperfection, amplitude_dependent_damping, "
        "shaker_attachment, clamp_compliance), its magnitude drawn from a realistic "
        "range with --hidden-seed; repeatable; recorded in dataset.json's truth block",
    )
    p.add_argument("--hidden-seed", type=int, default=0, help="seed of the hidden magnitudes (default 0)")
    p.set_defaults(func=cmd_make_dataset)

    p = sub.add_parser(
        "plot-data",
        help="plot the tests of a data set (time, FRF, PSD)",
        description="Write PNG figures of a data set: force and velocity of each "
        "test, H1 FRF and coherence of the chirps (each, and the "
        "levels overlaid), velocity PSD of the sines (each, and the "
        "levels overlaid). Without --data: the embedded default data set.",
    )
    add_data_out(p)
    p.set_defaults(func=cmd_plot_data)
