"""Writing a data set as a data-set folder (the format of :mod:`.folder`):
dataset.json in its canonical form and one CSV per test in a fixed number
format, so that the same arrays give the same bytes.  Apart from
:mod:`.folder`, which states the format and reads it."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np

from bayes_update.data.dataset import DEFAULT_SENSORS, Dataset

# Formats of the CSV writer: fixed, so that the same arrays give the same bytes.
TIME_FORMAT = "%.12g"


VALUE_FORMAT = "%.9e"


def sensors_metadata(sensors) -> dict:
    """The ``dataset.json`` keys of the sensors, canonical form: ``{}`` for the default
    single velocity sensor, ``{"response": kind}`` for one sensor named after its
    kind, ``{"sensors": [{"name", "response"}, ...]}`` otherwise."""
    sensors = [tuple(s) for s in sensors]
    if sensors == list(DEFAULT_SENSORS):
        return {}
    if len(sensors) == 1 and sensors[0][0] == sensors[0][1]:
        return {"response": sensors[0][1]}
    return {"sensors": [{"name": n, "response": k} for n, k in sensors]}


def dataset_metadata(dataset: Dataset) -> dict:
    """The ``dataset.json`` content of a data set (the contract keys, then the extra keys)."""
    meta = {"name": dataset.name, "sampling_rate_hz": dataset.sampling_rate_hz}
    meta.update(sensors_metadata(dataset.sensors))
    if dataset.rig is not None:
        meta["rig"] = dataset.rig.to_dict()
    if dataset.noise_sd:
        meta["noise_sd"] = dict(dataset.noise_sd)
    meta["tests"] = []
    for t in dataset.tests:
        entry = {"file": t.file, "signal": t.signal, "level": t.level, "role": t.role}
        if t.period_samples is not None:
            entry["period_samples"] = int(t.period_samples)
        if t.noise_sd:
            entry["noise_sd"] = dict(t.noise_sd)
        meta["tests"].append(dict(entry, **copy.deepcopy(t.meta)))
    for key, value in dataset.extra.items():
        if key not in meta:
            meta[key] = copy.deepcopy(value)
    return meta


def write_dataset(dataset: Dataset, folder) -> Path:
    """Write a data set in the folder format (dataset.json + one CSV per test).

    The CSV numbers have a fixed format (time ``%.12g`` [s]; force [N] and
    each response column ``%.9e``, ten significant digits), so the same
    arrays always give the same bytes.  The response columns are named by the
    sensors (default: ``velocity``).  Test files are always written as CSV (a
    ``.uff`` file name is replaced by ``.csv``).  The ``rig`` block is written
    as held (:attr:`Dataset.rig`: the raw block, or ``to_dict()`` of an
    ``fe.Rig``), and not at all when None; ``noise_sd`` (top level and per
    test) and ``period_samples`` only when set.
    """
    dataset = copy.copy(dataset)
    dataset.tests = [copy.copy(t) for t in dataset.tests]
    for t in dataset.tests:
        if Path(t.file).suffix.lower() != ".csv":
            t.file = Path(t.file).stem + ".csv"
            t.meta = {k: v for k, v in t.meta.items() if k != "uff_load_case"}
    dataset.validate()
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    meta = dataset_metadata(dataset)
    names = [n for n, _ in dataset.sensors]
    (folder / "dataset.json").write_text(json.dumps(meta, indent=2) + "\n")
    for t in dataset.tests:
        arr = np.column_stack([t.time, t.force, t.response])
        np.savetxt(
            folder / t.file,
            arr,
            delimiter=",",
            header=",".join(("time", "force", *names)),
            comments="",
            fmt=(TIME_FORMAT, VALUE_FORMAT) + (VALUE_FORMAT,) * len(names),
        )
    return folder
