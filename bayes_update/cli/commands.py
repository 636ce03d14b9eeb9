"""The commands that take any model: ``calibrate``, ``sample``, ``discrepancy``.

``--model`` names the model: a file or module of your own, or the beam (``fe``,
``rom``; its options in :mod:`bayes_update.cli.beam`).  Settings come from
the command's defaults (``--quick``: small ones), then ``--config FILE.toml``,
then the options on the command line.
"""

from __future__ import annotations

import dataclasses
import json
import sys

from bayes_update.cli import beam as beam_cli
from bayes_update.cli.execution import DASK_PORT, SCHEDULER_TIMEOUT, check_scheduler, executor_from, workers_from
from bayes_update.cli.modelless import add_cache_command, add_inspect_command, cmd_cache, cmd_inspect
from bayes_update.cli.options import (
    add_cache,
    add_common,
    add_data_out,
    add_metrics,
    add_model,
    add_posterior_options,
    add_scheduler,
    read_config,
    run_cache,
    settings_from,
)
from bayes_update.data.folder import read_dataset

__all__ = [
    "DASK_PORT",
    "SCHEDULER_TIMEOUT",
    "add_commands",
    "cmd_cache",
    "cmd_calibrate",
    "cmd_discrepancy",
    "cmd_inspect",
    "cmd_sample",
]


def add_commands(sub) -> None:
    p = sub.add_parser(
        "calibrate",
        help="two-stage deterministic calibration of a model on a data set",
        description="Your own model (--model path.py:NAME): a sensitivity screen picks the "
        "parameters the linear test moves, stage 1 fits them on e_lin, stage 2 "
        "fits all on both tests (least squares from Sobol' starts); "
        "calibration.json holds one key per parameter (its unit), e_lin, e_nlin "
        "and the prediction error on each validation test. The beam (--model "
        "fe|rom): the paper's section 4 on grids, Tables 1-3 with figures. "
        "Without --data: the beam's embedded default data set.",
    )
    add_data_out(p)
    p.add_argument("--quick", action="store_true", help="small designs or coarse grids (a first look, or CI)")
    add_model(p)
    add_metrics(p)
    beam_cli.add_model_options(p)
    add_cache(p)
    add_common(p)
    add_scheduler(p)
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser(
        "sample",
        help="the posterior of a model's parameters (GP surrogate + emcee, or direct)",
        description="Bayesian updating on a data set: the likelihood from the Volterra metrics "
        "of the 'linear' and 'nonlinear' tests with noise and model-error scales "
        "measured at the start, the model's declared uniform prior (--prior to "
        "change it), Gaussian-process surrogates refined where the posterior is, "
        "emcee. Writes posterior.nc (ArviZ), posterior_summary.json, run.json "
        "and figures. Without --data: the beam's embedded default data set.",
    )
    add_data_out(p)
    p.add_argument(
        "--direct",
        action="store_true",
        help="sample on the model itself, no surrogate (for a model of a few ms per run)",
    )
    p.add_argument("--quick", action="store_true", help="small designs and chains (a first look, or CI)")
    p.add_argument(
        "--thorough",
        action="store_true",
        help="the former sizes, some 1200-1400 model runs instead of 230-300 "
        "(PosteriorSettings.thorough: a reference for the default's)",
    )
    add_cache(p)
    add_model(p)
    add_metrics(p)
    add_posterior_options(p)
    beam_cli.add_model_options(p)
    add_common(p)
    add_scheduler(p)
    p.set_defaults(func=cmd_sample)

    add_inspect_command(sub)
    add_cache_command(sub)

    p = sub.add_parser(
        "discrepancy",
        help="find the effect the model misses, add it, show the gap shrink",
        description="After the baseline update, each effect the model offers "
        "(candidate_effects(); the beam's: initial_imperfection, "
        "amplitude_dependent_damping, shaker_attachment, clamp_compliance) is "
        "fitted with its own parameters and ranked by Laplace evidence; one is "
        "named only when 2 ln B > 6, its parameter excludes 'no effect' and it "
        "predicts the validation tests better; then re-update, and the gap that "
        "remains, in numbers. Writes "
        "discrepancy.json, evidence.md and figures. Without --data: the beam's "
        "embedded default data set.",
    )
    add_data_out(p)
    p.add_argument("--quick", action="store_true", help="fewer noise replicates and iterations (CI)")
    p.add_argument(
        "--candidates",
        nargs="+",
        default=None,
        metavar="NAME",
        help="restrict the candidates (default: all the model offers)",
    )
    add_model(p)
    add_metrics(p)
    beam_cli.add_model_options(p)
    add_common(p)
    add_scheduler(p)
    p.set_defaults(func=cmd_discrepancy)


