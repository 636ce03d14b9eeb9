"""Command line: ``bayes-update <command> ...``."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path



from bayes_update.reports import beam_cli
from bayes_update.core import ModelError
from bayes_update.data.dataset import DatasetError
from bayes_update.data.folder import read_dataset





def _add_metrics_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--metrics", choices=("paper", "full"), default=None,
                   help="metric set: paper (e_lin on y1 of the linear test, e_nlin on y2 + y3 of the "
                        "nonlinear one; the beam's default) or full (the whole projection of each test, "
                        "weighted by its noise; the default for your own model)")








def _user_model(args):
    """The user's model of ``--model SPEC``, or None for the beam's."""
    if args.model in beam_cli.BEAM_MODELS:
        return None
    from bayes_update.core import load_model

    return load_model(args.model)








def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bayes-update",
        description="Probabilistic updating of a nonlinear FE beam model with Volterra series "
                    "(after Bussetta, Shiki and da Silva, 2017).")
    sub = parser.add_subparsers(dest="command", metavar="command")

    p = sub.add_parser("simulate", help="run the FE model on the recorded forces of a data set",
                       description="Drive the model with each test's recorded force and write the "
                                   "responses as a data-set folder of the same form, plus a plot "
                                   "per test. Without --data: the paper's 4 s chirp at the paper's "
                                   "parameters. Units are SI.")
    p.add_argument("--data", type=Path, default=None, help="data-set folder (dataset.json + CSV)")
    beam_cli.add_parameter_options(p)
    beam_cli.add_model_options(p)
    beam_cli.add_factor_options(p)
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.set_defaults(func=beam_cli.cmd_simulate)

    p = sub.add_parser("calibrate", help="the paper's two-stage deterministic updating (any model)",
                       description="Reproduce section 4 of the paper on a data set: e_lin over "
                                   "(F, k_s) grids per c on the 'linear' test (Table 1), e_lin "
                                   "against eta (Fig. 8), e_lin + e_nlin over (F, k_s, c) on the "
                                   "'nonlinear' test (Table 2), a Nelder-Mead refinement "
                                   "(Table 3) and the validation tests. Writes tables (CSV), "
                                   "figures (PNG), report.txt and calibration.json (SI). "
                                   "With --model path.py:NAME (your own model): a sensitivity "
                                   "screen picks the linear test's parameters, stage 1 fits them "
                                   "on e_lin, stage 2 fits all on both tests (least squares from "
                                   "Sobol' starts); calibration.json has one key per parameter "
                                   "(its unit), e_lin, e_nlin and the prediction error on each "
                                   "validation test. Without --data: the embedded default data set.")
    p.add_argument("--data", type=Path, default=None, help="data-set folder (dataset.json + CSV)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--quick", action="store_true",
                   help="coarse grids (about 1/10 of the runs): a first look, or CI")
    p.add_argument("--workers", type=int, default=None,
                   help="processes for the grids (default: all cores; 1 = serial)")
    p.add_argument("--seed", type=int, default=0, help="seed of the start designs (your own model; default 0)")
    beam_cli.add_model_options(p)
    _add_metrics_option(p)
    beam_cli.add_factor_options(p)
    p.set_defaults(func=cmd_calibrate)

    p = sub.add_parser("sample", help="posterior of (eta, c, F, k_s) with emcee (GP surrogate or direct)",
                       description="Bayesian updating on a data set: likelihood from e_lin (test "
                                   "with role 'linear') and e_nlin (role 'nonlinear') with noise "
                                   "and model-error scales measured at the deterministic estimate, "
                                   "uniform prior on the box eta 1-6 MPa s, c 0-30 N s/mm, F 60-95 N, "
                                   "k_s 0-600 N/mm, Gaussian-process surrogates refined where the "
                                   "posterior is, emcee. Writes posterior.nc (ArviZ, SI units), "
                                   "posterior_summary.json and figures. Without --data: the "
                                   "embedded default data set.")
    p.add_argument("--data", type=Path, default=None, help="data-set folder (dataset.json + CSV)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--direct", action="store_true",
                   help="sample on the model itself, no surrogate (the reference posterior; "
                        "use with --model rom)")
    p.add_argument("--quick", action="store_true", help="small designs and chains (a first look, or CI)")
    p.add_argument("--seed", type=int, default=None, help="seed of every random choice (default 0)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes for the model runs (default: all cores; 1 = serial)")
    p.add_argument("--no-cache", action="store_true",
                   help="do not keep model runs in OUT/cache (by default an interrupted run resumes)")
    p.add_argument("--prior", action="append", default=[], metavar="NAME=LO:HI",
                   help="change one range of the uniform prior box, in paper units (eta MPa s, c N s/mm, "
                        "F N, k_s N/mm), e.g. --prior F=20:95; repeatable")
    beam_cli.add_model_options(p)
    _add_metrics_option(p)
    beam_cli.add_factor_options(p)
    p.set_defaults(func=cmd_sample)

    p = sub.add_parser("discrepancy", help="find the effect the model misses, add it, show the gap shrink",
                       description="After the baseline update (least-squares mode with the measured "
                                   "likelihood scales), locate where model and data disagree (by test, "
                                   "kernel order, sine harmonic, free-decay amplitude), fit each effect "
                                   "of the catalogue (initial_imperfection, amplitude_dependent_damping, "
                                   "shaker_attachment, clamp_compliance) with its own parameters, rank "
                                   "them by Laplace evidence, name one only when 2 ln B > 6 and its "
                                   "parameter excludes 'no effect', re-update and report the gap before "
                                   "and after. Writes discrepancy.json, evidence.md and figures. "
                                   "With --model path/to/file.py:NAME: the candidates are the model's "
                                   "candidate_effects() (docs/models.md). "
                                   "Without --data: the embedded default data set.")
    p.add_argument("--data", type=Path, default=None, help="data-set folder (dataset.json + CSV)")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--quick", action="store_true", help="fewer noise replicates and iterations (CI)")
    p.add_argument("--workers", type=int, default=None,
                   help="processes for the model runs (default: all cores; 1 = serial)")
    p.add_argument("--candidates", nargs="+", default=None, metavar="NAME",
                   help="restrict the catalogue (default: all four effects, or all the model's candidate_effects())")
    beam_cli.add_model_options(p)
    _add_metrics_option(p)
    beam_cli.add_factor_options(p)
    p.set_defaults(func=cmd_discrepancy)

    p = sub.add_parser("reproduce", help="the whole study on the embedded default data set, with a report",
                       description="Deterministic updating (Tables 1-3) with the data set's bending "
                                   "stiffness factor and with a locking-free beam, f1 against the "
                                   "preload, the posterior for both, and report.md with every table "
                                   "and figure, then the discrepancy workflow on a variant of the rig "
                                   "with a hidden bow. About 12 minutes on 2 cores (--quick: about 3).")
    p.add_argument("--out", type=Path, required=True, help="output folder")
    p.add_argument("--quick", action="store_true", help="coarse grids and small posterior settings")
    p.add_argument("--workers", type=int, default=None,
                   help="processes for the model runs (default: all cores; 1 = serial)")
    p.add_argument("--no-discrepancy", action="store_true",
                   help="skip the discrepancy workflow on the hidden-effect variant (about 3 minutes)")
    p.set_defaults(func=cmd_reproduce)

    p = sub.add_parser("make-dataset", help="regenerate the embedded default data set (virtual rig)",
                       description="Run the virtual rig (paper-equivalent rig, bending stiffness "
                                   "factor 1.24, the paper's Table 3 parameters, 20 elements at "
                                   "4096 Hz, filtered and decimated to 1024 Hz, noisy) on the "
                                   "paper's six tests and write the data-set folder. With the "
                                   "defaults it reproduces the embedded data set byte for byte.")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default: the package's embedded data set, "
                        "bayes_update/models/beam/default_data)")
    p.add_argument("--seed", type=int, default=None, help="noise seed (default 2017)")
    p.add_argument("--snr-force", type=float, default=None, metavar="DB",
                   help="force-channel SNR [dB re RMS] (default 40)")
    p.add_argument("--snr-velocity", type=float, default=None, metavar="DB",
                   help="velocity-channel SNR [dB re RMS] (default 40)")
    p.add_argument("--imperfection", type=float, default=0.0, metavar="M",
                   help="initial bow of the beam at mid-span [m] (hidden effect; default 0)")
    p.add_argument("--hidden", action="append", default=[], metavar="EFFECT",
                   help="hide an effect in the data (initial_imperfection, amplitude_dependent_damping, "
                        "shaker_attachment, clamp_compliance), its magnitude drawn from a realistic "
                        "range with --hidden-seed; repeatable; recorded in dataset.json's truth block")
    p.add_argument("--hidden-seed", type=int, default=0, help="seed of the hidden magnitudes (default 0)")
    p.set_defaults(func=cmd_make_dataset)

    p = sub.add_parser("plot-data", help="plot the tests of a data set (time, FRF, PSD)",
                       description="Write PNG figures of a data set: force and velocity of each "
                                   "test, H1 FRF and coherence of the chirps (each, and the "
                                   "levels overlaid), velocity PSD of the sines (each, and the "
                                   "levels overlaid). Without --data: the embedded default data set.")
    p.add_argument("--data", type=Path, default=None, help="data-set folder (dataset.json + CSV)")
    p.add_argument("--out", type=Path, required=True, help="output folder for the PNG files")
    p.set_defaults(func=cmd_plot_data)
    return parser






def cmd_calibrate(args) -> int:
    import dataclasses

    from bayes_update.models.beam.calibrate import CalibrationSettings, calibrate, format_tables
    from bayes_update.reports.beam_calibration import write_result
    from bayes_update.models.beam.virtual_rig import load_default_dataset

    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    data = read_dataset(args.data) if args.data else load_default_dataset()
    user = _user_model(args)
    if user is not None:
        from bayes_update.reports.calibration import format_calibration, write_calibration
        from bayes_update.core.calibrate import calibrate_model

        cal = calibrate_model(data, user, metrics=args.metrics or "full", workers=args.workers,
                              n_start=16 if args.quick else 64, seed=args.seed)
        write_calibration(cal, args.out, sensors=data.sensors)
        print(format_calibration(cal))
        print(f"wrote {args.final_out}")
        return 0
    if args.metrics not in (None, "paper"):
        raise ValueError("--metrics full: the beam's calibrate is the paper's grids on the paper's metrics; "
                         "use `sample --metrics full` for the beam under the full set")
    rig = beam_cli.rig_for(data, args)
    data = dataclasses.replace(data, rig=rig)
    model = beam_cli.model_for(args, rig)
    settings = CalibrationSettings.quick() if args.quick else CalibrationSettings()
    result = calibrate(data, model, settings, workers=args.workers)
    write_result(result, data, args.out)
    print(format_tables(result))
    print(f"wrote {args.final_out}")
    return 0


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


def _prior_space(rig, items):
    from bayes_update.models.beam.space import ParameterSpace

    return ParameterSpace(rig, **_prior_ranges(items, ("eta", "c", "F", "k_s")))


def _user_prior(model, items):
    """The model's declared prior with the --prior ranges (in the parameter's unit) put in, or None."""
    import dataclasses

    from bayes_update.core import ParameterSet

    if not items:
        return None
    params = {p.name: p for p in model.parameters}
    for name, (lo, hi) in _prior_ranges(items, tuple(params)).items():
        params[name] = dataclasses.replace(params[name], low=lo, high=hi)
    return ParameterSet(list(params.values()), model)


def _user_truth(data, space) -> dict | None:
    """A synthetic data set's truth block, when it names the model's parameters (plots only)."""
    truth = data.extra.get("truth")
    if isinstance(truth, dict) and set(space.names) <= set(truth):
        return {n: float(truth[n]) for n in space.names}
    return None


def cmd_sample(args) -> int:
    import dataclasses

    from bayes_update.core.posterior import PosteriorSettings, sample
    from bayes_update.reports.posterior import format_summary, write_posterior
    from bayes_update.models.beam.virtual_rig import load_default_dataset

    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    if args.direct and args.model == "fe":
        print("bayes-update sample: note: --direct on the full FE costs ~0.1 s per likelihood "
              "evaluation (a few hours); --model rom is the intended use", file=sys.stderr)
    data = read_dataset(args.data) if args.data else load_default_dataset()
    kw = {} if args.seed is None else {"seed": args.seed}
    settings = PosteriorSettings.quick(**kw) if args.quick else PosteriorSettings(**kw)
    model = _user_model(args)
    if model is None:
        rig = beam_cli.rig_for(data, args)
        data = dataclasses.replace(data, rig=rig)
        model = beam_cli.model_for(args, rig)
        space = _prior_space(rig, args.prior)
    else:
        space = _user_prior(model, args.prior)
    res = sample(data, model, settings, workers=args.workers, direct=args.direct, space=space,
                 cache_dir=None if args.no_cache else args.cache_dir, metrics=args.metrics)
    from bayes_update.models.beam.virtual_rig import truth_paper_units
    truth = truth_paper_units(data) if args.model in beam_cli.BEAM_MODELS else _user_truth(data, res.space)
    write_posterior(res, args.out, truth=truth)
    print(format_summary(res))
    t = res.timing
    print(f"time: {t['total']:.0f} s ({', '.join(f'{k} {v:.0f} s' for k, v in t.items() if k != 'total')}); "
          f"{res.n_model_runs['total']} model runs ({sum(res.n_model_runs_reused.values())} of them found in "
          f"{args.cache_dir}); wrote {args.final_out}")
    return 0


def cmd_discrepancy(args) -> int:
    import dataclasses

    from bayes_update.models.beam.missing_effect import DiscrepancySettings, find_missing_effect, format_result, write_discrepancy
    from bayes_update.models.beam.virtual_rig import load_default_dataset, truth_paper_units

    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    model = _user_model(args)
    if model is not None:
        return _discrepancy_of_user_model(args, model)
    if args.metrics not in (None, "paper"):
        raise ValueError("--metrics full: the beam's discrepancy workflow runs on the paper's metrics")
    data = read_dataset(args.data) if args.data else load_default_dataset()
    rig = beam_cli.rig_for(data, args)
    data = dataclasses.replace(data, rig=rig)
    model = beam_cli.model_for(args, rig)
    settings = DiscrepancySettings.quick() if args.quick else DiscrepancySettings()
    res = find_missing_effect(data, model, settings=settings, workers=args.workers, candidates=args.candidates)
    truth = truth_paper_units(data)
    hidden = data.extra.get("truth", {}).get("effects") if isinstance(data.extra.get("truth"), dict) else None
    write_discrepancy(res, data, args.out, truth={"parameters": truth, "effects": hidden} if truth else None)
    print(format_result(res))
    print(f"time: {res.timing['total']:.0f} s; wrote {args.final_out}")
    return 0


def _discrepancy_of_user_model(args, model) -> int:
    """`discrepancy --model SPEC`: the generic engine, candidates from the model's candidate_effects()."""
    from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy, format_result, write_discrepancy
    from bayes_update.core.effects import candidate_effects

    candidate_effects(model, [p.name for p in getattr(model, "parameters", ())])   # before any data work
    if args.data is None:
        raise ValueError("--model SPEC needs --data: the embedded default data set is the beam's")
    data = read_dataset(args.data)
    settings = DiscrepancySettings.quick() if args.quick else DiscrepancySettings()
    res = find_discrepancy(data, model, settings=settings, workers=args.workers, candidates=args.candidates,
                           metrics=args.metrics)
    truth = data.extra.get("truth")
    write_discrepancy(res, args.out, truth=truth if isinstance(truth, dict) else None)
    import matplotlib.pyplot as plt

    from bayes_update.reports.discrepancy import gap_figure

    fig = gap_figure(res)
    fig.savefig(Path(args.out) / "gap_before_after.png", dpi=110)
    plt.close(fig)
    print(format_result(res))
    print(f"time: {res.timing['total']:.0f} s; wrote {args.final_out}")
    return 0


