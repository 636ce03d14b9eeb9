"""Options every command shares, the settings file (``--config``) and the log setup."""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path

__all__ = [
    "add_common",
    "add_data_out",
    "add_metrics",
    "add_model",
    "add_posterior_options",
    "configure_logging",
    "add_scheduler",
    "read_config",
    "settings_from",
    "settings_replaced",
]


def add_data_out(p: argparse.ArgumentParser, out_required: bool = True) -> None:
    p.add_argument(
        "--data",
        type=Path,
        default=None,
        help="data-set folder (dataset.json + one CSV per test; docs/data_format.md); "
        "default: the beam's embedded data set",
    )
    p.add_argument("--out", type=Path, required=out_required, help="output folder")


def add_cache(p: argparse.ArgumentParser) -> None:
    """--cache DIR and --no-cache: where the command keeps its model runs (every command
    given the same folder shares them: bayes_update.core.runs)."""
    p.add_argument(
        "--cache",
        type=Path,
        default=None,
        metavar="DIR",
        help="folder of the run cache (default: $BAYES_UPDATE_CACHE, else ~/.cache/bayes-update): "
        "every model run is kept there as it ends, so that the same command run again, "
        "interrupted or not, makes none of them again, and sample after calibrate on the "
        "same data and model starts from calibrate's runs",
    )
    p.add_argument("--no-cache", action="store_true", help="keep no model run on disk (none is reused)")


def run_cache(args):
    """The run cache folder of a command's options (:func:`add_cache`), or None."""
    if getattr(args, "no_cache", False):
        return None
    from bayes_update.core.runs import default_root

    return args.cache if getattr(args, "cache", None) is not None else default_root()


def add_common(p: argparse.ArgumentParser, seed: bool = True) -> None:
    """--workers, --seed, --config and the log options."""
    p.add_argument(
        "--workers", type=int, default=None, help="processes for the model runs (default: all cores; 1 = serial)"
    )
    if seed:
        p.add_argument("--seed", type=int, default=None, help="seed of every random choice (default 0)")
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE.toml",
        help="settings file: a [calibrate], [sample] or [discrepancy] table whose keys are the "
        "command's settings (e.g. [sample] n_walkers = 48, n_steps = 20000); options on the "
        "command line win",
    )
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quiet", "-q", action="store_true", help="warnings and errors only")
    g.add_argument("--verbose", "-v", action="store_true", help="debug messages too")
    p.add_argument("--log-file", type=Path, default=None, help="also write the log to this file")


def add_scheduler(p: argparse.ArgumentParser) -> None:
    """--scheduler: the model runs on a Dask cluster."""
    p.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="a Dask scheduler (e.g. tcp://10.0.0.5:8786): the model runs go to its workers "
        "instead of local processes (--workers is then ignored); needs dask[distributed]",
    )


def add_model(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--model",
        default="fe",
        metavar="SPEC",
        help="the model to update: path/to/file.py:NAME or package.module:NAME (a class or "
        "zero-argument factory with `parameters` and `simulate(theta, force, fs)`; "
        "docs/models.md), or the beam: fe (its full FE model, the default) or rom (its "
        "modal reduced-order model, ~1 ms per run)",
    )
    p.add_argument(
        "--prior",
        action="append",
        default=[],
        metavar="NAME=LO:HI",
        help="change one parameter's prior range, in the unit the model declares for it "
        "(the beam: eta MPa s, c N s/mm, F N, k_s N/mm), e.g. --prior F=20:95; repeatable (the beam's "
        "calibrate searches the paper's grids instead and refuses it)",
    )


def add_metrics(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--metrics",
        choices=("paper", "full"),
        default=None,
        help="metric set: paper (e_lin on y1 of the linear test, e_nlin on y2 + y3 of the "
        "nonlinear one; the beam's default) or full (the whole projection of each test, "
        "weighted by its noise; the default for any other model)",
    )


def add_posterior_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--walkers",
        type=int,
        default=None,
        help="emcee walkers (PosteriorSettings.n_walkers; direct_walkers with --direct)",
    )
    p.add_argument(
        "--steps",
        type=int,
        default=None,
        help="emcee steps per walker on the surrogate (PosteriorSettings.n_steps; direct_steps with --direct)",
    )
    p.add_argument(
        "--predictive",
        type=int,
        default=None,
        metavar="N",
        help="model runs at N posterior draws: predictive bands and the surrogate's check "
        "(PosteriorSettings.n_predictive; default 0, 32 is a good size)",
    )
    p.add_argument(
        "--sensitivity",
        type=int,
        default=None,
        metavar="N",
        help="global Sobol' indices from a GP on N model runs over the prior box "
        "(PosteriorSettings.n_global; default 0, 128 is a good size)",
    )


def read_config(path: Path | None, section: str) -> dict:
    """The ``[section]`` table of a TOML settings file ({} without a file)."""
    if path is None:
        return {}
    import tomllib

    try:
        doc = tomllib.loads(Path(path).read_text())
    except OSError as exc:
        raise ValueError(f"--config {path}: cannot read it ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ValueError(f"--config {path}: not valid TOML ({exc})") from None
    unknown = sorted(set(doc) - {"calibrate", "sample", "discrepancy"})
    if unknown:
        raise ValueError(f"--config {path}: unknown table(s) {unknown}; use [calibrate], [sample] or [discrepancy]")
    table = doc.get(section, {})
    if not isinstance(table, dict):
        raise ValueError(f"--config {path}: [{section}] must be a table of settings")
    return table


def settings_from(cls, quick: bool, config: dict, **overrides):
    """``cls.quick(...)`` or ``cls(...)`` with the config file's keys, then the
    command line's (``overrides`` that are not None); unknown keys are named."""
    import dataclasses

    known = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(config) - known)
    if unknown:
        raise ValueError(f"--config: unknown {cls.__name__} setting(s) {unknown}; known: {sorted(known)}")
    kw = {**config, **{k: v for k, v in overrides.items() if v is not None}}
    return cls.quick(**kw) if quick else cls(**kw)


def settings_replaced(base, config: dict):
    """``base`` (a settings dataclass) with the config file's keys; unknown keys are named."""
    import dataclasses

    known = {f.name for f in dataclasses.fields(base)}
    unknown = sorted(set(config) - known)
    if unknown:
        raise ValueError(f"--config: unknown {type(base).__name__} setting(s) {unknown}; known: {sorted(known)}")
    return dataclasses.replace(base, **config)


def configure_logging(args) -> None:
    """The package's log (``bayes_update``) to stderr at INFO (WARNING with
    --quiet, DEBUG with --verbose), and to --log-file when given."""
    log = logging.getLogger("bayes_update")
    for h in list(log.handlers):
        log.removeHandler(h)
    level = (
        logging.WARNING
        if getattr(args, "quiet", False)
        else logging.DEBUG
        if getattr(args, "verbose", False)
        else logging.INFO
    )
    log.setLevel(level)
    log.propagate = False
    console = logging.StreamHandler(sys.stderr)
    console.setFormatter(logging.Formatter("%(message)s"))
    log.addHandler(console)
    if getattr(args, "log_file", None) is not None:
        f = logging.FileHandler(args.log_file)
        f.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(message)s"))
        log.addHandler(f)