# ------------------------------------------------------------------ the model
def _prior_ranges(items, names) -> dict:
    """{name: (low, high)} from the --prior NAME=LO:HI options; ``names`` are the allowed ones."""
    ranges = {}
    for item in items:
        try:
            name, rng = item.split("=", 1)
            lo, hi = (float(v) for v in rng.split(":"))
        except ValueError:
            raise ValueError(f"--prior {item!r}: expected NAME=LO:HI, e.g. {names[-1]}=0:1") from None
        if name not in names:
            raise ValueError(f"--prior {item!r}: NAME must be one of {', '.join(names)}")
        ranges[name] = (lo, hi)
    return ranges


def _model_and_data(args):
    """(model, data set, space or None, truth or None) the options ask for: the
    beam's truth in its (paper) units, else the data set's ``truth`` block as
    written (:func:`bayes_update.reports.posterior.truth_in_model_units` keeps
    what names the model's parameters in their units).  ``space``: the prior
    that ``--prior`` makes of a model of your own's declared parameters."""
    if args.model in beam_cli.BEAM_MODELS:
        from bayes_update.models.beam.virtual_rig import load_default_dataset, truth_paper_units

        data = read_dataset(args.data) if args.data else load_default_dataset()
        rig = beam_cli.rig_for(data, args)
        data = dataclasses.replace(data, rig=rig)
        model = beam_cli.model_for(args, rig, _prior_ranges(args.prior, ("eta", "c", "F", "k_s")))
        return model, data, None, truth_paper_units(data)
    from bayes_update.core import load_model

    model = load_model(args.model)
    if args.data is None:
        raise ValueError(f"--model {args.model} needs --data: the embedded default data set is the beam's")
    space = _prior_space(model, args.prior)
    data = read_dataset(args.data)
    truth = data.extra.get("truth")
    return model, data, space, truth if isinstance(truth, dict) else None


def _prior_space(model, items):
    """The prior of ``--prior NAME=LO:HI`` options over a model of your own's declared
    parameters (checked first: their names and units are the options'), or None."""
    if not items:
        return None
    from bayes_update.core import ParameterSet
    from bayes_update.core.model import check_contract

    params = {p.name: p for p in check_contract(model).parameters}
    for name, (lo, hi) in _prior_ranges(items, tuple(params)).items():
        try:
            params[name] = dataclasses.replace(params[name], low=lo, high=hi)
        except ValueError as exc:
            raise ValueError(f"--prior {name}={lo:g}:{hi:g}: {exc}") from None
    return ParameterSet(list(params.values()), model)


def _check_first(data, model, space) -> None:
    """The check before any long step (:func:`bayes_update.core.preflight.preflight`), here
    before the first look at the data; the command's own call then finds it done."""
    from bayes_update.core.preflight import preflight

    preflight(data, model, space)


def _first_look(data, out, model) -> None:
    """The data set's first look (``bayes-update inspect``) in OUT/inspection: the first page of
    every report, so that a calibration is never read without the noise and modes it stood on
    (the records prepared as ``model``'s problem prepares them: one estimate of the modes)."""
    from bayes_update.reports.inspection import write_inspection

    paths = write_inspection(data, out / "inspection", remove_offsets=bool(getattr(model, "remove_offsets", True)))
    for w in json.loads(paths["inspection.json"].read_text())["warnings"]:
        print(f"bayes-update: data: {w}", file=sys.stderr)


