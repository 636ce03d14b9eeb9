"""The data format's vocabulary (roles, response kinds and their SI units, the
columns and keys of dataset.json), its checks and its errors.

Errors
------
(all subclasses of :class:`DatasetError`, itself a ``ValueError``; the
message always names the file and what is wrong)

===============================  ===================================================
:class:`MissingColumnError`      a CSV lacks ``time``, ``force`` or a sensor's
                                 column (or a UFF test lacks its force/velocity
                                 record)
:class:`LengthMismatchError`     a CSV row has a different number of values than
                                 the header, or channels of a record differ in
                                 length
:class:`NonFiniteError`          NaN or inf in a column (the line is named)
:class:`NonIncreasingTimeError`  time not strictly increasing (line named)
:class:`NonUniformTimeError`     time steps differ by more than 1 % (line named)
:class:`SamplingRateError`       the time column disagrees with
                                 ``sampling_rate_hz`` (by more than 1 % of a
                                 sample period anywhere in the record)
:class:`UnknownRoleError`        a test's role is not one of :data:`ROLES`
:class:`UnknownResponseError`    a response kind is not one of
                                 :data:`RESPONSE_KINDS`
:class:`SensorError`             a bad ``sensors`` block: duplicate or invalid
                                 names, a sensor's kind contradicting the
                                 top-level ``response``; also
                                 :attr:`Record.velocity` on a data set whose
                                 response is not a single velocity
:class:`DatasetError`            anything else (missing file, bad JSON,
                                 unparsable number, ...); a bad ``rig`` block is
                                 reported by :func:`bayes_update.models.beam.rig.rig_of`
===============================  ===================================================
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "COLUMNS",
    "DEFAULT_RESPONSE",
    "DEFAULT_SENSORS",
    "DEFAULT_LEVEL",
    "DEFAULT_SIGNAL",
    "DatasetError",
    "LengthMismatchError",
    "MissingColumnError",
    "NOISE_TEST_KEYS",
    "NonFiniteError",
    "NonIncreasingTimeError",
    "NonUniformTimeError",
    "RESERVED_KEYS",
    "RESPONSE_KINDS",
    "RESPONSE_UNITS",
    "ROLES",
    "SamplingRateError",
    "SensorError",
    "TEST_KEYS",
    "TIME_TOLERANCE",
    "TimeColumnError",
    "UNITS",
    "UnknownResponseError",
    "UnknownRoleError",
    "is_single_velocity",
    "source_label",
    "check_channels",
    "check_noise_sd",
    "check_period_samples",
    "check_sensors",
    "check_time",
]


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


# keys of dataset.json read by this module (never in Dataset.extra)
RESERVED_KEYS = ("name", "sampling_rate_hz", "response", "sensors", "rig", "tests", "noise_sd")


TEST_KEYS = ("file", "signal", "level", "role")


NOISE_TEST_KEYS = ("period_samples", "noise_sd")
"""Keys of a test entry read into :attr:`Record.period_samples` and :attr:`Record.noise_sd`
(never in :attr:`Record.meta`)."""


DEFAULT_SIGNAL = DEFAULT_LEVEL = "unknown"


# Tolerance of the time-column checks, as a fraction of the sample period.
TIME_TOLERANCE = 0.01


class DatasetError(ValueError):
    """A data set is malformed or cannot be used as given; the message names the file or the test."""


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


def source_label(source) -> str:
    """Where a record came from, for an error message (its path, or "<in-memory record>")."""
    return str(source) if source is not None else "<in-memory record>"


def check_sensors(sensors, source=None) -> tuple:
    """Validate sensors (a sequence of ``(name, kind)`` pairs); return them as a tuple of tuples.

    Raises :class:`UnknownResponseError` or :class:`SensorError` naming ``source``.
    """
    where = source_label(source)
    try:
        pairs = tuple((name, kind) for name, kind in sensors)
    except (TypeError, ValueError):
        raise SensorError(f"{where}: sensors must be (name, response kind) pairs, got {sensors!r}") from None
    if not pairs:
        raise SensorError(f"{where}: a data set needs at least one sensor")
    for name, kind in pairs:
        if not isinstance(name, str) or not name or name != name.strip() or "," in name or name in ("time", "force"):
            raise SensorError(
                f"{where}: sensor name {name!r} is not usable as a CSV column: "
                "give a non-empty name without commas or surrounding spaces, "
                "other than 'time' and 'force'"
            )
        if kind not in RESPONSE_KINDS:
            raise UnknownResponseError(
                f"{where}: sensor {name!r} has unknown response kind {kind!r}; kinds are {RESPONSE_KINDS}"
            )
    names = [n for n, _ in pairs]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise SensorError(
            f"{where}: duplicate sensor name(s) {dup}; give each sensor its own name (it is its CSV column)"
        )
    return pairs


def check_channels(time, force, response, source=None, sensors=DEFAULT_SENSORS):
    """Validate a record's channels; return ``(time, force, response)`` as float arrays.

    ``time`` and ``force``: 1-D, length n.  ``response``: shape (n,) for one
    sensor ((n, 1) is accepted and flattened), (n, len(sensors)) for several.
    Raises :class:`LengthMismatchError`, :class:`NonFiniteError` or
    :class:`DatasetError` naming ``source`` (a file name, or the record) on
    bad input.
    """
    where = source_label(source)
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
            raise DatasetError(
                f"{where}: the response must have shape (n, {len(sensors)}), one column "
                f"per sensor {names}, got shape {resp.shape}"
            )
        columns = {name: resp[:, j] for j, name in enumerate(names)}
    sizes = {k: v.shape[0] for k, v in {**arrays, **columns}.items()}
    if len(set(sizes.values())) != 1:
        raise LengthMismatchError(f"{where}: channels have different lengths {sizes}")
    for name, values in {**arrays, **columns}.items():
        bad = ~np.isfinite(values)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise NonFiniteError(
                f"{where}: channel {name!r} has NaN or inf (sample {i}, {int(bad.sum())} bad value(s))"
            )
    return arrays["time"], arrays["force"], resp


def check_time(time, fs: float, source=None, line_offset: int | None = None) -> None:
    """Check that ``time`` [s] is strictly increasing, uniform and sampled at ``fs`` [Hz].

    Tolerance: 1 % of a sample period (:data:`TIME_TOLERANCE`) on every step
    and on every sample's distance from ``time[0] + k / fs``.  Raises
    :class:`NonIncreasingTimeError`, :class:`NonUniformTimeError` or
    :class:`SamplingRateError`.  ``line_offset``: file line of sample 0, for
    the messages (CSV: 2).
    """
    where = source_label(source)

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
            f"{where}: time is not strictly increasing at {at(i)} (t = {t[i - 1]:.9g} s then {t[i]:.9g} s)"
        )
    step = float(np.median(dt))
    irregular = np.flatnonzero(np.abs(dt - step) > TIME_TOLERANCE * step)
    if irregular.size:
        i = int(irregular[0]) + 1
        raise NonUniformTimeError(
            f"{where}: time column is not uniform: steps between {dt.min():.6g} and "
            f"{dt.max():.6g} s, first irregular step at {at(i)} ({dt[i - 1]:.6g} s against "
            f"{step:.6g} s); resample it yourself, the reader never resamples silently"
        )
    period = 1.0 / fs
    drift = np.abs(t - (t[0] + np.arange(t.size) * period))
    if drift.max() > TIME_TOLERANCE * period:
        i = int(np.argmax(drift > TIME_TOLERANCE * period))
        raise SamplingRateError(
            f"{where}: the time column implies a sampling rate of {1.0 / step:.6g} Hz but "
            f"sampling_rate_hz is {fs:g} Hz (sample {i} is {drift[i]:.3g} s off t0 + k/fs); "
            "fix sampling_rate_hz or the time column, the reader never resamples silently"
        )


def check_period_samples(period, n_samples: int | None = None, source=None):
    """Validate a declared excitation period: None, or an integer number of samples,
    at least 2 and (given ``n_samples``) at most half the record (two periods).
    Returns it as an int (or None); raises :class:`DatasetError` naming ``source``."""
    if period is None:
        return None
    where = source_label(source)
    if isinstance(period, bool) or not isinstance(period, (int, np.integer)):
        raise DatasetError(
            f"{where}: 'period_samples' must be an integer number of samples (the excitation's period), got {period!r}"
        )
    period = int(period)
    if period < 2:
        raise DatasetError(f"{where}: 'period_samples' must be at least 2, got {period}")
    if n_samples is not None and 2 * period > n_samples:
        raise DatasetError(
            f"{where}: 'period_samples' is {period} but the record has {n_samples} "
            "samples: it must hold at least two periods"
        )
    return period


def check_noise_sd(noise_sd, channels, source=None, key: str = "noise_sd") -> dict:
    """Validate a declared noise block ``{channel: sd}``: channels among ``channels``
    (``force`` and the sensors' names), sd a positive finite number in the channel's
    unit per sample.  Returns a new dict of floats; raises :class:`DatasetError`
    naming ``source`` and ``key``."""
    where = source_label(source)
    if noise_sd is None:
        return {}
    if not isinstance(noise_sd, dict):
        raise DatasetError(
            f"{where}: {key!r} must be an object {{channel: sd}}, e.g. "
            f'{{"force": 0.002, "{channels[-1]}": 1e-4}}, got {noise_sd!r}'
        )
    out = {}
    for name, value in noise_sd.items():
        if name not in channels:
            raise DatasetError(
                f"{where}: {key!r} names channel {name!r}; the channels are "
                f"{list(channels)} ('force' and the sensors' names)"
            )
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.floating, np.integer))
            or not (np.isfinite(value) and value > 0)
        ):
            raise DatasetError(
                f"{where}: {key!r} of channel {name!r} must be a positive number "
                f"(the noise sd per sample in the channel's unit), got {value!r}"
            )
        out[name] = float(value)
    return out


def is_single_velocity(sensors) -> bool:
    """One sensor, measuring velocity: the beam rig's (and the paper's) layout."""
    return len(sensors) == 1 and sensors[0][1] == "velocity"
