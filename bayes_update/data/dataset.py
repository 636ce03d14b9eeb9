"""Data sets: recorded (or virtual) tests of a structure, in memory and on disk.

The data layer knows no model: it never imports :mod:`fe`.  A data set for
any model (``simulate(theta, force, fs) -> response``, docs/models.md) is a
sampling rate, one or several response sensors and a list of tests; the beam
rig's description is one optional block that only the beam code reads
(:func:`bayes_update.models.beam.rig.rig_of`).

In memory
---------
A :class:`Dataset` holds the sampling rate [Hz], one :class:`Record` per test,
the data set's raw ``rig`` block (or None) and the other ``dataset.json``
keys.  A record carries ``time`` [s] and ``force`` [N] (1-D float arrays of
length n) and ``response``: shape (n,) for one sensor, (n, n_sensors) for
several, columns in the order of :attr:`Dataset.sensors`; plus its
``signal``, ``level`` and ``role`` (one of :data:`ROLES`).  A sensor is a
``(name, response kind)`` pair, the kind one of :data:`RESPONSE_KINDS`; the
default, and the beam's, is one sensor ``("velocity", "velocity")``, for
which :attr:`Record.velocity` is an alias of :attr:`Record.response`.  Units
are SI (:data:`RESPONSE_UNITS`: m, m/s, m/s^2); nothing here converts,
integrates or differentiates.

On disk: the folder format (DESIGN.md section 5, a public contract)
-------------------------------------------------------------------
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
    test (R6 F4 of the records).
any other key
    kept in :attr:`Dataset.extra` and written back unchanged (e.g. the
    ``truth`` block of a virtual data set, which the updating code never
    reads).

Examples: a user model's displacement response::

    {"sampling_rate_hz": 2000.0, "response": "displacement",
     "tests": [{"file": "low.csv", "role": "linear"},
               {"file": "high.csv", "role": "nonlinear"}]}

with ``low.csv`` headed ``time,force,displacement``; two sensors::

    {"sampling_rate_hz": 2000.0,
     "sensors": [{"name": "tip_acc", "response": "acceleration"},
                 {"name": "mid_disp", "response": "displacement"}],
     "tests": [...]}

with CSV files headed ``time,force,tip_acc,mid_disp``.

:func:`write_dataset` writes the sensors in a canonical form: nothing for the
default single velocity sensor, ``response`` for one sensor named after its
kind, ``sensors`` otherwise.

Errors (all subclasses of :class:`DatasetError`, itself a ``ValueError``; the
message always names the file and what is wrong)
--------------------------------------------------------------------------
=========================  ===================================================
:class:`MissingColumnError`  a CSV lacks ``time``, ``force`` or a sensor's
                             column (or a UFF test lacks its force/velocity
                             record)
:class:`LengthMismatchError` a CSV row has a different number of values than
                             the header, or channels of a record differ in
                             length
:class:`NonFiniteError`      NaN or inf in a column (the line is named)
:class:`NonIncreasingTimeError` time not strictly increasing (line named)
:class:`NonUniformTimeError` time steps differ by more than 1 % (line named)
:class:`SamplingRateError`   the time column disagrees with
                             ``sampling_rate_hz`` (by more than 1 % of a
                             sample period anywhere in the record)
:class:`UnknownRoleError`    a test's role is not one of :data:`ROLES`
:class:`UnknownResponseError` a response kind is not one of
                             :data:`RESPONSE_KINDS`
:class:`SensorError`         a bad ``sensors`` block: duplicate or invalid
                             names, a sensor's kind contradicting the
                             top-level ``response``; also
                             :attr:`Record.velocity` on a data set whose
                             response is not a single velocity
:class:`DatasetError`        anything else (missing file, bad JSON,
                             unparsable number, ...); a bad ``rig`` block is
                             reported by :func:`bayes_update.models.beam.rig.rig_of`
=========================  ===================================================

The readers never resample, interpolate or reorder: data that do not meet
the format are refused with one of these errors.
"""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bayes_update.core.problem import DatasetError

ROLES = ("linear", "nonlinear", "validation")
"""Roles of a test: ``linear`` (low level, fits the linear kernel: e_lin),
``nonlinear`` (high level: e_nlin), ``validation`` (not used by the update)."""

RESPONSE_KINDS = ("displacement", "velocity", "acceleration")
"""Kinds of a response sensor."""

