"""Writing a data set's tests to one UFF file (two type-58 records per test,
the mapping of :mod:`.uff`).  Apart from the reader (:mod:`.uff`): a file
written here is read back there, and neither needs the other's code."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from bayes_update.data.dataset import Dataset, Record, SensorError, is_single_velocity
from bayes_update.data.uff_codes import FORCE_TYPE, TIME_RESPONSE, TIME_TYPE, VELOCITY_TYPE, load_pyuff


def _record_dict(test: Record, channel: str, case: int, binary: bool, fs: float) -> dict:
    force = channel == "force"
    data = np.ascontiguousarray(test.force if force else test.velocity, dtype=float)
    t0 = float(test.time[0])
    return dict(
        type=58,
        binary=int(bool(binary)),
        id1=test.name,
        id2=f"signal={test.signal} level={test.level} role={test.role}",
        id3=f"{channel} [{'N' if force else 'm/s'}]",
        id4="bayes_update",
        id5="",
        func_type=TIME_RESPONSE,
        func_id=0,
        ver_num=0,
        load_case_id=case,
        rsp_ent_name="beam",
        rsp_node=1 if force else 2,
        rsp_dir=2,
        ref_ent_name="beam",
        ref_node=1,
        ref_dir=2,
        ord_data_type=4,
        abscissa_spacing=1,
        abscissa_min=t0,
        abscissa_inc=1.0 / fs,
        z_axis_value=0.0,
        num_pts=data.size,
        abscissa_spec_data_type=TIME_TYPE,
        abscissa_len_unit_exp=0,
        abscissa_force_unit_exp=0,
        abscissa_temp_unit_exp=0,
        abscissa_axis_lab="Time",
        abscissa_axis_units_lab="s",
        ordinate_spec_data_type=FORCE_TYPE if force else VELOCITY_TYPE,
        ordinate_len_unit_exp=0 if force else 1,
        ordinate_force_unit_exp=1 if force else 0,
        ordinate_temp_unit_exp=0,
        ordinate_axis_lab="Force" if force else "Velocity",
        ordinate_axis_units_lab="N" if force else "m/s",
        orddenom_spec_data_type=0,
        orddenom_len_unit_exp=0,
        orddenom_force_unit_exp=0,
        orddenom_temp_unit_exp=0,
        orddenom_axis_lab="",
        orddenom_axis_units_lab="",
        z_axis_spec_data_type=0,
        z_axis_len_unit_exp=0,
        z_axis_force_unit_exp=0,
        z_axis_temp_unit_exp=0,
        z_axis_axis_lab="",
        z_axis_axis_units_lab="",
        data=data,
        x=np.asarray(test.time, dtype=float),
    )


def write_uff(dataset: Dataset, path, binary: bool = False) -> Path:
    """Write every test of ``dataset`` to one UFF file (two type-58 records per test,
    load cases 1, 2, ... in test order; mapping in the module docstring).

    ``binary=True`` stores the values as doubles (exact round trip); ASCII
    (default) keeps twelve significant digits.  An existing file is replaced.
    Only the records are written: the rig and extra keys (e.g. ``truth``)
    belong in a ``dataset.json``.
    """
    pyuff = load_pyuff()
    dataset.validate()
    if not is_single_velocity(dataset.sensors):
        raise SensorError(
            f"{path}: UFF files hold force and velocity records only, but the data set "
            f"{dataset.name!r} has the sensors {dataset.sensors}; write it as a folder "
            "(write_dataset)"
        )
    path = Path(path)
    if path.exists():
        os.remove(path)
    sets = []
    for case, test in enumerate(dataset.tests, start=1):
        for channel in ("force", "velocity"):
            sets.append(_record_dict(test, channel, case, binary, dataset.sampling_rate_hz))
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return path