def cmd_reproduce(args) -> int:
    from bayes_update.reports.beam_study import reproduce

    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    reproduce(args.out, quick=args.quick, workers=args.workers, discrepancy=not args.no_discrepancy,
              cache_dir=args.cache_dir)
    print(f"wrote {args.final_out / 'report.md'}")
    return 0


def cmd_make_dataset(args) -> int:
    from bayes_update.models.beam.virtual_rig import DEFAULT_SEED, DEFAULT_SNR_DB, make_dataset

    out = args.out
    start = time.perf_counter()
    rig = None
    if args.hidden:
        from bayes_update.models.beam.virtual_rig import VirtualRig, hidden_effects
        rig = VirtualRig(effects=hidden_effects(args.hidden, args.hidden_seed))
    ds = make_dataset(out, rig=rig,
                      seed=DEFAULT_SEED if args.seed is None else args.seed,
                      snr_force_db=DEFAULT_SNR_DB if args.snr_force is None else args.snr_force,
                      snr_velocity_db=(DEFAULT_SNR_DB if args.snr_velocity is None
                                       else args.snr_velocity),
                      imperfection=args.imperfection)
    elapsed = time.perf_counter() - start
    lin = ds.extra["truth"]["linearised"]
    size = sum(f.stat().st_size for f in Path(out).iterdir() if f.is_file())
    print(f"wrote {len(ds.tests)} tests to {args.final_out} ({size / 1e6:.2f} MB) in {elapsed:.1f} s; "
          f"f1 = {lin['f1_hz']:.2f} Hz, 35 Hz / f1 = {lin['sine_frequency_over_f1']:.3f}")
    return 0


