"""The data-set folder on disk (a public contract, stated here; design points in
docs/design.md#the-data-set-folder):
:func:`read_dataset` and :func:`write_dataset`.

A folder with ``dataset.json`` and one file per test.  A CSV file has a
header row and the columns ``time`` [s], ``force`` [N] and one column per
sensor, named by the sensor's name (other columns are ignored): by default
``velocity`` [m/s].  A test file may also be a UFF type-58 file (``.uff`` or
``.unv``, see :mod:`bayes_update.data.uff`; force and velocity only).
``dataset.json`` keys:

``name``
    free text (default: the folder name).
``sampling_rate_hz``
    required, the sampling rate of every test [Hz].
``response``
    optional, the response kind of the single sensor: ``"displacement"``
    [m], ``"velocity"`` [m/s] (default) or ``"acceleration"`` [m/s^2]; the
    CSV column has that name.  With ``sensors``, the default kind of the
    sensors (a sensor that states another kind is an error).
``sensors``
    optional, for several sensors: a list of ``{"name": ..., "response":
    ...}``, one CSV column per sensor named by ``name`` (unique, not
    ``time`` or ``force``, no comma); ``response`` as above (default: the
    top-level ``response``, else velocity).  The column order of
    :attr:`Record.response` is the list's order.
``rig``
    optional, the beam rig (read by the beam code only,
    :func:`bayes_update.models.beam.rig.rig_of`: :meth:`fe.Rig.from_dict` keys
    ``length_m``, ``width_m``, ``thickness_m``, ``youngs_modulus_pa``,
    ``poisson_ratio``, ``density_kg_m3``, ``shaker_position_m``,
    ``sensor_position_m`` (from the clamped bottom),
    ``bending_stiffness_factor``; absent keys, or an absent block, take the
    paper's values, ``bending_stiffness_factor`` 1.0).  Kept here as given
    (:attr:`Dataset.rig`) and written back unchanged; a user model ignores it.
``tests``
    required, a list of ``{"file", "role", "signal", "level"}``: ``file``
    and ``role`` required, ``signal`` and ``level`` free text, default
    ``"unknown"``; extra keys of an entry are kept in :attr:`Record.meta`.
    For a UFF file holding several tests, ``"uff_load_case"`` selects the
    test (R6 F4 of the records).  Two optional keys of an entry describe
    its noise (:mod:`bayes_update.data.noise`):

    ``period_samples``
        the excitation's period in samples, an integer, when the test is
        periodic (several periods of a multisine, the generator clocked with
        the acquisition): the noise is then estimated from the
        period-to-period scatter (the first period, a transient, dropped).
        At least 2 and at most half the record.  Without it a period is
        looked for in the force (exact repetition).
    ``noise_sd``
        this test's declared noise, as the top-level ``noise_sd`` below;
        overrides it channel by channel.
``noise_sd``
    optional, the measurement noise of the channels as known by the user
    (sensor data sheets, a record with the structure at rest):
    ``{"force": 0.002, "<sensor name>": 1e-4, ...}``, the standard deviation
    per sample of each channel's noise over the recorded band, in the
    channel's unit (force [N], a sensor in its kind's SI unit); any subset
    of ``force`` and the sensors' names (for the default sensor:
    ``velocity``).  A declared value always wins over an estimate from the
    data; a channel not declared is estimated.
``truth``
    optional, the true parameters of a virtual data set, to mark the
    figures (the updating never reads it): each value with its unit, either
    ``{"k": 4.6, "fn": 23.7, "units": {"k": "kN/m", "fn": "Hz"}}`` or
    ``{"k": {"value": 4.6, "unit": "kN/m"}, ...}``.  ``sample``'s
    ``corner.png`` draws a value only where its unit is the model's declared
    unit for that parameter, the same string (nothing converts units); a
    value without a stated unit, or in another unit, is not drawn, and the
    log says so (:func:`bayes_update.reports.posterior.truth_in_model_units`).
    Kept in :attr:`Dataset.extra` and written back unchanged.
any other key
    kept in :attr:`Dataset.extra` and written back unchanged.

A test whose force is zero, or constant, over its whole record is refused
(:class:`DatasetError` naming the file and the test) when a problem is built
on the data set or it is inspected
(:func:`bayes_update.data.checks.require_live_force`); quiet sections within
a record are fine.

Examples: a user model's displacement response::

    {"sampling_rate_hz": 2000.0, "response": "displacement",
     "tests": [{"file": "low.csv", "role": "linear"},
               {"file": "high.csv", "role": "nonlinear"}]}

with ``low.csv`` headed ``time,force,displacement``; two sensors::

    {"sampling_rate_hz": 2000.0,
     "sensors": [{"name": "tip_acc", "response": "acceleration"},
                 {"name": "mid_disp", "response": "displacement"}],
     "tests": [...]}

with CSV files headed ``time,force,tip_acc,mid_disp``; with the noise
declared for two channels, a periodic test and one test's own force noise::

    {"sampling_rate_hz": 610.0,
     "sensors": [{"name": "acc1", "response": "acceleration"},
                 {"name": "acc2", "response": "acceleration"}],
     "noise_sd": {"force": 0.002, "acc1": 1e-3},
     "tests": [{"file": "ms_high.csv", "role": "nonlinear", "period_samples": 4096},
               {"file": "rand_low.csv", "role": "linear", "noise_sd": {"force": 0.001}}]}

:func:`write_dataset` writes the sensors in a canonical form: nothing for the
default single velocity sensor, ``response`` for one sensor named after its
kind, ``sensors`` otherwise.

The errors are those of :mod:`bayes_update.data.dataset`.  The readers never resample,
interpolate or reorder: data that do not meet the format are refused with one of these errors.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from bayes_update.data.csv_reader import read_test_csv
from bayes_update.data.dataset import (
    DEFAULT_LEVEL,
    DEFAULT_RESPONSE,
    DEFAULT_SIGNAL,
    NOISE_TEST_KEYS,
    RESERVED_KEYS,
    RESPONSE_KINDS,
    ROLES,
    TEST_KEYS,
    Dataset,
    DatasetError,
    Record,
    SensorError,
    UnknownResponseError,
    UnknownRoleError,
    check_noise_sd,
    check_period_samples,
    check_sensors,
    is_single_velocity,
    source_label,
)
from bayes_update.data.folder_writer import (
    TIME_FORMAT,
    VALUE_FORMAT,
    dataset_metadata,
    sensors_metadata,
    write_dataset,
)

__all__ = [
    "TIME_FORMAT",
    "UFF_SUFFIXES",
    "VALUE_FORMAT",
    "dataset_metadata",
    "read_dataset",
    "sensors_from_metadata",
    "sensors_metadata",
    "write_dataset",
]

UFF_SUFFIXES = (".uff", ".unv")


# ---------------------------------------------------------------------- reading
def read_dataset(folder) -> Dataset:
    """Read a data-set folder (``dataset.json`` + one CSV or UFF58 file per test).

    Raises a :class:`DatasetError` subclass naming the file on bad input
    (see the module docstring).
    """
    folder = Path(folder)
    meta_path = folder / "dataset.json"
    if not folder.is_dir():
        raise DatasetError(f"{folder}: not a folder (expected a data-set folder with dataset.json)")
    if not meta_path.is_file():
        raise DatasetError(f"{folder}: no dataset.json in this folder")
    try:
        meta = json.loads(meta_path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{meta_path}: invalid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise DatasetError(f"{meta_path}: the top level must be an object")
    for key in ("sampling_rate_hz", "tests"):
        if key not in meta:
            raise DatasetError(f"{meta_path}: missing key {key!r}")
    try:
        fs = float(meta["sampling_rate_hz"])
    except (TypeError, ValueError):
        raise DatasetError(
            f"{meta_path}: sampling_rate_hz must be a number, got {meta['sampling_rate_hz']!r}"
        ) from None
    if not (np.isfinite(fs) and fs > 0):
        raise DatasetError(f"{meta_path}: sampling_rate_hz must be positive, got {fs}")
    rig = meta.get("rig")
    if rig is not None and not isinstance(rig, dict):
        raise DatasetError(f"{meta_path}: 'rig' must be an object")
    sensors = sensors_from_metadata(meta, meta_path)
    channels = ("force",) + tuple(n for n, _ in sensors)
    noise_sd = check_noise_sd(meta.get("noise_sd"), channels, meta_path)
    if not isinstance(meta["tests"], list) or not meta["tests"]:
        raise DatasetError(f"{meta_path}: 'tests' must be a non-empty list")
    tests = []
    for entry in meta["tests"]:
        if not isinstance(entry, dict):
            raise DatasetError(f"{meta_path}: test entry {entry!r} is not an object")
        for key in ("file", "role"):
            if key not in entry:
                raise DatasetError(f"{meta_path}: test entry {entry} lacks {key!r}")
        if entry["role"] not in ROLES:
            raise UnknownRoleError(
                f"{meta_path}: test {entry['file']} has unknown role {entry['role']!r}; roles are {ROLES}"
            )
        path = folder / entry["file"]
        if not path.is_file():
            raise DatasetError(f"{path}: file listed in dataset.json does not exist")
        if path.suffix.lower() in UFF_SUFFIXES:
            if not is_single_velocity(sensors):
                raise SensorError(
                    f"{path}: a UFF test file holds force and velocity records only, but "
                    f"{meta_path} declares the sensors {list(sensors)}; write this test "
                    "as a CSV file with one column per sensor"
                )
            from bayes_update.data.uff import read_uff_test

            time, force, response, _ = read_uff_test(path, fs, entry.get("uff_load_case"))
        else:
            time, force, response = read_test_csv(path, fs, sensors, meta_path)
        where = f"{meta_path} (test {entry['file']})"
        period = check_period_samples(entry.get("period_samples"), len(time), where)
        test_noise = check_noise_sd(entry.get("noise_sd"), channels, where)
        extra = {k: v for k, v in entry.items() if k not in TEST_KEYS + NOISE_TEST_KEYS}
        tests.append(
            Record(
                entry["file"],
                entry.get("signal", DEFAULT_SIGNAL),
                entry.get("level", DEFAULT_LEVEL),
                entry["role"],
                time,
                force,
                response,
                extra,
                source=str(path),
                sensors=sensors,
                period_samples=period,
                noise_sd=test_noise,
            )
        )
    extra = {k: v for k, v in meta.items() if k not in RESERVED_KEYS}
    ds = Dataset(meta.get("name", folder.name), fs, rig, tests, extra, source=str(folder), noise_sd=noise_sd)
    ds.validate()
    return ds


def sensors_from_metadata(meta: dict, meta_path=None) -> tuple:
    """The sensors ``((name, kind), ...)`` a ``dataset.json`` declares (its ``response``
    and ``sensors`` keys; default one velocity sensor).  Raises
    :class:`UnknownResponseError` or :class:`SensorError` naming ``meta_path``."""
    where = source_label(meta_path)
    kinds = f"kinds are {RESPONSE_KINDS}"
    top = meta.get("response", DEFAULT_RESPONSE)
    if top not in RESPONSE_KINDS:
        raise UnknownResponseError(f"{where}: unknown response kind {top!r} ('response'); {kinds}")
    if "sensors" not in meta:
        return ((top, top),)
    block = meta["sensors"]
    if not isinstance(block, list) or not block:
        raise SensorError(f'{where}: \'sensors\' must be a non-empty list of {{"name": ..., "response": ...}} objects')
    sensors = []
    for entry in block:
        if not isinstance(entry, dict) or "name" not in entry:
            raise SensorError(
                f"{where}: sensor entry {entry!r} must be an object with a 'name' "
                "(its CSV column) and a 'response' kind"
            )
        unknown = sorted(set(entry) - {"name", "response"})
        if unknown:
            raise SensorError(
                f"{where}: sensor {entry['name']!r} has unknown key(s) {unknown}; a sensor has 'name' and 'response'"
            )
        kind = entry.get("response", top)
        if kind not in RESPONSE_KINDS:
            raise UnknownResponseError(f"{where}: sensor {entry['name']!r} has unknown response kind {kind!r}; {kinds}")
        if "response" in meta and kind != top:
            raise SensorError(
                f"{where}: sensor {entry['name']!r} has response {kind!r} but the top-level "
                f"'response' is {top!r}; drop the top-level 'response' and give each sensor its "
                "kind, or make them agree"
            )
        sensors.append((entry["name"], kind))
    return check_sensors(sensors, where)
