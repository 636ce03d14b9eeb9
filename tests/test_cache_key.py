"""The evaluation cache of ``sample`` is keyed by the data's content, not its path.

Before, the key held the data folder's path: new data written to the same
folder reused the old folder's model runs (issue 21).
"""

import shutil

import numpy as np

import fe
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior.design import design_cache
from bayes_update.core.posterior.target import Evaluate
from bayes_update.core.problem import Problem
from bayes_update.data.folder import read_dataset, write_dataset
from bayes_update.models.beam.model import Beam
from bayes_update.models.beam.rig import rig_of
from bayes_update.models.beam.virtual_rig import DEFAULT_DATASET_DIR


def _cache_file(data_dir, cache_dir):
    data = read_dataset(data_dir)
    beam = Beam(fe.ModalROM(rig=rig_of(data)))
    problem = Problem(data, beam)
    ev = Evaluate(problem, ParameterSet(beam.parameters, beam), problem.stages)
    return design_cache(cache_dir, ev, "design").file


def test_changed_data_at_the_same_path_gets_a_new_cache(tmp_path):
    data_dir = tmp_path / "data"
    shutil.copytree(DEFAULT_DATASET_DIR, data_dir)
    before = _cache_file(data_dir, tmp_path / "cache")
    data = read_dataset(data_dir)
    test = data.test("chirp_high")
    test.velocity[100] += 1e-7  # one sample of one channel, far below the noise [m/s]
    write_dataset(data, data_dir)
    after = _cache_file(data_dir, tmp_path / "cache")
    assert after != before


def test_same_data_at_another_path_shares_the_cache(tmp_path):
    shutil.copytree(DEFAULT_DATASET_DIR, tmp_path / "a")
    shutil.copytree(DEFAULT_DATASET_DIR, tmp_path / "b")
    assert _cache_file(tmp_path / "a", tmp_path / "cache") == _cache_file(tmp_path / "b", tmp_path / "cache")


def test_fingerprint_sees_every_channel_and_the_role():
    data = read_dataset(DEFAULT_DATASET_DIR)
    ref = data.fingerprint()
    for channel in ("time", "force", "velocity"):
        d = read_dataset(DEFAULT_DATASET_DIR)
        arr = getattr(d.tests[0], channel)
        arr[-1] = np.nextafter(arr[-1], np.inf)
        assert d.fingerprint() != ref, channel
    d = read_dataset(DEFAULT_DATASET_DIR)
    d.tests[0].role = "validation"
    assert d.fingerprint() != ref
