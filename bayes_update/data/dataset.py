"""Data sets: recorded (or virtual) tests of a structure, in memory.

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

On disk: :mod:`bayes_update.data.folder` (the folder format, a public
contract) and :mod:`bayes_update.data.uff`.

Errors: :mod:`bayes_update.data.format` (the vocabulary of the format, its
checks and its errors, all re-exported here).

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

from bayes_update.data.format import (  # noqa: F401  (the format's names, re-exported)
    COLUMNS,
    DEFAULT_LEVEL,
    DEFAULT_RESPONSE,
    DEFAULT_SENSORS,
    DEFAULT_SIGNAL,
    NOISE_TEST_KEYS,
    RESERVED_KEYS,
    RESPONSE_KINDS,
    RESPONSE_UNITS,
    ROLES,
    TEST_KEYS,
    TIME_TOLERANCE,
    UNITS,
    DatasetError,
    LengthMismatchError,
    MissingColumnError,
    NonFiniteError,
    NonIncreasingTimeError,
    NonUniformTimeError,
    SamplingRateError,
    SensorError,
    TimeColumnError,
    UnknownResponseError,
    UnknownRoleError,
    check_channels,
    check_noise_sd,
    check_period_samples,
    check_sensors,
    check_time,
    is_single_velocity,
    source_label,
)


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
    period_samples : the excitation's period [samples] when it is periodic
        (several periods of a multisine), declared in ``dataset.json``; None
        when not declared (:mod:`bayes_update.data.noise` may still detect it).
    noise_sd : this test's declared noise ``{channel: sd}`` (``force`` [N] and
        sensor names, sd per sample in the channel's unit); overrides the data
        set's :attr:`Dataset.noise_sd` channel by channel.

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
    period_samples: int | None = None
    noise_sd: dict = field(default_factory=dict)

    def __post_init__(self):
        self.validate()

    def validate(self) -> None:
        where = self.source or self.file
        for key in TEST_KEYS:
            if not isinstance(getattr(self, key), str) or not getattr(self, key):
                raise DatasetError(f"{where}: test {key!r} must be a non-empty string, got {getattr(self, key)!r}")
        if self.role not in ROLES:
            raise UnknownRoleError(f"{where}: unknown role {self.role!r}; roles are {ROLES}")
        self.sensors = check_sensors(self.sensors, where)
        self.time, self.force, self.response = check_channels(self.time, self.force, self.response, where, self.sensors)
        self.period_samples = check_period_samples(self.period_samples, self.time.size, where)
        self.noise_sd = check_noise_sd(self.noise_sd, self.channels, where)

    def _velocity_alias(self) -> None:
        if not is_single_velocity(self.sensors):
            raise SensorError(
                f"{self.source or self.file}: Record.velocity is the response of a single velocity "
                f"sensor, but this record's sensors are {list(self.sensors)}; use Record.response "
                "(columns in sensor order) or Record.channel(name)"
            )

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
    def channels(self) -> tuple:
        """``("force", sensor names...)``: the measured channels."""
        return ("force",) + tuple(n for n, _ in self.sensors)

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
    file read from, or None; noise_sd : the declared noise ``{channel: sd}``
    of every test (``force`` [N] and sensor names, sd per sample in the
    channel's unit), which a test's own :attr:`Record.noise_sd` overrides
    (:meth:`declared_noise_sd`).
    """

    name: str
    sampling_rate_hz: float
    rig: object
    tests: list
    extra: dict = field(default_factory=dict)
    source: str | None = None
    noise_sd: dict = field(default_factory=dict)

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
            raise SensorError(
                f"{self.source or self.name}: {len(sensors)} sensors {sensors}; "
                "response_kind is for a single sensor, see Dataset.sensors"
            )
        return sensors[0][1]

    @property
    def units(self) -> dict:
        """Units of the channels: time, force and each sensor."""
        return {"time": "s", "force": "N", **{n: RESPONSE_UNITS[k] for n, k in self.sensors}}

    def declared_noise_sd(self, record) -> dict:
        """The noise declared for a test: the data set's ``noise_sd`` overridden
        channel by channel by the test's own (``{channel: sd}``)."""
        return {**self.noise_sd, **record.noise_sd}

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
        set with the default sensor hashes exactly as before sensors existed.)
        The declared noise and periods (``noise_sd``, ``period_samples``) are
        hashed when present, so a data set without them hashes as before."""
        h = hashlib.sha256(repr(float(self.sampling_rate_hz)).encode())
        sensors = [tuple(s) for s in self.sensors]
        if sensors != list(DEFAULT_SENSORS):
            h.update(("|sensors|" + json.dumps(sensors)).encode())
        if self.noise_sd:
            h.update(("|noise_sd|" + json.dumps(self.noise_sd, sort_keys=True)).encode())
        for t in self.tests:
            h.update(f"|{t.file}|{t.role}|".encode())
            if t.period_samples is not None or t.noise_sd:
                h.update(json.dumps([t.period_samples, t.noise_sd], sort_keys=True).encode())
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
            raise DatasetError(
                f"{where}: rig must be None, the rig block (a dict) or an object with "
                f"to_dict() such as fe.Rig, got {type(self.rig).__name__}"
            )
        reserved = sorted(k for k in self.extra if k in RESERVED_KEYS)
        if reserved:
            raise DatasetError(
                f"{where}: extra key(s) {reserved} are dataset.json keys of their own; "
                "set them through the Dataset's fields or the records' sensors"
            )
        files = [t.file for t in self.tests]
        dup = sorted({f for f in files if files.count(f) > 1})
        if dup:
            raise DatasetError(f"{where}: duplicate test file name(s) {dup}")
        for t in self.tests:
            t.validate()
            check_time(t.time, fs, t.source or t.file)
        sensors = self.sensors
        self.noise_sd = check_noise_sd(self.noise_sd, ("force",) + tuple(n for n, _ in sensors), where)
        for t in self.tests:
            if list(t.sensors) != sensors:
                raise SensorError(
                    f"{where}: test {t.file} has sensors {list(t.sensors)}, test "
                    f"{self.tests[0].file} {sensors}; every test of a data set has the "
                    "same sensors"
                )