# ----------------------------------------------------------------- commands
def cmd_calibrate(args) -> int:
    # every check before the first long step (the first look at the data, then the calibration)
    workers = workers_from(args)
    config = read_config(args.config, "calibrate")
    if args.model in beam_cli.BEAM_MODELS:
        from bayes_update.models.beam.calibrate import CalibrationSettings

        if args.metrics not in (None, "paper"):
            raise ValueError(
                "--metrics full: the beam's calibrate is the paper's grids on the paper's metrics; "
                "use `sample --metrics full` for the beam under the full set"
            )
        if args.prior:
            # the paper's grids are the beam calibrate's search: a prior would be ignored without a word
            raise ValueError(
                "--prior: the beam's calibrate searches the paper's grids, not a prior; set them in a [calibrate] "
                "table of --config (eta_values, c_values, k_s_values), or use --prior with `sample` or `discrepancy`"
            )
        settings = settings_from(CalibrationSettings, args.quick, config)
    else:
        from bayes_update.core.calibrate import check_settings

        options = {
            "n_start": 16 if args.quick else 64,
            "seed": 0,
            **check_settings(config, f"--config {args.config}: [calibrate]"),
            **({"seed": args.seed} if args.seed is not None else {}),
        }
    check_scheduler(args)
    model, data, space, _ = _model_and_data(args)
    _check_first(data, model, space)
    _first_look(data, args.out, model)
    if args.model in beam_cli.BEAM_MODELS:
        from bayes_update.models.beam.calibrate import calibrate, format_tables
        from bayes_update.reports.beam_calibration import write_result

        with executor_from(args) as pool:
            result = calibrate(data, model, settings, workers=workers, executor=pool)
        write_result(result, data, args.out)
        print(format_tables(result))
    else:
        from bayes_update.core.calibrate import calibrate_model
        from bayes_update.reports.calibration import format_calibration, write_calibration

        with executor_from(args) as pool:
            cal = calibrate_model(
                data,
                model,
                metrics=args.metrics or "full",
                space=space,
                workers=workers,
                executor=pool,
                cache_dir=run_cache(args),
                **options,
            )
        write_calibration(cal, args.out, sensors=data.sensors)
        print(format_calibration(cal))
    print(f"wrote {args.final_out}")
    return 0


def cmd_sample(args) -> int:
    from bayes_update.core.posterior import PosteriorSettings, sample
    from bayes_update.core.posterior.settings import THOROUGH
    from bayes_update.reports.posterior import write_posterior

    # every check before the first long step (the first look at the data, then the posterior)
    workers = workers_from(args)
    if args.thorough and args.quick:
        raise ValueError("--thorough and --quick: choose one")
    config = {**(THOROUGH if args.thorough else {}), **read_config(args.config, "sample")}
    settings = settings_from(
        PosteriorSettings,
        args.quick,
        config,
        seed=args.seed,
        n_predictive=args.predictive,
        n_global=args.sensitivity,
        **{
            ("direct_walkers" if args.direct else "n_walkers"): args.walkers,
            ("direct_steps" if args.direct else "n_steps"): args.steps,
        },
    )
    if args.direct and args.model == "fe":
        print(
            "bayes-update sample: note: --direct on the full FE costs ~0.1 s per likelihood "
            "evaluation (a few hours); --model rom is the intended use",
            file=sys.stderr,
        )
    check_scheduler(args)
    model, data, space, truth = _model_and_data(args)
    _check_first(data, model, space)
    _first_look(data, args.out, model)
    with executor_from(args) as pool:
        res = sample(
            data,
            model,
            settings,
            workers=workers,
            direct=args.direct,
            space=space,
            executor=pool,
            cache_dir=run_cache(args),
            metrics=args.metrics,
        )
    if truth is not None and args.model not in beam_cli.BEAM_MODELS:
        # the data set's own block: drawn only where it names the model's parameters in their units
        from bayes_update.reports.posterior import truth_in_model_units

        truth = truth_in_model_units(truth, res.space.report_units)
    elif truth is not None:  # the beam's, already in the model's (paper) units
        truth = {
            k: float(v) for k, v in truth.items() if k in res.space.report_units and isinstance(v, (int, float))
        } or None
    write_posterior(res, args.out, truth=truth)
    print(res.summary_table())
    print(
        f"{res.n_model_runs['total']} model runs ({sum(res.n_model_runs_reused.values())} of them found in "
        f"{run_cache(args) or 'no cache'}), {res.timing['total']:.0f} s; wrote {args.final_out}"
    )
    return 0


def cmd_discrepancy(args) -> int:
    from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy
    from bayes_update.reports.discrepancy import format_result, write_discrepancy

    # every check before the first long step; find_discrepancy's own first (the model's contract and
    # candidate effects, the data set's roles, one run) comes before its long ones
    workers = workers_from(args)
    settings = settings_from(DiscrepancySettings, args.quick, read_config(args.config, "discrepancy"), seed=args.seed)
    check_scheduler(args)
    model, data, space, truth = _model_and_data(args)
    if args.model in beam_cli.BEAM_MODELS:
        hidden = data.extra.get("truth", {}).get("effects") if isinstance(data.extra.get("truth"), dict) else None
        truth = {"parameters": truth, "effects": hidden} if truth else None
    with executor_from(args) as pool:
        res = find_discrepancy(
            data,
            model,
            settings=settings,
            workers=workers,
            candidates=args.candidates,
            metrics=args.metrics,
            space=space,
            executor=pool,
        )
    write_discrepancy(res, args.out, truth=truth)
    print(format_result(res))
    print(f"{res.n_model_runs['total']} model runs, {res.timing['total']:.0f} s; wrote {args.final_out}")
    return 0
