"""Input checks shared by the basis, the fitting and the pole-selection functions."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .kautz import KautzPole, RealPole, _check_n_functions

#: Highest kernel order supported.
MAX_ORDER = 3


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


def _normalise_n_functions(n_functions) -> dict:
    if isinstance(n_functions, Mapping):
        items = list(n_functions.items())
    elif isinstance(n_functions, (int, np.integer)) and not isinstance(n_functions, bool):
        items = [(1, n_functions)]
    elif isinstance(n_functions, Sequence) and not isinstance(n_functions, str):
        items = list(enumerate(n_functions, start=1))
    else:
        raise ValueError(
            "n_functions must be a tuple (J1, J2, J3), a dict {order: J} or an int (order 1 only); "
            f"got {n_functions!r}"
        )
    out = {}
    for order, J in items:
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= order <= MAX_ORDER:
            raise ValueError(f"kernel orders must be integers 1..{MAX_ORDER}, got {order!r}")
        if J is None or (not isinstance(J, bool) and isinstance(J, (int, np.integer)) and J == 0):
            continue  # order omitted
        try:
            out[int(order)] = _check_n_functions(J)
        except ValueError as exc:
            raise ValueError(f"order {order}: {exc}") from None
    if not out:
        raise ValueError(f"no kernel order selected by n_functions = {n_functions!r}")
    return dict(sorted(out.items()))


def _per_order(value, orders, name):
    """Spread a scalar / sequence (aligned with orders 1..) / dict over ``orders``."""
    if isinstance(value, np.ndarray):
        value = value.item() if value.ndim == 0 else list(value)
    if isinstance(value, Mapping):
        missing = [n for n in orders if n not in value]
        if missing:
            raise ValueError(f"{name}: no entry for order(s) {missing}")
        return {n: value[n] for n in orders}
    if isinstance(value, Sequence) and not isinstance(value, str):
        if len(value) < max(orders):
            raise ValueError(f"{name}: a sequence must give one entry per order 1..{max(orders)}, got {len(value)}")
        return {n: value[n - 1] for n in orders}
    return {n: value for n in orders}


def _modes_of(entry, order) -> tuple:
    """One order's modes: a pole, or a non-empty sequence of poles."""
    if isinstance(entry, (KautzPole, RealPole)):
        modes = (entry,)
    else:
        modes = tuple(entry) if isinstance(entry, Sequence) else None
    if not modes or not all(isinstance(p, (KautzPole, RealPole)) for p in modes):
        raise ValueError(
            f"pole for order {order} must be a KautzPole (use KautzPole.from_modal / from_z), a "
            f"RealPole, or a non-empty sequence of them (one per mode), got {entry!r}"
        )
    return modes
