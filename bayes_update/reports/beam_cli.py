"""The beam's part of the command line: its model options (--model fe|rom, mesh,
integrator, bending-stiffness factor), the rig a command runs on, and
``bayes-update simulate``."""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import fe
from fe.model import DEFAULT_ELEMENTS, DEFAULT_RHO_INF, DEFAULT_SUBSTEPS

from bayes_update.data import signals
from bayes_update.data.dataset import Dataset, Record
from bayes_update.data.folder import read_dataset, write_dataset
from bayes_update.models.beam.rig import rig_of

#: what a beam run raises where the point cannot be run (the CLI reports it in one line)
FAILURES = (fe.ConvergenceError,)


# the paper's high-level chirp on the default (locking-free) rig [N]
DEFAULT_CHIRP_AMPLITUDE = 0.1


def add_model_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--model", default="fe", metavar="SPEC",
                   help="fe: the beam's full FE model (default); rom: its modal reduced-order model "
                        "(fe.ModalROM, ~1 ms per run); or your own model, path/to/file.py:NAME or "
                        "package.module:NAME (a class or zero-argument factory with `parameters` and "
                        "`simulate(theta, force, fs)`; docs/models.md; discrepancy needs its "
                        "candidate_effects())")
    p.add_argument("--modes", type=int, default=None,
                   help="modes kept by --model rom (default 3)")
    p.add_argument("--elements", type=int, default=DEFAULT_ELEMENTS,
                   help=f"beam elements (default {DEFAULT_ELEMENTS})")
    p.add_argument("--substeps", type=int, default=DEFAULT_SUBSTEPS,
                   help=f"generalized-alpha steps per sample (default {DEFAULT_SUBSTEPS})")
    p.add_argument("--rho-inf", type=float, default=DEFAULT_RHO_INF,
                   help=f"generalized-alpha spectral radius at infinity (default {DEFAULT_RHO_INF}; "
                        "the paper used 0.01)")


def add_parameter_options(p: argparse.ArgumentParser) -> None:
    d = fe.PAPER_PARAMETERS
    p.add_argument("--eta", type=float, default=d.eta,
                   help=f"deviatoric material viscosity [Pa s] (default {d.eta:g}, the paper's)")
    p.add_argument("--c", type=float, default=d.c, help=f"top damper [N s/m] (default {d.c:g})")
    p.add_argument("--F", type=float, default=d.F, help=f"preload [N] (default {d.F:g})")
    p.add_argument("--k-s", type=float, default=d.k_s, help=f"top spring [N/m] (default {d.k_s:g})")


def add_factor_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--bending-stiffness-factor", type=float, default=None, metavar="X",
                   help="multiply the model's EI by X (default: the data set's "
                        "rig.bending_stiffness_factor, 1.0 when absent; 1.24 reproduces the "
                        "paper's shear-locking mesh)")
    p.add_argument("--override-factor", action="store_true",
                   help="allow --bending-stiffness-factor to differ from the factor the data set states")


BEAM_MODELS = ("fe", "rom")


def model_for(args, rig: fe.Rig):
    """The model the options ask for, on ``rig``."""
    if args.model not in BEAM_MODELS:
        raise ValueError(f"--model {args.model}: `{args.command}` runs the beam models ({', '.join(BEAM_MODELS)}) "
                         "only so far; `bayes-update sample` takes a model of your own")
    if args.model == "rom":
        from fe.rom import DEFAULT_ROM_MODES
        return fe.ModalROM(rig=rig, n_modes=args.modes or DEFAULT_ROM_MODES)
    if args.modes is not None:
        raise ValueError("--modes applies to --model rom only")
    return fe.BeamModel(rig=rig, n_elements=args.elements, substeps=args.substeps, rho_inf=args.rho_inf)


def rig_for(data: Dataset, args) -> fe.Rig:
    """The model's rig: the data set's, with the factor from the command line if given.
    A factor that contradicts the one the data set states needs --override-factor."""
    import dataclasses

    rig = rig_of(data)
    factor = getattr(args, "bending_stiffness_factor", None)
    if factor is None:
        return rig
    stated = stated_factor(data)
    if stated is not None and stated != factor and not args.override_factor:
        raise ValueError(f"the data set states bending_stiffness_factor = {stated:g} but "
                         f"--bending-stiffness-factor {factor:g} was given; pass --override-factor "
                         "to use it anyway (e.g. to calibrate a locking-free model on the "
                         "paper-equivalent data)")
    return dataclasses.replace(rig, bending_stiffness_factor=factor)


def stated_factor(data: Dataset):
    """The factor written in the data set's dataset.json, or None when absent."""
    if data.source is None:
        return None
    path = Path(data.source)
    path = path / "dataset.json" if path.is_dir() else path
    try:
        rig = json.loads(path.read_text()).get("rig", {})
    except (OSError, ValueError):
        return None
    value = rig.get("bending_stiffness_factor")
    return None if value is None else float(value)


def default_dataset() -> Dataset:
    force = signals.chirp(DEFAULT_CHIRP_AMPLITUDE)
    t = np.arange(force.size) / signals.PAPER_FS
    test = Record("chirp_high.csv", "chirp", "high", "nonlinear", t, force, np.zeros_like(force))
    return Dataset("paper-chirp", signals.PAPER_FS, fe.Rig(), [test])


def cmd_simulate(args) -> int:
    params = fe.Parameters(eta=args.eta, c=args.c, F=args.F, k_s=args.k_s)
    from bayes_update.models.beam.forward import simulate_dataset
    from bayes_update.reports.plots import plot_test

    data = read_dataset(args.data) if args.data else default_dataset()
    rig = rig_for(data, args)
    if rig != rig_of(data):
        import dataclasses
        data = dataclasses.replace(data, rig=rig)
    model = model_for(args, rig)
    start = time.perf_counter()
    out = simulate_dataset(data, model, params)
    elapsed = time.perf_counter() - start
    from bayes_update.models.beam.problem import _describe_model
    out.extra["model"] = {**_describe_model(model), "parameters_si": params.to_dict()}
    write_dataset(out, args.out)
    for measured, simulated in zip(data.tests, out.tests):
        has_data = args.data is not None
        fig = plot_test(measured if has_data else simulated,
                        simulated.velocity if has_data else None,
                        title=f"{simulated.name}: model at eta={params.eta:g} Pa s, c={params.c:g} N s/m, "
                              f"F={params.F:g} N, k_s={params.k_s:g} N/m")
        fig.savefig(Path(args.out) / f"{simulated.name}.png", dpi=110)
    modes = model.modal_analysis(params, n_modes=2)
    summary = {"elapsed_s": elapsed, "tests": [t.file for t in out.tests],
               "P_eff_N": params.effective_preload(rig_of(data)),
               "f1_hz": float(modes.frequencies_hz[0]), "zeta1": float(modes.damping_ratios[0])}
    (Path(args.out) / "simulate.json").write_text(json.dumps(summary, indent=2) + "\n")
    print(f"simulated {len(out.tests)} test(s) in {elapsed:.2f} s; P_eff = {summary['P_eff_N']:.2f} N, "
          f"f1 = {summary['f1_hz']:.2f} Hz; wrote {args.final_out}")
    return 0