RESPONSE_UNITS = {"displacement": "m", "velocity": "m/s", "acceleration": "m/s^2"}
"""SI units of each response kind (never converted by the readers)."""

DEFAULT_RESPONSE = "velocity"
DEFAULT_SENSORS = ((DEFAULT_RESPONSE, DEFAULT_RESPONSE),)
"""The default (and the beam's) sensors: one velocity sensor, CSV column ``velocity``."""

COLUMNS = ("time", "force", "velocity")
"""CSV columns of the default single velocity sensor."""
UNITS = {"time": "s", "force": "N", "velocity": "m/s"}
"""Units of the default in-memory channels (fixed)."""

UFF_SUFFIXES = (".uff", ".unv")

# keys of dataset.json read by this module (never in Dataset.extra)
RESERVED_KEYS = ("name", "sampling_rate_hz", "response", "sensors", "rig", "tests")
TEST_KEYS = ("file", "signal", "level", "role")
DEFAULT_SIGNAL = DEFAULT_LEVEL = "unknown"

# Formats of the CSV writer: fixed, so that the same arrays give the same bytes.
TIME_FORMAT = "%.12g"
VALUE_FORMAT = "%.9e"

# Tolerance of the time-column checks, as a fraction of the sample period.
TIME_TOLERANCE = 0.01


class MissingColumnError(DatasetError):
    """A required column (time, force, a sensor's) or channel is missing."""


class LengthMismatchError(DatasetError):
    """Rows or channels of a record have different lengths."""


class NonFiniteError(DatasetError):
    """A channel contains NaN or inf."""


class TimeColumnError(DatasetError):
    """The time column is unusable (base class of the two below)."""


class NonIncreasingTimeError(TimeColumnError):
    """Time does not strictly increase."""


class NonUniformTimeError(TimeColumnError):
    """Time steps are not uniform (the readers never resample)."""


class SamplingRateError(DatasetError):
    """The time column disagrees with the declared sampling rate."""


class UnknownRoleError(DatasetError):
    """A test's role is not one of ROLES."""


class UnknownResponseError(DatasetError):
    """A response kind is not one of RESPONSE_KINDS."""


class SensorError(DatasetError):
    """The sensors are malformed or contradict each other, or the velocity alias
    is used on a data set whose response is not a single velocity."""


def _where(source) -> str:
    return str(source) if source is not None else "<in-memory record>"


