"""Input checks shared by the fitting and pole-selection functions."""
from __future__ import annotations

import numpy as np


def as_record_list(x, name: str) -> tuple[list, bool]:
    """One record (1-D array) or several (list/tuple of 1-D arrays, or a 2-D
    array whose rows are records) -> (list of float arrays, was_single)."""
    if isinstance(x, (list, tuple)) and len(x) > 0 and np.ndim(x[0]) >= 1:
        records = [np.asarray(r, dtype=float) for r in x]
        single = False
    else:
        arr = np.asarray(x, dtype=float)
        if arr.ndim == 1:
            records, single = [arr], True
        elif arr.ndim == 2:
            records, single = list(arr), False
        else:
            raise ValueError(
                f"{name} must be a 1-D array (one record) or a list of 1-D arrays (several records); "
                f"got an array of shape {arr.shape}"
            )
    if not records:
        raise ValueError(f"{name}: no records given")
    for k, r in enumerate(records):
        label = name if single else f"{name}[{k}]"
        if r.ndim != 1:
            raise ValueError(f"{label} must be 1-D (samples in time), got shape {r.shape}")
        if r.size == 0:
            raise ValueError(f"{label} is empty")
        bad = ~np.isfinite(r)
        if bad.any():
            first = int(np.argmax(bad))
            raise ValueError(
                f"{label} contains {int(bad.sum())} NaN/inf value(s) (first at sample {first}); "
                "remove or interpolate them before fitting"
            )
    return records, single


def paired_records(u, y) -> tuple[list, list, bool]:
    """Validate input/output records: same number of records, equal lengths."""
    us, single_u = as_record_list(u, "u")
    ys, single_y = as_record_list(y, "y")
    if len(us) != len(ys):
        raise ValueError(f"got {len(us)} input record(s) but {len(ys)} output record(s); pass one y per u")
    for k, (a, b) in enumerate(zip(us, ys)):
        if a.size != b.size:
            where = "" if single_u and single_y else f" (record {k})"
            raise ValueError(
                f"input and output records have unequal lengths{where}: len(u) = {a.size}, "
                f"len(y) = {b.size}; trim them to the same samples"
            )
    return us, ys, single_u and single_y
