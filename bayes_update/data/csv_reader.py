"""One test's CSV file of a data-set folder, read and checked: the header's
columns (time, force, one per sensor), every number finite, the time column at
the declared rate; a file that does not parse is searched for its first
malformed line.  Apart from :mod:`.folder` (the folder and its dataset.json):
the CSV format of a single test file on its own."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bayes_update.data.dataset import (
    DEFAULT_SENSORS,
    DatasetError,
    LengthMismatchError,
    MissingColumnError,
    NonFiniteError,
    check_time,
)


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


def read_test_csv(path: Path, fs: float, sensors=DEFAULT_SENSORS, meta_path=None):
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
