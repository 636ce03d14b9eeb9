"""Run a model of the rig on every test of a data set."""

from __future__ import annotations

import copy

from tqdm.auto import tqdm

import fe
from bayes_update.data.dataset import Dataset
from bayes_update.models.beam.rig import rig_of


def simulate_dataset(dataset: Dataset, model, params: fe.Parameters, progress: bool = True) -> Dataset:
    """A copy of ``dataset`` whose velocity columns are the model's response at
    the sensor to each test's recorded force (same time column)."""
    out = copy.deepcopy(dataset)
    for test in tqdm(out.tests, desc="simulate", unit="test", disable=None if progress else True):
        result = fe.simulate(
            model, params, test.force, fs=dataset.sampling_rate_hz, positions=[rig_of(dataset).sensor_position_m]
        )
        test.velocity = result.sensor_velocity.copy()
    return out