def cmd_plot_data(args) -> int:

    from bayes_update.data import spectral
    from bayes_update.reports.plots import plot_frf, plot_psd, plot_test
    from bayes_update.models.beam.virtual_rig import load_default_dataset

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
            save(plot_frf({t.name: est}, title=f"{t.name}: H1 FRF and coherence"),
                 f"{t.name}_frf.png")
        elif t.signal == "sine":
            spec = {f"{t.name} velocity": spectral.psd(t.velocity, fs)}
            sines[t.name] = spec
            freq = t.meta.get("frequency_hz")
            save(plot_psd(spec, harmonics_of=freq, title=f"{t.name}: velocity PSD"),
                 f"{t.name}_psd.png")
    if len(chirps) > 1:
        save(plot_frf(chirps,
                      title="chirp tests: H1 FRF by level (distortion = nonlinearity)"),
             "chirp_frf.png")
    if len(sines) > 1:
        merged = {name: next(iter(spec.values())) for name, spec in sines.items()}
        freqs = {t.meta.get("frequency_hz") for t in data.tests if t.signal == "sine"}
        save(plot_psd(merged, harmonics_of=freqs.pop() if len(freqs) == 1 else None,
                      title="sine tests: velocity PSD by level"), "sine_psd.png")
    print(f"wrote {len(written)} figure(s) to {args.final_out}")
    return 0


