"""UFF (universal file format) type-58 import and export of rig tests, via ``pyuff``.

Mapping (reader and writer)
---------------------------
A test is a pair of type-58 "function at nodal DOF" records with the same
**load case** (R6 F4, ``load_case_id``), both time responses
(R6 F1 ``func_type`` = 1) with an evenly spaced abscissa in seconds.  The
channel is given by the **ordinate specific data type** (R9 F1,
``ordinate_spec_data_type``):

==================  ==============================  ==========================
ordinate type       channel                          accepted units labels
==================  ==============================  ==========================
13 (excitation      ``force`` [N], the load cell     ``N`` (or blank), ``kN``,
force)                                               ``mN``, ``lbf``
11 (velocity)       ``velocity`` [m/s], transverse   ``m/s`` (or blank),
                    at the sensor                    ``mm/s``, ``um/s``, ``in/s``
==================  ==============================  ==========================

Any other ordinate type (e.g. 12 acceleration, 8 displacement) is refused with
an error naming the file and the record: integrating or differentiating is the
user's decision, never done silently.  A blank units label is read as SI (the
assumption is recorded in ``Record.meta["uff"]``); a known non-SI label is
converted by its exact factor (recorded too); an unknown label is an error.
The abscissa units label must be ``s``, ``ms`` or blank (seconds).

Test metadata: the writer puts the test name in ID line 1 (R1, ``id1``) and
``signal=<...> level=<...> role=<...>`` in ID line 2 (``id2``); the reader
takes them from the velocity record if present, else names the test
``test<load case>`` with signal and level ``unknown`` and role
``validation``; pass ``tests={name: {"signal": ..., "level": ..., "role":
...}}`` to :func:`read_uff` to set them.  The writer uses response node 2
(the sensor) and reference node 1 (the shaker), direction +Y (2), for both
records, and load cases 1, 2, ... in test order.  Positions of the nodes are
not read from the file: the rig (geometry, shaker and sensor positions)
comes from ``dataset.json`` or the ``rig`` argument.  A UFF test holds one
velocity sensor: data sets with other response kinds or several sensors are
read and written as CSV only.

Time and sampling rate: UFF58 stores the abscissa start and increment with six
significant digits (format E13.5), so the reader takes the sampling rate as
1 / increment rounded to six significant digits (exact for any rate with at
most six significant digits, such as 1024 Hz) and rebuilds the time as
``t0 + k / fs``.  If a sampling rate is declared (``dataset.json`` or the
``sampling_rate_hz`` argument) the file's rate must agree with it to the
precision of the format (1e-5 relative), else :class:`SamplingRateError`.  An
unevenly spaced abscissa (R7 F3 = 0) is checked like a CSV time column
(uniform, increasing, at the declared rate) and never resampled.

The data values round-trip exactly with ``binary=True`` and to twelve
significant digits in ASCII (pyuff writes E20.11).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from bayes_update.data.dataset import (
    ROLES,
    Dataset,
    DatasetError,
    LengthMismatchError,
    MissingColumnError,
    NonFiniteError,
    Record,
    SamplingRateError,
    UnknownRoleError,
    check_time,
)
from bayes_update.data.uff_codes import (
    FORCE_TYPE,
    FORCE_UNITS,
    RATE_TOLERANCE,
    SPEC_NAMES,
    TIME_RESPONSE,
    TIME_TYPE,
    TIME_UNITS,
    VELOCITY_TYPE,
    VELOCITY_UNITS,
    load_pyuff,
)
from bayes_update.data.uff_writer import write_uff

__all__ = [
    "FORCE_TYPE",
    "FORCE_UNITS",
    "RATE_TOLERANCE",
    "SPEC_NAMES",
    "TIME_RESPONSE",
    "TIME_TYPE",
    "TIME_UNITS",
    "VELOCITY_TYPE",
    "VELOCITY_UNITS",
    "read_uff",
    "read_uff_test",
    "write_uff",
]


def _round_sig(x: float, digits: int = 6) -> float:
    if x == 0 or not math.isfinite(x):
        return x
    return round(x, digits - 1 - int(math.floor(math.log10(abs(x)))))


def _read_sets(path: Path) -> list:
    pyuff = load_pyuff()
    if not path.is_file():
        raise DatasetError(f"{path}: UFF file does not exist")
    try:
        uff = pyuff.UFF(str(path))
        types = list(uff.get_set_types())
    except Exception as exc:  # pyuff raises bare Exceptions on bad files
        raise DatasetError(f"{path}: not a readable UFF file ({exc})") from None
    idx = [i for i, t in enumerate(types) if int(t) == 58]
    if not idx:
        raise DatasetError(f"{path}: no type-58 records (record types found: {sorted({int(t) for t in types})})")
    try:
        sets = uff.read_sets(idx)
    except Exception as exc:
        raise DatasetError(f"{path}: could not read the type-58 records ({exc})") from None
    if isinstance(sets, dict):
        sets = [sets]
    return list(zip(idx, sets))


def _channel(path, i, rec):
    """(channel name, SI factor, units label) of one record; raises on anything else."""
    where = f"{path}: record {i} (load case {rec.get('load_case_id')}, id1 {rec.get('id1', '')!r})"
    if int(rec.get("func_type", 0)) != TIME_RESPONSE:
        raise DatasetError(
            f"{where}: function type {rec.get('func_type')} is not a time response (1); only time histories can be read"
        )
    spec = int(rec.get("ordinate_spec_data_type", 0))
    label = str(rec.get("ordinate_axis_units_lab", "")).strip()
    if spec == FORCE_TYPE:
        name, table = "force", FORCE_UNITS
    elif spec == VELOCITY_TYPE:
        name, table = "velocity", VELOCITY_UNITS
    else:
        raise DatasetError(
            f"{where}: ordinate type {spec} ({SPEC_NAMES.get(spec, 'other')}) is neither "
            f"{FORCE_TYPE} (excitation force) nor {VELOCITY_TYPE} (velocity); convert it "
            "yourself, the reader does not integrate or differentiate"
        )
    if label.lower() not in table:
        raise DatasetError(f"{where}: unknown {name} units label {label!r}; known: {sorted(k for k in table if k)}")
    if np.iscomplexobj(rec.get("data")):
        raise DatasetError(f"{where}: complex data; a time response must be real")
    return name, table[label.lower()], label


def _time_axis(path, i, rec, fs):
    """Time [s] of one record and the file's sampling rate [Hz]."""
    where = f"{path}: record {i} (load case {rec.get('load_case_id')})"
    tlabel = str(rec.get("abscissa_axis_units_lab", "")).strip().lower()
    if tlabel not in TIME_UNITS:
        raise DatasetError(f"{where}: abscissa units {tlabel!r} are not a time unit (s, ms or blank)")
    scale = TIME_UNITS[tlabel]
    data = np.asarray(rec["data"], dtype=float)
    n = data.size
    if int(rec.get("abscissa_spacing", 1)) == 1:
        inc = float(rec["abscissa_inc"]) * scale
        if not inc > 0:
            raise DatasetError(f"{where}: abscissa increment {rec['abscissa_inc']} is not positive")
        fs_file = _round_sig(1.0 / inc, 6)
        if fs is not None and abs(fs_file - fs) > RATE_TOLERANCE * fs:
            raise SamplingRateError(
                f"{where}: the abscissa increment {inc:.6g} s implies {fs_file:g} Hz but the "
                f"declared sampling rate is {fs:g} Hz; the reader never resamples"
            )
        rate = fs if fs is not None else fs_file
        t0 = float(rec.get("abscissa_min", 0.0)) * scale
        return t0 + np.arange(n) / rate, rate
    t = np.asarray(rec["x"], dtype=float) * scale
    if not np.all(np.isfinite(t)):
        raise NonFiniteError(f"{where}: abscissa has NaN or inf")
    rate = fs if fs is not None else _round_sig(1.0 / float(np.median(np.diff(t))), 6)
    check_time(t, rate, where)
    return t, rate


