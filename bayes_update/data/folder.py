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

import copy
import json
from pathlib import Path

import numpy as np

from bayes_update.data.dataset import (
    DEFAULT_LEVEL,
    DEFAULT_RESPONSE,
    DEFAULT_SENSORS,
    DEFAULT_SIGNAL,
    NOISE_TEST_KEYS,
    RESERVED_KEYS,
    RESPONSE_KINDS,
    ROLES,
    TEST_KEYS,
    Dataset,
    DatasetError,
    LengthMismatchError,
    MissingColumnError,
    NonFiniteError,
    Record,
    SensorError,
    UnknownResponseError,
    UnknownRoleError,
    check_noise_sd,
    check_period_samples,
    check_sensors,
    check_time,
    is_single_velocity,
    source_label,
)

UFF_SUFFIXES = (".uff", ".unv")


# Formats of the CSV writer: fixed, so that the same arrays give the same bytes.
TIME_FORMAT = "%.12g"


VALUE_FORMAT = "%.9e"


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
            time, force, response = _read_csv(path, fs, sensors, meta_path)
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


def _diagnose_rows(path: Path, n_columns: int) -> None:
    """Find the first malformed data line of a CSV and raise a precise error."""
    with path.open() as fh:
        fh.readline()
        for lineno, line in enumerate(fh, start=2):
            if not line.strip():
                continue
            fields = [f.strip() for f in line.rstrip("\r\n").split(",")]
            if len(fields) != n_columns:
                raise LengthMismatchError(
                    f"{path}: line {lineno} has {len(fields)} value(s), the header has {n_columns} column(s)"
                )
            for f in fields:
                try:
                    float(f)
                except ValueError:
                    what = "an empty value" if f == "" else f"{f!r}, not a number"
                    raise DatasetError(f"{path}: line {lineno} has {what}") from None


def _read_csv(path: Path, fs: float, sensors=DEFAULT_SENSORS, meta_path=None):
    """Read one test CSV: time [s], force [N], one column per sensor; checks everything.
    Returns ``(time, force, response)``, response (n,) for one sensor, (n, k) for k."""
    names = [n for n, _ in sensors]
    columns = ("time", "force", *names)
    try:
        with path.open() as fh:
            first = fh.readline()
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not a text (CSV) file") from None
    header = [h.strip() for h in first.strip().split(",")]
    missing = [c for c in columns if c not in header]
    if missing:
        hint = ""
        if any(c in names for c in missing):
            declared = f"{meta_path or 'dataset.json'} declares the sensor(s) {[list(s) for s in sensors]}"
            hint = (
                f"; {declared}: name the response column(s) after the sensors, or set "
                "'response'/'sensors' in dataset.json to match the header"
            )
        raise MissingColumnError(f"{path}: missing column(s) {missing}; header is {header}{hint}")
    dup = sorted({h for h in header if header.count(h) > 1 and h in columns})
    if dup:
        raise DatasetError(f"{path}: duplicate column(s) {dup} in header {header}")
    try:
        data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    except ValueError:
        _diagnose_rows(path, len(header))
        raise DatasetError(f"{path}: could not parse the numbers") from None
    if data.shape[0] == 0:
        raise DatasetError(f"{path}: no data rows")
    if data.shape[1] != len(header):
        raise LengthMismatchError(
            f"{path}: {data.shape[1]} value(s) per row but {len(header)} column name(s) in the header"
        )
    cols = {name: data[:, header.index(name)] for name in columns}
    for name, values in cols.items():
        bad = ~np.isfinite(values)
        if bad.any():
            line = int(np.flatnonzero(bad)[0]) + 2
            raise NonFiniteError(f"{path}: column {name!r} has NaN or inf (line {line})")
    check_time(cols["time"], fs, path, line_offset=2)
    if len(names) == 1:
        response = cols[names[0]]
    else:
        response = np.column_stack([cols[n] for n in names])
    return cols["time"], cols["force"], response


# ---------------------------------------------------------------------- writing
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
