"""The beam's model on the command line: its options (``--model fe|rom``, mesh,
integrator, bending-stiffness factor), the model of the contract they ask for,
and the rig a command runs on (the data set's, its factor checked against the
one ``dataset.json`` states).  Apart from :mod:`bayes_update.cli.beam` (the beam's own
commands): the commands for any model use these too."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import fe
from bayes_update.data.dataset import Dataset
from bayes_update.models.beam.rig import rig_of
from fe.model import DEFAULT_ELEMENTS, DEFAULT_RHO_INF, DEFAULT_SUBSTEPS

#: what a beam run raises where the point cannot be run (the CLI reports it in one line)
FAILURES = (fe.ConvergenceError,)


def add_model_options(p: argparse.ArgumentParser) -> None:
    """The beam's model options (used with --model fe|rom)."""
    g = p.add_argument_group("the beam's model (--model fe or rom)")
    g.add_argument("--modes", type=int, default=None, help="modes kept by --model rom (default 3)")
    g.add_argument("--elements", type=int, default=DEFAULT_ELEMENTS, help=f"beam elements (default {DEFAULT_ELEMENTS})")
    g.add_argument(
        "--substeps",
        type=int,
        default=DEFAULT_SUBSTEPS,
        help=f"generalized-alpha steps per sample (default {DEFAULT_SUBSTEPS})",
    )
    g.add_argument(
        "--rho-inf",
        type=float,
        default=DEFAULT_RHO_INF,
        help=f"generalized-alpha spectral radius at infinity (default {DEFAULT_RHO_INF}; the paper used 0.01)",
    )
    g.add_argument(
        "--bending-stiffness-factor",
        type=float,
        default=None,
        metavar="X",
        help="multiply the model's EI by X (default: the data set's "
        "rig.bending_stiffness_factor, 1.0 when absent; 1.24 reproduces the "
        "paper's shear-locking mesh)",
    )
    g.add_argument(
        "--override-factor",
        action="store_true",
        help="allow --bending-stiffness-factor to differ from the factor the data set states",
    )


BEAM_MODELS = ("fe", "rom")


def model_for(args, rig: fe.Rig, prior: dict | None = None):
    """The beam model of the contract the options ask for, on ``rig``, with the
    prior ranges ``prior`` ({name: (low, high)}, paper units)."""
    from bayes_update.models.beam.model import Beam

    return Beam(fe_model_for(args, rig), prior or {})


def fe_model_for(args, rig: fe.Rig):
    """The ``fe`` model the options ask for, on ``rig``."""
    if args.model not in BEAM_MODELS:
        raise ValueError(
            f"--model {args.model}: `{args.command}` runs the beam models ({', '.join(BEAM_MODELS)}) "
            "only so far; `bayes-update sample` takes a model of your own"
        )
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
        raise ValueError(
            f"the data set states bending_stiffness_factor = {stated:g} but "
            f"--bending-stiffness-factor {factor:g} was given; pass --override-factor "
            "to use it anyway (e.g. to calibrate a locking-free model on the "
            "paper-equivalent data)"
        )
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