def _group_tests(path: Path, fs: float | None) -> dict:
    """{load case: {"force": ..., "velocity": ..., "time": ..., "fs": ..., "rec": velocity record}}."""
    groups = {}
    for i, rec in _read_sets(path):
        name, factor, label = _channel(path, i, rec)
        case = int(rec.get("load_case_id", 0))
        g = groups.setdefault(case, {"records": {}})
        if name in g["records"]:
            raise DatasetError(
                f"{path}: load case {case} has more than one {name} record (records {g['records'][name][0]} and {i})"
            )
        g["records"][name] = (i, rec, factor, label)
    out = {}
    for case, g in groups.items():
        recs = g["records"]
        missing = [c for c in ("force", "velocity") if c not in recs]
        if missing:
            raise MissingColumnError(
                f"{path}: load case {case} has no {' and no '.join(missing)} record "
                f"(ordinate type {FORCE_TYPE} for force, {VELOCITY_TYPE} for velocity)"
            )
        entry = {}
        times = {}
        for ch, (i, rec, factor, label) in recs.items():
            values = np.asarray(rec["data"], dtype=float) * factor
            bad = ~np.isfinite(values)
            if bad.any():
                raise NonFiniteError(
                    f"{path}: record {i} ({ch}, load case {case}) has NaN or inf (sample {int(np.flatnonzero(bad)[0])})"
                )
            entry[ch] = values
            times[ch], entry["fs"] = _time_axis(path, i, rec, fs)
            entry.setdefault("units", {})[ch] = {"label": label, "factor_to_si": factor}
        if entry["force"].size != entry["velocity"].size:
            raise LengthMismatchError(
                f"{path}: load case {case}: force has {entry['force'].size} samples, velocity {entry['velocity'].size}"
            )
        if not np.allclose(times["force"], times["velocity"], rtol=0, atol=0.01 / entry["fs"]):
            raise DatasetError(
                f"{path}: load case {case}: force and velocity records have different time axes (start or increment)"
            )
        entry["time"] = times["velocity"]
        entry["rec"] = recs["velocity"][1]
        out[case] = entry
    return out


