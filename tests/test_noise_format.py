"""The dataset.json keys of the noise (noise_sd, period_samples): read, carried on
Dataset/Record, written back, validated with messages naming the file and the key."""

import json

import lab_records as lab
import numpy as np
import pytest

from bayes_update.data.dataset import Dataset, DatasetError, Record
from bayes_update.data.folder import read_dataset, write_dataset
from bayes_update.data.noise import dataset_noise


@pytest.fixture(scope="module")
def records():
    return [lab.periodic_test(), *lab.random_tests()]


def test_the_keys_round_trip_through_the_folder(records, tmp_path):
    folder = lab.write_lab_dataset(records, tmp_path / "lab", noise_sd={"force": 0.001, "acc3": 0.08})
    meta = json.loads((folder / "dataset.json").read_text())
    assert meta["noise_sd"] == {"force": 0.001, "acc3": 0.08}
    assert meta["tests"][0]["period_samples"] == 1024
    assert "period_samples" not in meta["tests"][1] and "noise_sd" not in meta["tests"][1]
    meta["tests"][1]["noise_sd"] = {"acc1": 0.0125}
    (folder / "dataset.json").write_text(json.dumps(meta))
    ds = read_dataset(folder)
    assert ds.noise_sd == {"force": 0.001, "acc3": 0.08}
    assert ds.tests[0].period_samples == 1024 and ds.tests[1].period_samples is None
    assert ds.tests[1].noise_sd == {"acc1": 0.0125}
    assert "period_samples" not in ds.tests[0].meta and "noise_sd" not in ds.tests[1].meta
    assert ds.declared_noise_sd(ds.tests[1]) == {"force": 0.001, "acc3": 0.08, "acc1": 0.0125}
    again = json.loads((write_dataset(ds, tmp_path / "again") / "dataset.json").read_text())
    assert again["noise_sd"] == meta["noise_sd"] and again["tests"] == meta["tests"]
    # the estimates read from disk are those of the records in memory (ten digits on disk)
    noise = dataset_noise(ds)
    assert noise["random_low"]["acc1"].sd == 0.0125 and noise["random_high"]["acc1"].method == "carried"
    assert noise["multisine_low"]["acc2"].method == "periods"
    truth = records[0].noise_sd["acc2"]
    assert abs(noise["multisine_low"]["acc2"].sd / truth - 1) < 0.15


def test_existing_data_sets_hash_as_before_and_the_declared_noise_is_hashed(records):
    ds = lab.lab_dataset(records, declare_period=False)
    plain = ds.fingerprint()
    ds.noise_sd = {"acc1": 0.01}
    declared = ds.fingerprint()
    ds.noise_sd = {}
    ds.tests[0].period_samples = 1024
    assert len({plain, declared, ds.fingerprint()}) == 3
    ds.tests[0].period_samples = None
    assert ds.fingerprint() == plain


def _folder(tmp_path, rec, **keys):
    ds = Dataset("x", rec.fs, None, [rec.record(declare_period=False)])
    folder = write_dataset(ds, tmp_path / "x")
    meta = json.loads((folder / "dataset.json").read_text())
    for key, value in keys.items():
        if key.startswith("test_"):
            meta["tests"][0][key[5:]] = value
        else:
            meta[key] = value
    (folder / "dataset.json").write_text(json.dumps(meta))
    return folder


@pytest.mark.parametrize(
    "keys, words",
    [
        ({"noise_sd": [0.1]}, ["'noise_sd' must be an object"]),
        ({"noise_sd": {"acc9": 0.1}}, ["channel 'acc9'", "'force'", "'acc1'"]),
        ({"noise_sd": {"acc1": -1.0}}, ["'acc1' must be a positive number"]),
        ({"noise_sd": {"force": "0.1"}}, ["'force' must be a positive number"]),
        ({"noise_sd": {"force": 0}}, ["'force' must be a positive number"]),
        ({"test_noise_sd": {"velocity": 1.0}}, ["test multisine_low.csv", "channel 'velocity'"]),
        ({"test_period_samples": 1024.5}, ["test multisine_low.csv", "'period_samples' must be an integer"]),
        ({"test_period_samples": True}, ["'period_samples' must be an integer"]),
        ({"test_period_samples": 1}, ["'period_samples' must be at least 2"]),
        ({"test_period_samples": 5000}, ["'period_samples' is 5000", "at least two periods"]),
    ],
)
def test_bad_keys_are_refused_naming_the_file_and_the_key(records, tmp_path, keys, words):
    folder = _folder(tmp_path, records[0], **keys)
    with pytest.raises(DatasetError) as info:
        read_dataset(folder)
    msg = str(info.value)
    assert str(folder / "dataset.json") in msg
    for w in words:
        assert w in msg, (w, msg)


def test_records_and_data_sets_in_memory_are_validated_too(records):
    rec = records[0]
    with pytest.raises(DatasetError, match="'period_samples' must be at least 2"):
        rec.record().__class__(**{**_fields(rec.record()), "period_samples": 0})
    with pytest.raises(DatasetError, match="channel 'strain'"):
        Dataset("x", rec.fs, None, [rec.record()], noise_sd={"strain": 1.0}).validate()
    old = Record("a.csv", "s", "l", "linear", np.arange(8) / 8.0, np.zeros(8), np.zeros(8))
    assert old.period_samples is None and old.noise_sd == {}


def _fields(record) -> dict:
    import dataclasses

    return {f.name: getattr(record, f.name) for f in dataclasses.fields(record)}
