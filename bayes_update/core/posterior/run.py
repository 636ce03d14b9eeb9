"""What every step of :func:`~bayes_update.core.posterior.sampler.sample` reads: the run's
context and its seeds."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior.settings import PosteriorSettings
from bayes_update.core.problem import Problem
from bayes_update.core.steps import StepLog
from bayes_update.data.dataset import Dataset


class StepSeeds(NamedTuple):
    """One seed per step of :func:`sample`, spawned from ``settings.seed`` in this order
    (a step's draws do not move when another step draws more or fewer numbers)."""

    likelihood: int  # the noise replicates and the model-form draws
    walkers: int  # the walkers' initial positions
    chain: int  # emcee's moves
    design: int  # the surrogates' design (plus the attempt, on a re-centred box)
    predictive: int  # the posterior-predictive draws
    linear_only: int  # the beam's linear-only posterior
    sobol: int  # the global sensitivity indices
    start: int  # the start search's designs


def step_seeds(seed) -> StepSeeds:
    return StepSeeds(*(int(s.generate_state(1)[0]) for s in np.random.SeedSequence(seed).spawn(len(StepSeeds._fields))))


@dataclass
class Run:
    """What every step of one :func:`sample` reads: the problem, its prior, the
    settings, the executor, where to cache and log, the step log and the seeds
    (one per step, spawned from ``settings.seed``)."""

    dataset: Dataset
    problem: Problem
    space: ParameterSet
    settings: PosteriorSettings
    pool: object
    cache_dir: object
    progress: bool
    log: object
    steps: StepLog
    seeds: "StepSeeds"
    reused: dict = field(default_factory=dict)  # model runs found in the cache, per design
    warnings: list = field(default_factory=list)  # fit warnings at the start (bayes_update.core.checks)