def _parse_id2(text: str) -> dict:
    return dict(re.findall(r"(signal|level|role)\s*=\s*([^\s;,]+)", text or ""))


def read_uff_test(path, fs: float | None = None, load_case=None):
    """One test from a UFF file: ``(time [s], force [N], velocity [m/s], info)``.

    The file must hold exactly one test (one load case) unless ``load_case``
    selects one.  ``fs`` [Hz]: the declared sampling rate (checked).  Used by
    :func:`bayes_update.data.folder.read_dataset` for ``.uff``/``.unv`` test files.
    """
    path = Path(path)
    groups = _group_tests(path, fs)
    if load_case is None:
        if len(groups) != 1:
            raise DatasetError(
                f"{path}: holds {len(groups)} tests (load cases {sorted(groups)}); set 'uff_load_case' in dataset.json"
            )
        load_case = next(iter(groups))
    if int(load_case) not in groups:
        raise DatasetError(f"{path}: no load case {load_case}; load cases are {sorted(groups)}")
    g = groups[int(load_case)]
    info = {
        "load_case": int(load_case),
        "units": g["units"],
        "sampling_rate_hz": g["fs"],
        "id1": str(g["rec"].get("id1", "")).strip(),
        "id2": str(g["rec"].get("id2", "")).strip(),
    }
    return g["time"], g["force"], g["velocity"], info


def read_uff(
    path, rig=None, name: str | None = None, sampling_rate_hz: float | None = None, tests: dict | None = None
) -> Dataset:
    """Read a UFF file of type-58 time records into a :class:`Dataset`.

    Parameters
    ----------
    path : the ``.uff``/``.unv`` file (see the module docstring for the mapping).
    rig : the beam rig kept in :attr:`Dataset.rig` (an ``fe.Rig`` or a ``rig``
        block dict; default None, which the beam code reads as the paper's
        geometry, factor 1.0: :func:`bayes_update.models.beam.rig.rig_of`).
    name : data-set name (default: the file name).
    sampling_rate_hz : declared rate [Hz], checked against the file (default:
        taken from the file).
    tests : optional ``{test name: {"signal", "level", "role"}}`` overriding
        what the file says.
    """
    path = Path(path)
    groups = _group_tests(path, sampling_rate_hz)
    rates = {case: g["fs"] for case, g in groups.items()}
    fs = next(iter(rates.values()))
    if any(abs(r - fs) > RATE_TOLERANCE * fs for r in rates.values()):
        raise SamplingRateError(f"{path}: tests have different sampling rates {rates}")
    tests = tests or {}
    records = []
    for case in sorted(groups):
        g = groups[case]
        test_name = str(g["rec"].get("id1", "")).strip() or f"test{case}"
        test_name = re.sub(r"[^\w.-]+", "_", test_name)
        meta = {"signal": "unknown", "level": "unknown", "role": "validation"}
        meta.update(_parse_id2(str(g["rec"].get("id2", ""))))
        meta.update(tests.get(test_name, {}))
        if meta["role"] not in ROLES:
            raise UnknownRoleError(
                f"{path}: load case {case} ({test_name}) has unknown role {meta['role']!r}; roles are {ROLES}"
            )
        extra = {"uff_load_case": case}
        if any(u["factor_to_si"] != 1.0 or not u["label"] for u in g["units"].values()):
            extra["uff"] = {"units_in_file": g["units"], "note": "converted to SI; a blank label was read as SI"}
        records.append(
            Record(
                f"{test_name}.uff",
                meta["signal"],
                meta["level"],
                meta["role"],
                g["time"],
                g["force"],
                g["velocity"],
                extra,
                source=f"{path} (load case {case})",
            )
        )
    names = [r.file for r in records]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DatasetError(f"{path}: several load cases share the test name(s) {dup} (id1)")
    ds = Dataset(name or path.stem, float(fs), rig, records, source=str(path))
    ds.validate()
    return ds