def check_sensors(sensors, source=None) -> tuple:
    """Validate sensors (a sequence of ``(name, kind)`` pairs); return them as a tuple of tuples.

    Raises :class:`UnknownResponseError` or :class:`SensorError` naming ``source``.
    """
    where = _where(source)
    try:
        pairs = tuple((name, kind) for name, kind in sensors)
    except (TypeError, ValueError):
        raise SensorError(f"{where}: sensors must be (name, response kind) pairs, got {sensors!r}") from None
    if not pairs:
        raise SensorError(f"{where}: a data set needs at least one sensor")
    for name, kind in pairs:
        if not isinstance(name, str) or not name or name != name.strip() or "," in name \
                or name in ("time", "force"):
            raise SensorError(f"{where}: sensor name {name!r} is not usable as a CSV column: "
                              "give a non-empty name without commas or surrounding spaces, "
                              "other than 'time' and 'force'")
        if kind not in RESPONSE_KINDS:
            raise UnknownResponseError(f"{where}: sensor {name!r} has unknown response kind {kind!r}; "
                                       f"kinds are {RESPONSE_KINDS}")
    names = [n for n, _ in pairs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise SensorError(f"{where}: duplicate sensor name(s) {dup}; give each sensor its own name "
                          "(it is its CSV column)")
    return pairs


def check_channels(time, force, response, source=None, sensors=DEFAULT_SENSORS):
    """Validate a record's channels; return ``(time, force, response)`` as float arrays.

    ``time`` and ``force``: 1-D, length n.  ``response``: shape (n,) for one
    sensor ((n, 1) is accepted and flattened), (n, len(sensors)) for several.
    Raises :class:`LengthMismatchError`, :class:`NonFiniteError` or
    :class:`DatasetError` naming ``source`` (a file name, or the record) on
    bad input.
    """
    where = _where(source)
    sensors = check_sensors(sensors, source)
    names = [n for n, _ in sensors]
    arrays = {}
    for name, values in (("time", time), ("force", force)):
        a = np.asarray(values, dtype=float)
        if a.ndim != 1:
            raise DatasetError(f"{where}: channel {name!r} must be 1-D, got shape {a.shape}")
        arrays[name] = a
    resp = np.asarray(response, dtype=float)
    if len(sensors) == 1:
        if resp.ndim == 2 and resp.shape[1] == 1:
            resp = resp[:, 0]
        if resp.ndim != 1:
            raise DatasetError(f"{where}: channel {names[0]!r} must be 1-D, got shape {resp.shape}")
        columns = {names[0]: resp}
    else:
        if resp.ndim != 2 or resp.shape[1] != len(sensors):
            raise DatasetError(f"{where}: the response must have shape (n, {len(sensors)}), one column "
                               f"per sensor {names}, got shape {resp.shape}")
        columns = {name: resp[:, j] for j, name in enumerate(names)}
    sizes = {k: v.shape[0] for k, v in {**arrays, **columns}.items()}
    if len(set(sizes.values())) != 1:
        raise LengthMismatchError(f"{where}: channels have different lengths {sizes}")
    for name, values in {**arrays, **columns}.items():
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise NonFiniteError(f"{where}: channel {name!r} has NaN or inf "
                                 f"(sample {i}, {int(bad.sum())} bad value(s))")
    return arrays["time"], arrays["force"], resp


def check_time(time, fs: float, source=None, line_offset: int | None = None) -> None:
    """Check that ``time`` [s] is strictly increasing, uniform and sampled at ``fs`` [Hz].

    Tolerance: 1 % of a sample period (:data:`TIME_TOLERANCE`) on every step
    and on every sample's distance from ``time[0] + k / fs``.  Raises
    :class:`NonIncreasingTimeError`, :class:`NonUniformTimeError` or
    :class:`SamplingRateError`.  ``line_offset``: file line of sample 0, for
    the messages (CSV: 2).
    """
    where = _where(source)

    def at(i):
        return f"line {i + line_offset}" if line_offset is not None else f"sample {i}"

    t = np.asarray(time, dtype=float)
    if t.size < 2:
        raise TimeColumnError(f"{where}: fewer than 2 samples")
    dt = np.diff(t)
    bad = np.flatnonzero(dt <= 0)
    if bad.size:
        i = int(bad[0]) + 1
        raise NonIncreasingTimeError(
            f"{where}: time is not strictly increasing at {at(i)} "
            f"(t = {t[i - 1]:.9g} s then {t[i]:.9g} s)")
    step = float(np.median(dt))
    irregular = np.flatnonzero(np.abs(dt - step) > TIME_TOLERANCE * step)
    if irregular.size:
        i = int(irregular[0]) + 1
        raise NonUniformTimeError(
            f"{where}: time column is not uniform: steps between {dt.min():.6g} and "
            f"{dt.max():.6g} s, first irregular step at {at(i)} ({dt[i - 1]:.6g} s against "
            f"{step:.6g} s); resample it yourself, the reader never resamples silently")
    period = 1.0 / fs
    drift = np.abs(t - (t[0] + np.arange(t.size) * period))
    if drift.max() > TIME_TOLERANCE * period:
        i = int(np.argmax(drift > TIME_TOLERANCE * period))
        raise SamplingRateError(
            f"{where}: the time column implies a sampling rate of {1.0 / step:.6g} Hz but "
            f"sampling_rate_hz is {fs:g} Hz (sample {i} is {drift[i]:.3g} s off t0 + k/fs); "
            "fix sampling_rate_hz or the time column, the reader never resamples silently")


def _is_single_velocity(sensors) -> bool:
    return len(sensors) == 1 and sensors[0][1] == "velocity"


@dataclass
class Record:
    """One recorded test.

    Attributes
    ----------
    file : name of the test's file in the data-set folder (e.g. ``chirp_low.csv``).
    signal : excitation type (``chirp``, ``sine``, or free text).
    level : excitation level (``low``, ``medium``, ``high``, or free text).
    role : one of :data:`ROLES`.
    time : sample times [s], uniform, shape (n,).
    force : measured input force [N], shape (n,).
    response : measured response (SI units of each sensor's kind): shape
        (n,) for one sensor, (n, n_sensors) for several, columns in the order
        of ``sensors``.  For the beam: transverse velocity at the sensor [m/s].
    meta : extra keys of the test entry in ``dataset.json`` (e.g. the
        nominal force amplitude), kept and written back.
    source : where the record was read from (for messages), or None.
    sensors : ``((name, response kind), ...)``; default one velocity sensor
        named ``velocity`` (:data:`DEFAULT_SENSORS`).

    ``velocity`` is an alias of ``response`` (read and write) when the record
    has a single velocity sensor; otherwise it raises :class:`SensorError`.
    The channels are validated on construction (equal lengths, finite
    values, known role, shape matching the sensors); assigning new arrays
    later (e.g. a simulated response) is allowed, :meth:`validate` re-checks.
    """

    file: str
    signal: str
    level: str
    role: str
    time: np.ndarray
    force: np.ndarray
    response: np.ndarray
    meta: dict = field(default_factory=dict)
    source: str | None = None
    sensors: tuple = DEFAULT_SENSORS

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        where = self.source or self.file
        for key in TEST_KEYS:
            if not isinstance(getattr(self, key), str) or not getattr(self, key):
                raise DatasetError(f"{where}: test {key!r} must be a non-empty string, "
                                   f"got {getattr(self, key)!r}")
        if self.role not in ROLES:
            raise UnknownRoleError(f"{where}: unknown role {self.role!r}; roles are {ROLES}")
        self.sensors = check_sensors(self.sensors, where)
        self.time, self.force, self.response = check_channels(
            self.time, self.force, self.response, where, self.sensors)

    def _velocity_alias(self) -> None:
        if not _is_single_velocity(self.sensors):
            raise SensorError(
                f"{self.source or self.file}: Record.velocity is the response of a single velocity "
                f"sensor, but this record's sensors are {list(self.sensors)}; use Record.response "
                "(columns in sensor order) or Record.channel(name)")

    @property
    def velocity(self) -> np.ndarray:
        """The response [m/s] of a record with a single velocity sensor (the beam's)."""
        self._velocity_alias()
        return self.response

    @velocity.setter
    def velocity(self, values) -> None:
        self._velocity_alias()
        self.response = values

    def channel(self, name: str) -> np.ndarray:
        """One sensor's response, shape (n,)."""
        names = [n for n, _ in self.sensors]
        if name not in names:
            raise KeyError(f"no sensor named {name!r}; sensors are {names}")
        r = np.asarray(self.response)
        return r if r.ndim == 1 else r[:, names.index(name)]

    @property
    def units(self) -> dict:
        """Units of the channels: time, force and each sensor."""
        return {"time": "s", "force": "N", **{n: RESPONSE_UNITS[k] for n, k in self.sensors}}

    @property
    def name(self) -> str:
        """The test's name: its file name without suffix (e.g. ``chirp_low``)."""
        return Path(self.file).stem

    @property
    def n_samples(self) -> int:
        return int(self.time.size)

    @property
    def sampling_rate_hz(self) -> float:
        """Sampling rate implied by the time column [Hz]."""
        return float(1.0 / np.median(np.diff(self.time)))

    @property
    def duration_s(self) -> float:
        """Record length, n_samples / fs [s]."""
        return self.n_samples / self.sampling_rate_hz


class RigBlock(dict):
    """The raw ``rig`` block of a ``dataset.json`` (a dict, as read).  Only the beam
    code interprets it (:func:`bayes_update.models.beam.rig.rig_of`); :meth:`to_dict`
    gives a plain copy, like :meth:`fe.Rig.to_dict`."""

    def to_dict(self) -> dict:
        return copy.deepcopy(dict(self))


@dataclass
class Dataset:
    """A set of tests of one structure, with the same sensors.

    name : free text; sampling_rate_hz : [Hz] of every test; rig : the beam
    rig's description, kept for the beam code: the raw ``rig`` block of
    ``dataset.json`` (a :class:`RigBlock`, i.e. a dict), None when absent, or
    an object with ``to_dict()`` given by the caller (the beam code passes an
    :class:`fe.Rig`); read it as an ``fe.Rig`` with
    :func:`bayes_update.models.beam.rig.rig_of`.  tests : list of :class:`Record`,
    all with the same sensors; extra : other ``dataset.json`` keys, preserved
    (e.g. ``truth``, never read by the updating code); source : folder or
    file read from, or None.
    """

    name: str
    sampling_rate_hz: float
    rig: object
    tests: list
    extra: dict = field(default_factory=dict)
    source: str | None = None

    def __post_init__(self):
        if isinstance(self.rig, dict) and not isinstance(self.rig, RigBlock):
            self.rig = RigBlock(self.rig)

    @property
    def sensors(self) -> list:
        """``[(name, response kind), ...]``: the response columns, in order."""
        return list(self.tests[0].sensors) if self.tests else list(DEFAULT_SENSORS)

    @property
    def response_kind(self) -> str:
        """The response kind of a data set with a single sensor."""
        sensors = self.sensors
        if len(sensors) != 1:
            raise SensorError(f"{self.source or self.name}: {len(sensors)} sensors {sensors}; "
                              "response_kind is for a single sensor, see Dataset.sensors")
        return sensors[0][1]

    @property
    def units(self) -> dict:
        """Units of the channels: time, force and each sensor."""
        return {"time": "s", "force": "N", **{n: RESPONSE_UNITS[k] for n, k in self.sensors}}

    def by_role(self, role: str) -> list:
        if role not in ROLES:
            raise UnknownRoleError(f"unknown role {role!r}; roles are {ROLES}")
        return [t for t in self.tests if t.role == role]

    def test(self, name: str) -> Record:
        for t in self.tests:
            if t.name == name or t.file == name:
                return t
        raise KeyError(f"no test named {name!r}; tests are {[t.name for t in self.tests]}")

    @property
    def names(self) -> list:
        return [t.name for t in self.tests]

    def fingerprint(self) -> str:
        """sha256 (hex) of what the updating reads: the sampling rate, the
        sensors (names and kinds, when not the default single velocity sensor),
        and each test's file name, role and channels (exact float64 bytes of
        time, force and response).  Caches key on this, never on the folder's
        path: new data at the same path must not reuse old results.  (A data
        set with the default sensor hashes exactly as before sensors existed.)"""
        h = hashlib.sha256(repr(float(self.sampling_rate_hz)).encode())
        sensors = [tuple(s) for s in self.sensors]
        if sensors != list(DEFAULT_SENSORS):
            h.update(("|sensors|" + json.dumps(sensors)).encode())
        for t in self.tests:
            h.update(f"|{t.file}|{t.role}|".encode())
            for channel in (t.time, t.force, t.response):
                h.update(np.ascontiguousarray(channel, dtype=np.float64).tobytes())
        return h.hexdigest()

    def validate(self) -> None:
        """Check every record (channels, role, sensors, time column against the sampling rate)."""
        where = self.source or self.name
        fs = self.sampling_rate_hz
        if not (isinstance(fs, (int, float)) and np.isfinite(fs) and fs > 0):
            raise DatasetError(f"{where}: sampling_rate_hz must be a positive number, got {fs!r}")
        if not (self.rig is None or callable(getattr(self.rig, "to_dict", None))):
            raise DatasetError(f"{where}: rig must be None, the rig block (a dict) or an object with "
                               f"to_dict() such as fe.Rig, got {type(self.rig).__name__}")
        reserved = sorted(k for k in self.extra if k in RESERVED_KEYS)
        if reserved:
            raise DatasetError(f"{where}: extra key(s) {reserved} are dataset.json keys of their own; "
                               "set them through the Dataset's fields or the records' sensors")
        files = [t.file for t in self.tests]
        dup = sorted({f for f in files if files.count(f) > 1})
        if dup:
            raise DatasetError(f"{where}: duplicate test file name(s) {dup}")
        for t in self.tests:
            t.validate()
            check_time(t.time, fs, t.source or t.file)
        sensors = self.sensors
        for t in self.tests:
            if list(t.sensors) != sensors:
                raise SensorError(f"{where}: test {t.file} has sensors {list(t.sensors)}, test "
                                  f"{self.tests[0].file} {sensors}; every test of a data set has the "
                                  "same sensors")


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
        raise DatasetError(f"{meta_path}: sampling_rate_hz must be a number, "
                           f"got {meta['sampling_rate_hz']!r}") from None
    if not (np.isfinite(fs) and fs > 0):
        raise DatasetError(f"{meta_path}: sampling_rate_hz must be positive, got {fs}")
    rig = meta.get("rig")
    if rig is not None and not isinstance(rig, dict):
        raise DatasetError(f"{meta_path}: 'rig' must be an object")
    sensors = sensors_from_metadata(meta, meta_path)
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
            raise UnknownRoleError(f"{meta_path}: test {entry['file']} has unknown role "
                                   f"{entry['role']!r}; roles are {ROLES}")
        path = folder / entry["file"]
        if not path.is_file():
            raise DatasetError(f"{path}: file listed in dataset.json does not exist")
        if path.suffix.lower() in UFF_SUFFIXES:
            if not _is_single_velocity(sensors):
                raise SensorError(f"{path}: a UFF test file holds force and velocity records only, but "
                                  f"{meta_path} declares the sensors {list(sensors)}; write this test "
                                  "as a CSV file with one column per sensor")
            from bayes_update.data.uff import read_uff_test

            time, force, response, _ = read_uff_test(path, fs, entry.get("uff_load_case"))
        else:
            time, force, response = _read_csv(path, fs, sensors, meta_path)
        extra = {k: v for k, v in entry.items() if k not in TEST_KEYS}
        tests.append(Record(entry["file"], entry.get("signal", DEFAULT_SIGNAL),
                            entry.get("level", DEFAULT_LEVEL), entry["role"],
                            time, force, response, extra, source=str(path), sensors=sensors))
    extra = {k: v for k, v in meta.items() if k not in RESERVED_KEYS}
    ds = Dataset(meta.get("name", folder.name), fs, rig, tests, extra, source=str(folder))
    ds.validate()
    return ds


def sensors_from_metadata(meta: dict, meta_path=None) -> tuple:
    """The sensors ``((name, kind), ...)`` a ``dataset.json`` declares (its ``response``
    and ``sensors`` keys; default one velocity sensor).  Raises
    :class:`UnknownResponseError` or :class:`SensorError` naming ``meta_path``."""
    where = _where(meta_path)
    kinds = f"kinds are {RESPONSE_KINDS}"
    top = meta.get("response", DEFAULT_RESPONSE)
    if top not in RESPONSE_KINDS:
        raise UnknownResponseError(f"{where}: unknown response kind {top!r} ('response'); {kinds}")
    if "sensors" not in meta:
        return ((top, top),)
    block = meta["sensors"]
    if not isinstance(block, list) or not block:
        raise SensorError(f"{where}: 'sensors' must be a non-empty list of "
                          '{"name": ..., "response": ...} objects')
    sensors = []
    for entry in block:
        if not isinstance(entry, dict) or "name" not in entry:
            raise SensorError(f"{where}: sensor entry {entry!r} must be an object with a 'name' "
                              "(its CSV column) and a 'response' kind")
        unknown = sorted(set(entry) - {"name", "response"})
        if unknown:
            raise SensorError(f"{where}: sensor {entry['name']!r} has unknown key(s) {unknown}; a "
                              "sensor has 'name' and 'response'")
        kind = entry.get("response", top)
        if kind not in RESPONSE_KINDS:
            raise UnknownResponseError(f"{where}: sensor {entry['name']!r} has unknown response kind "
                                       f"{kind!r}; {kinds}")
        if "response" in meta and kind != top:
            raise SensorError(
                f"{where}: sensor {entry['name']!r} has response {kind!r} but the top-level "
                f"'response' is {top!r}; drop the top-level 'response' and give each sensor its "
                "kind, or make them agree")
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
                    f"{path}: line {lineno} has {len(fields)} value(s), the header has "
                    f"{n_columns} column(s)")
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
            declared = (f"{meta_path or 'dataset.json'} declares the sensor(s) "
                        f"{[list(s) for s in sensors]}")
            hint = (f"; {declared}: name the response column(s) after the sensors, or set "
                    "'response'/'sensors' in dataset.json to match the header")
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
            f"{path}: {data.shape[1]} value(s) per row but {len(header)} column name(s) in the header")
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
    meta["tests"] = [dict({"file": t.file, "signal": t.signal, "level": t.level, "role": t.role},
                          **copy.deepcopy(t.meta)) for t in dataset.tests]
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
    ``fe.Rig``), and not at all when None.
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
        np.savetxt(folder / t.file, arr, delimiter=",", header=",".join(("time", "force", *names)),
                   comments="", fmt=(TIME_FORMAT, VALUE_FORMAT) + (VALUE_FORMAT,) * len(names))
    return folder