#: errors reported in one line (exit status 2) instead of a traceback
_REPORTED_ERRORS = (ValueError, DatasetError, ModelError) + beam_cli.FAILURES


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if getattr(args, "out", None) is None and args.command != "make-dataset":
            return args.func(args)
        return _run_staged(args)
    except _REPORTED_ERRORS as exc:
        print(f"bayes-update {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"bayes-update {args.command}: interrupted; {_resume_hint(args)}", file=sys.stderr)
        return 130


# commands whose model runs are kept in OUT/cache, so that a rerun resumes
_RESUMABLE = ("sample", "reproduce")


def _run_staged(args) -> int:
    """Run a command that writes OUT: results go to a staging folder and reach
    OUT only when the command finishes (:mod:`bayes_update.reports.outputs`); the cache
    of model runs is OUT/cache."""
    from bayes_update.reports.outputs import staged_output

    if args.command == "make-dataset" and args.out is None:
        if args.hidden:
            raise ValueError("--hidden needs --out: the embedded default data set has no hidden effect")
        from bayes_update.models.beam.virtual_rig import DEFAULT_DATASET_DIR
        args.out = DEFAULT_DATASET_DIR
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
        return (f"nothing in {out} was changed except {out / 'cache'}, which keeps the model runs "
                "finished so far: rerun the same command to resume")
    return f"nothing in {out} was changed; rerun the same command to start again"


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
