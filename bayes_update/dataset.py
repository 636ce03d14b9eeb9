"""Data sets: recorded (or virtual) tests of the rig, in memory and on disk.

In memory
---------
A :class:`Dataset` holds the rig description (:class:`fe.Rig`, SI units), the
sampling rate [Hz] and one :class:`Record` per test.  A record carries three
1-D float arrays of equal length: ``time`` [s], ``force`` [N] (load cell) and
``velocity`` [m/s] (transverse, at the sensor), plus its ``signal``, ``level``
and ``role`` (one of :data:`ROLES`).  The units are fixed (:data:`UNITS`);
importers convert to them explicitly and record what they converted.

On disk: the folder format (DESIGN.md section 5, a public contract)
-------------------------------------------------------------------
A folder with ``dataset.json`` and one file per test.  A CSV file has a
header row and the columns ``time`` [s], ``force`` [N], ``velocity`` [m/s]
(other columns are ignored).  A test file may also be a UFF type-58 file
(``.uff`` or ``.unv``, see :mod:`bayes_update.uff`).  ``dataset.json`` keys:

``name``
    free text (default: the folder name).
``sampling_rate_hz``
    required, the sampling rate of every test [Hz].
``rig``
    the rig (:meth:`fe.Rig.from_dict`: ``length_m``, ``width_m``,
    ``thickness_m``, ``youngs_modulus_pa``, ``poisson_ratio``,
    ``density_kg_m3``, ``shaker_position_m``, ``sensor_position_m`` (from the
    clamped bottom), ``bending_stiffness_factor``); absent keys take the
    paper's values, ``bending_stiffness_factor`` 1.0.  A user's own rig
    (other length, positions) is described here and the model takes its
    geometry from it.
``tests``
    a list of ``{"file", "signal", "level", "role"}``; extra keys of an entry
    are kept in :attr:`Record.meta`.  For a UFF file holding several tests,
    ``"uff_load_case"`` selects the test (R6 F4 of the records).
any other key
    kept in :attr:`Dataset.extra` and written back unchanged (e.g. the
    ``truth`` block of a virtual data set, which the updating code never
    reads).

Errors (all subclasses of :class:`DatasetError`, itself a ``ValueError``; the
message always names the file and what is wrong)
--------------------------------------------------------------------------
=========================  ===================================================
:class:`MissingColumnError`  a CSV lacks ``time``, ``force`` or ``velocity``
                             (or a UFF test lacks its force/velocity record)
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
:class:`DatasetError`        anything else (missing file, bad JSON, bad rig
                             block, unparsable number, ...)
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

from fe import Rig

from .core.problem import DatasetError

ROLES = ("linear", "nonlinear", "validation")
"""Roles of a test: ``linear`` (low level, fits the linear kernel: e_lin),
``nonlinear`` (high level: e_nlin), ``validation`` (not used by the update)."""

COLUMNS = ("time", "force", "velocity")
UNITS = {"time": "s", "force": "N", "velocity": "m/s"}
"""Units of the in-memory channels (fixed)."""

UFF_SUFFIXES = (".uff", ".unv")

# Formats of the CSV writer: fixed, so that the same arrays give the same bytes.
TIME_FORMAT = "%.12g"
VALUE_FORMAT = "%.9e"

# Tolerance of the time-column checks, as a fraction of the sample period.
TIME_TOLERANCE = 0.01


class MissingColumnError(DatasetError):
    """A required column (time, force, velocity) or channel is missing."""


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


def _where(source) -> str:
    return str(source) if source is not None else "<in-memory record>"


def check_channels(time, force, velocity, source=None):
    """Validate three channels; return them as 1-D float arrays.

    Raises :class:`LengthMismatchError` or :class:`NonFiniteError` naming
    ``source`` (a file name, or the record) on bad input.
    """
    where = _where(source)
    arrays = {}
    for name, values in (("time", time), ("force", force), ("velocity", velocity)):
        a = np.asarray(values, dtype=float)
        if a.ndim != 1:
            raise DatasetError(f"{where}: channel {name!r} must be 1-D, got shape {a.shape}")
        arrays[name] = a
    sizes = {k: v.size for k, v in arrays.items()}
    if len(set(sizes.values())) != 1:
        raise LengthMismatchError(f"{where}: channels have different lengths {sizes}")
    for name, values in arrays.items():
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise NonFiniteError(f"{where}: channel {name!r} has NaN or inf "
                                 f"(sample {i}, {int(bad.sum())} bad value(s))")
    return arrays["time"], arrays["force"], arrays["velocity"]


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


@dataclass
class Record:
    """One recorded test of the rig.

    Attributes
    ----------
    file : name of the test's file in the data-set folder (e.g. ``chirp_low.csv``).
    signal : excitation type (``chirp``, ``sine``, or free text).
    level : excitation level (``low``, ``medium``, ``high``, or free text).
    role : one of :data:`ROLES`.
    time : sample times [s], uniform.
    force : shaker force measured by the load cell [N].
    velocity : transverse velocity at the sensor [m/s].
    meta : extra keys of the test entry in ``dataset.json`` (e.g. the
        nominal force amplitude), kept and written back.
    source : where the record was read from (for messages), or None.

    The channels are validated on construction (equal lengths, finite
    values, known role); assigning new arrays later (e.g. a simulated
    velocity) is allowed, :meth:`validate` re-checks.
    """

    file: str
    signal: str
    level: str
    role: str
    time: np.ndarray
    force: np.ndarray
    velocity: np.ndarray
    meta: dict = field(default_factory=dict)
    source: str | None = None

    units = UNITS

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        where = self.source or self.file
        for key in ("file", "signal", "level", "role"):
            if not isinstance(getattr(self, key), str) or not getattr(self, key):
                raise DatasetError(f"{where}: test {key!r} must be a non-empty string, "
                                   f"got {getattr(self, key)!r}")
        if self.role not in ROLES:
            raise UnknownRoleError(f"{where}: unknown role {self.role!r}; roles are {ROLES}")
        self.time, self.force, self.velocity = check_channels(
            self.time, self.force, self.velocity, where)

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


@dataclass
class Dataset:
    """A set of tests of one rig.

    name : free text; sampling_rate_hz : [Hz] of every test; rig :
    :class:`fe.Rig` (SI); tests : list of :class:`Record`; extra : other
    ``dataset.json`` keys, preserved (e.g. ``truth``, never read by the
    updating code); source : folder or file read from, or None.
    """

    name: str
    sampling_rate_hz: float
    rig: Rig
    tests: list
    extra: dict = field(default_factory=dict)
    source: str | None = None

    units = UNITS

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
        """sha256 (hex) of what the updating reads: the sampling rate and each
        test's file name, role and channels (exact float64 bytes).  Caches key
        on this, never on the folder's path: new data at the same path must
        not reuse old results."""
        h = hashlib.sha256(repr(float(self.sampling_rate_hz)).encode())
        for t in self.tests:
            h.update(f"|{t.file}|{t.role}|".encode())
            for channel in (t.time, t.force, t.velocity):
                h.update(np.ascontiguousarray(channel, dtype=np.float64).tobytes())
        return h.hexdigest()

    def validate(self) -> None:
        """Check every record (channels, role, time column against the sampling rate)."""
        where = self.source or self.name
        fs = self.sampling_rate_hz
        if not (isinstance(fs, (int, float)) and np.isfinite(fs) and fs > 0):
            raise DatasetError(f"{where}: sampling_rate_hz must be a positive number, got {fs!r}")
        if not isinstance(self.rig, Rig):
            raise DatasetError(f"{where}: rig must be an fe.Rig")
        files = [t.file for t in self.tests]
        dup = sorted({f for f in files if files.count(f) > 1})
        if dup:
            raise DatasetError(f"{where}: duplicate test file name(s) {dup}")
        for t in self.tests:
            t.validate()
            check_time(t.time, fs, t.source or t.file)


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
    rig_block = meta.get("rig", {})
    if not isinstance(rig_block, dict):
        raise DatasetError(f"{meta_path}: 'rig' must be an object")
    try:
        rig = Rig.from_dict(rig_block)
    except (TypeError, ValueError) as exc:
        raise DatasetError(f"{meta_path}: bad 'rig' block: {exc}") from None
    if not isinstance(meta["tests"], list) or not meta["tests"]:
        raise DatasetError(f"{meta_path}: 'tests' must be a non-empty list")
    tests = []
    for entry in meta["tests"]:
        if not isinstance(entry, dict):
            raise DatasetError(f"{meta_path}: test entry {entry!r} is not an object")
        for key in ("file", "signal", "level", "role"):
            if key not in entry:
                raise DatasetError(f"{meta_path}: test entry {entry} lacks {key!r}")
        if entry["role"] not in ROLES:
            raise UnknownRoleError(f"{meta_path}: test {entry['file']} has unknown role "
                                   f"{entry['role']!r}; roles are {ROLES}")
        path = folder / entry["file"]
        if not path.is_file():
            raise DatasetError(f"{path}: file listed in dataset.json does not exist")
        if path.suffix.lower() in UFF_SUFFIXES:
            from .uff import read_uff_test

            time, force, velocity, _ = read_uff_test(path, fs, entry.get("uff_load_case"))
        else:
            time, force, velocity = _read_csv(path, fs)
        extra = {k: v for k, v in entry.items() if k not in ("file", "signal", "level", "role")}
        tests.append(Record(entry["file"], entry["signal"], entry["level"], entry["role"],
                            time, force, velocity, extra, source=str(path)))
    extra = {k: v for k, v in meta.items()
             if k not in ("name", "sampling_rate_hz", "rig", "tests")}
    ds = Dataset(meta.get("name", folder.name), fs, rig, tests, extra, source=str(folder))
    ds.validate()
    return ds


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


def _read_csv(path: Path, fs: float):
    """Read one test CSV: time [s], force [N], velocity [m/s]; checks everything."""
    try:
        with path.open() as fh:
            first = fh.readline()
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not a text (CSV) file") from None
    header = [h.strip() for h in first.strip().split(",")]
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise MissingColumnError(f"{path}: missing column(s) {missing}; header is {header}")
    dup = sorted({h for h in header if header.count(h) > 1 and h in COLUMNS})
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
    cols = {name: data[:, header.index(name)] for name in COLUMNS}
    for name, values in cols.items():
        bad = ~np.isfinite(values)
        if bad.any():
            line = int(np.flatnonzero(bad)[0]) + 2
            raise NonFiniteError(f"{path}: column {name!r} has NaN or inf (line {line})")
    check_time(cols["time"], fs, path, line_offset=2)
    return cols["time"], cols["force"], cols["velocity"]


# ---------------------------------------------------------------------- writing
def dataset_metadata(dataset: Dataset) -> dict:
    """The ``dataset.json`` content of a data set (the contract keys, then the extra keys)."""
    meta = {
        "name": dataset.name,
        "sampling_rate_hz": dataset.sampling_rate_hz,
        "rig": dataset.rig.to_dict(),
        "tests": [dict({"file": t.file, "signal": t.signal, "level": t.level, "role": t.role},
                       **copy.deepcopy(t.meta)) for t in dataset.tests],
    }
    for key, value in dataset.extra.items():
        if key not in meta:
            meta[key] = copy.deepcopy(value)
    return meta


def write_dataset(dataset: Dataset, folder) -> Path:
    """Write a data set in the folder format (dataset.json + one CSV per test).

    The CSV numbers have a fixed format (time ``%.12g`` [s]; force [N] and
    velocity [m/s] ``%.9e``, ten significant digits), so the same arrays
    always give the same bytes.  Test files are always written as CSV (a
    ``.uff`` file name is replaced by ``.csv``).
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
    (folder / "dataset.json").write_text(json.dumps(meta, indent=2) + "\n")
    for t in dataset.tests:
        arr = np.column_stack([t.time, t.force, t.velocity])
        np.savetxt(folder / t.file, arr, delimiter=",", header=",".join(COLUMNS), comments="",
                   fmt=(TIME_FORMAT, VALUE_FORMAT, VALUE_FORMAT))
    return folder
