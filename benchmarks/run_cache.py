"""The run cache (bayes_update.core.runs) measured: model runs made and read when a
``sample`` is interrupted and run again, and when ``sample`` follows ``calibrate``.

    python benchmarks/run_cache.py [--seed 0]

On the Duffing user model of tests/test_user_model.py (fn, zeta, k3 free; the
logging wrapper of tests/test_budget_cache.py counts every run the model
finishes), with the default ``PosteriorSettings()`` and one worker:

* **uninterrupted**: ``sample`` on an empty cache: its runs per step;
* **interrupted + rerun**: the same command stopped (KeyboardInterrupt, as
  Ctrl-C) once half of those runs are finished, then run again on the same
  cache: runs made by the rerun, runs it read, and whether its posterior is the
  uninterrupted one's;
* **finished + rerun**: the same command once more: runs made (none expected);
* **calibrate, then sample**: ``calibrate_model`` on an empty cache, then
  ``sample`` on the same cache: the runs each made, against ``sample`` alone.

Before the run cache (the package until this change) only the surrogate
design's runs were kept (a netCDF file per design): a rerun made every other
run again, and ``sample`` after ``calibrate`` shared none.  Writes
``benchmarks/results/run_cache.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from _machine import machine  # noqa: E402
from test_budget_cache import LoggingModel, _runs  # noqa: E402
from test_user_model import make_dataset  # noqa: E402

from bayes_update.core.calibrate import calibrate_model  # noqa: E402
from bayes_update.core.posterior import PosteriorSettings, sample  # noqa: E402


def _sample(data, model, cache, seed):
    t = time.perf_counter()
    res = sample(
        data, model, PosteriorSettings(seed=seed), workers=1, cache_dir=cache, progress=False, log=lambda *a: None
    )
    return res, time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    data = make_dataset(seed=11)
    out = {"machine": machine(), "model": "Duffing (fn, zeta, k3), tests/test_user_model.py", "workers": 1}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        ref_log, log, stop = tmp / "ref.log", tmp / "runs.log", tmp / "stop"
        ref, t_ref = _sample(data, LoggingModel(ref_log, stop), tmp / "ref_cache", args.seed)
        made = _runs(ref_log)
        out["uninterrupted"] = {
            "runs_made": len(made),
            "runs_by_step": ref.n_model_runs,
            "wall_s": round(t_ref, 1),
            "gp_fit_s": round(ref.timing.get("gp_fit", 0.0), 1),
        }

        stop.write_text(str(len(made) // 2))
        try:
            _sample(data, LoggingModel(log, stop), tmp / "cache", args.seed)
        except KeyboardInterrupt:
            pass
        first = _runs(log)
        stop.unlink()
        again, t_again = _sample(data, LoggingModel(log, stop), tmp / "cache", args.seed)
        second = _runs(log)[len(first) :]
        out["interrupted_rerun"] = {
            "runs_before_interruption": len(first),
            "runs_made_by_rerun": len(second),
            "runs_made_twice": len(set(first) & set(second)),
            "runs_read_by_step": again.n_model_runs_reused,
            "wall_s": round(t_again, 1),
            "same_posterior": again.summary == ref.summary,
        }
        third, t_third = _sample(data, LoggingModel(log, stop), tmp / "cache", args.seed)
        out["finished_rerun"] = {
            "runs_made": len(_runs(log)) - len(first) - len(second),
            "wall_s": round(t_third, 1),
            "runs_read_by_step": third.n_model_runs_reused,
            "same_posterior": third.summary == ref.summary,
        }

        log2 = tmp / "cal.log"
        t = time.perf_counter()
        cal = calibrate_model(
            data, LoggingModel(log2, stop), workers=1, progress=False, log=lambda *a: None, cache_dir=tmp / "cal_cache"
        )
        t_cal = time.perf_counter() - t
        n_cal = len(_runs(log2))
        after, t_after = _sample(data, LoggingModel(log2, stop), tmp / "cal_cache", args.seed)
        by_sample = _runs(log2)[n_cal:]
        out["calibrate_then_sample"] = {
            "calibrate_runs": n_cal,
            "calibrate_wall_s": round(t_cal, 1),
            "sample_runs_made": len(by_sample),
            "sample_runs_by_step": after.n_model_runs,
            "sample_runs_read_by_step": after.n_model_runs_reused,
            "calibrate_runs_made_again": len(set(by_sample) & set(_runs(log2)[:n_cal])),
            "sample_alone_runs_made": len(made),
            "sample_wall_s": round(t_after, 1),
            "start_is_calibrates_best": {k: float(v) for k, v in after.start.items()}
            == {k: float(cal.theta[k]) for k in after.start},
        }
    res_dir = ROOT / "benchmarks" / "results"
    (res_dir / "run_cache.json").write_text(json.dumps(out, indent=1, default=str) + "\n")
    u, i, f, c = out["uninterrupted"], out["interrupted_rerun"], out["finished_rerun"], out["calibrate_then_sample"]
    md = [
        f"# Run cache: runs made and read ({out['model']})",
        "",
        f"Machine: {out['machine']}; one worker.",
        "",
        "| case | model runs made | runs read from the cache | wall [s] |",
        "|---|---:|---:|---:|",
        f"| sample, empty cache | {u['runs_made']} | 0 | {u['wall_s']} |",
        f"| sample interrupted after {i['runs_before_interruption']} runs, rerun | {i['runs_made_by_rerun']} "
        f"(made twice: {i['runs_made_twice']}) | {sum(i['runs_read_by_step'].values())} | {i['wall_s']} |",
        f"| the finished sample rerun | {f['runs_made']} | {sum(f['runs_read_by_step'].values())} | {f['wall_s']} |",
        f"| calibrate, empty cache | {c['calibrate_runs']} | 0 | {c['calibrate_wall_s']} |",
        f"| sample after calibrate | {c['sample_runs_made']} (alone: {c['sample_alone_runs_made']}) | "
        f"{sum(c['sample_runs_read_by_step'].values())} | {c['sample_wall_s']} |",
        "",
        f"The rerun's posterior equals the uninterrupted one's: {i['same_posterior']}.  Runs read per step "
        f"(rerun): {i['runs_read_by_step']}; (sample after calibrate): {c['sample_runs_read_by_step']}.",
        "Before the run cache only the design's runs were kept: a rerun made every other run again and "
        "sample after calibrate read none.",
        "",
    ]
    (res_dir / "run_cache.md").write_text("\n".join(md))
    print("\n".join(md))


if __name__ == "__main__":
    main()
