"""Step 1 of :func:`~bayes_update.core.posterior.sampler.sample`: the start (another command's
best point from the run cache, the model's own start, or the two-stage calibration)."""

from __future__ import annotations

import numpy as np

from bayes_update.core.calibrate import find_start
from bayes_update.core.kept_start import kept_start
from bayes_update.core.posterior.laplace_steps import fit_check
from bayes_update.core.posterior.run import Run


def start_step(run: Run, start) -> tuple[dict, dict]:
    """1. start: the model's own start or the two-stage calibration (unless given)."""
    space = run.space
    with run.steps("start"):
        kept = kept_start(run.problem) if start is None else None
        if kept is not None:
            # another command (calibrate) ran the model on these tests: its best point is the start
            start, n_kept = kept
            run.log(f"start: the best of {n_kept} points another command ran on these tests (the run cache)")
        elif start is None:
            start, n = find_start(
                run.dataset,
                run.problem,
                space,
                n_points=run.settings.n_start,
                seed=run.seeds.start,
                executor=run.pool,
                progress=run.progress,
                log=run.log,
                coarse=run.settings.coarse_start,
            )
            run.steps.add_runs(n)
        else:
            space.check(start, "start")
        info = {n: float(start[n]) for n in space.names}
        if not space.contains(start):
            start = space.to_parameters(np.clip(space.to_internal(start), space.box()[:, 0], space.box()[:, 1]))
        if not run.settings.coarse_start:
            fit_check(run, start, "start point")
    return start, info
