"""Command line: ``bayes-update <command> ...`` (also ``python -m bayes_update``).

Commands for any model (:mod:`.commands`): ``calibrate``, ``sample``,
``discrepancy``, ``inspect``; the beam's own (:mod:`.beam`): ``simulate``,
``reproduce``, ``make-dataset``, ``plot-data``.  Every failure the user can
fix is reported in one line with exit status 2; Ctrl-C ends a command with
status 130 and leaves OUT as it was (:mod:`bayes_update.reports.outputs`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bayes_update.cli import beam as beam_cli
from bayes_update.cli import commands
from bayes_update.cli.options import configure_logging
from bayes_update.core.model import ModelError, ModelRunError, ModelSpecError
from bayes_update.data.dataset import DatasetError

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    from bayes_update import __version__

    parser = argparse.ArgumentParser(
        prog="bayes-update",
        description="Probabilistic updating of nonlinear structural models with Volterra series "
        "(after Bussetta, Shiki and da Silva, 2017): calibrate, sample the posterior of, and "
        "find what is missing in a model of your own (--model path.py:NAME) or the paper's "
        "preloaded beam (--model fe|rom) against a data set of vibration tests.",
    )
    parser.add_argument("--version", action="version", version=f"bayes-update {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="command")
    commands.add_commands(sub)
    beam_cli.add_commands(sub)
    return parser


#: errors reported in one line (exit status 2) instead of a traceback; a model run that breaks the
#: contract (ModelRunError: an exception in simulate, NaN, a wrong shape) names the model, theta and remedy
_REPORTED_ERRORS = (ValueError, DatasetError, ModelError, ModelSpecError, ModelRunError, OSError) + beam_cli.FAILURES


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    configure_logging(args)
    try:
        return _run_staged(args)
    except _REPORTED_ERRORS as exc:
        print(f"bayes-update {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"bayes-update {args.command}: interrupted; {_resume_hint(args)}", file=sys.stderr)
        return 130


# commands whose model runs are kept (the run cache, or OUT/cache for reproduce), so that a rerun resumes
_RESUMABLE = ("sample", "calibrate", "reproduce")


def _run_staged(args) -> int:
    """Run a command that writes OUT: results go to a staging folder and reach
    OUT only when the command finishes (:mod:`bayes_update.reports.outputs`); the cache
    of model runs is OUT/cache."""
    from bayes_update.reports.outputs import staged_output

    if getattr(args, "out", None) is None:  # a command that writes no folder (cache)
        return args.func(args)
    args.final_out = Path(args.out)
    args.cache_dir = args.final_out / "cache"
    with staged_output(args.final_out) as staging:
        args.out = staging
        return args.func(args)


def _resume_hint(args) -> str:
    out = getattr(args, "final_out", None)
    if out is None:
        return "nothing was written"
    if args.command in _RESUMABLE and not getattr(args, "no_cache", False):
        if args.command == "reproduce":
            return (
                f"nothing in {out} was changed except {out / 'cache'}, which keeps the model runs "
                "finished so far: rerun the same command to resume"
            )
        from bayes_update.cli.options import run_cache

        # the beam's calibrate is the paper's grids, which keep no runs
        if args.command == "sample" or getattr(args, "model", None) not in beam_cli.BEAM_MODELS:
            return (
                f"nothing in {out} was changed; the model runs finished so far are kept in {run_cache(args)}: "
                "rerun the same command to resume"
            )
    return f"nothing in {out} was changed; rerun the same command to start again"
