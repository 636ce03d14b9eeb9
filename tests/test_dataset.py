"""Data sets: in-memory checks, folder and UFF58 round trips, and every
malformed-input case raising its documented error naming the file."""

import json

import numpy as np
import pytest

from bayes_update.data.dataset import (
    Dataset,
    DatasetError,
    LengthMismatchError,
    MissingColumnError,
    NonFiniteError,
    NonIncreasingTimeError,
    NonUniformTimeError,
    Record,
    SamplingRateError,
    UnknownRoleError,
)
from bayes_update.data.folder import read_dataset, write_dataset
from bayes_update.data.uff import read_uff, write_uff
from bayes_update.models.beam.rig import rig_of
from fe import Rig

FS = 1024.0


def make_records(n=512, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) / FS
    specs = [
        ("chirp_low.csv", "chirp", "low", "linear"),
        ("chirp_high.csv", "chirp", "high", "nonlinear"),
        ("sine_low.csv", "sine", "low", "validation"),
    ]
    return [
        Record(
            f, s, lvl, role, t, 0.1 * rng.standard_normal(n), 1e-3 * rng.standard_normal(n), {"force_amplitude_n": 0.1}
        )
        for f, s, lvl, role in specs
    ]


def make_dataset(**rig):
    return Dataset("tiny", FS, Rig(**rig), make_records(), extra={"truth": {"F": 77.0, "x": [1, 2]}})


@pytest.fixture
def folder(tmp_path):
    return write_dataset(make_dataset(), tmp_path / "data")


def assert_same_records(a: Dataset, b: Dataset, rtol=0.0):
    assert [t.name for t in a.tests] == [t.name for t in b.tests]
    for x, y in zip(a.tests, b.tests):
        assert (x.signal, x.level, x.role) == (y.signal, y.level, y.role)
        for ch in ("time", "force", "velocity"):
            np.testing.assert_allclose(getattr(x, ch), getattr(y, ch), rtol=rtol, atol=0)


# ------------------------------------------------------------------ round trips
def test_folder_round_trip_same_arrays(tmp_path):
    ds = make_dataset(length_m=0.5, sensor_position_m=0.25, bending_stiffness_factor=1.24)
    read = read_dataset(write_dataset(ds, tmp_path / "a"))
    assert read.sampling_rate_hz == FS
    assert rig_of(read) == ds.rig
    assert read.extra["truth"] == {"F": 77.0, "x": [1, 2]}
    assert read.tests[0].meta == {"force_amplitude_n": 0.1}
    assert_same_records(ds, read, rtol=1e-9)  # %.9e: ten significant digits
    # a second write of what was read gives the same bytes (fixed format)
    again = write_dataset(read, tmp_path / "b")
    for f in ("dataset.json", "chirp_low.csv", "chirp_high.csv", "sine_low.csv"):
        assert (again / f).read_bytes() == (tmp_path / "a" / f).read_bytes()


@pytest.mark.parametrize("binary", [False, True])
def test_uff58_round_trip_same_arrays(tmp_path, binary):
    ds = make_dataset()
    path = write_uff(ds, tmp_path / "tests.uff", binary=binary)
    read = read_uff(path, rig=ds.rig)
    assert read.sampling_rate_hz == FS
    assert [t.name for t in read.tests] == [t.name for t in ds.tests]
    for x, y in zip(ds.tests, read.tests):
        assert (x.signal, x.level, x.role) == (y.signal, y.level, y.role)
        np.testing.assert_array_equal(x.time, y.time)  # t0 + k / fs rebuilt exactly
        if binary:
            np.testing.assert_array_equal(x.force, y.force)
            np.testing.assert_array_equal(x.velocity, y.velocity)
        else:  # pyuff writes E20.11: twelve significant digits
            np.testing.assert_allclose(x.force, y.force, rtol=1e-11)
            np.testing.assert_allclose(x.velocity, y.velocity, rtol=1e-11)
    # UFF -> folder -> back: same arrays again
    back = read_dataset(write_dataset(read, tmp_path / "folder"))
    assert [t.file for t in back.tests] == ["chirp_low.csv", "chirp_high.csv", "sine_low.csv"]
    assert_same_records(read, back, rtol=1e-9)


def test_dataset_json_may_reference_uff_files_and_sets_the_rig(tmp_path):
    ds = make_dataset()
    folder = tmp_path / "user"
    folder.mkdir()
    write_uff(ds, folder / "all.uff")
    meta = {
        "name": "my rig",
        "sampling_rate_hz": FS,
        "rig": {"length_m": 0.6, "shaker_position_m": 0.1, "sensor_position_m": 0.3},
        "tests": [{"file": "all.uff", "uff_load_case": 2, "signal": "chirp", "level": "high", "role": "nonlinear"}],
    }
    (folder / "dataset.json").write_text(json.dumps(meta))
    read = read_dataset(folder)
    assert rig_of(read).length_m == 0.6 and rig_of(read).sensor_position_m == 0.3
    assert rig_of(read).bending_stiffness_factor == 1.0  # absent key: locking-free
    np.testing.assert_allclose(read.tests[0].velocity, ds.tests[1].velocity, rtol=1e-11)
    meta["tests"][0].pop("uff_load_case")
    (folder / "dataset.json").write_text(json.dumps(meta))
    with pytest.raises(DatasetError, match=r"all.uff: holds 3 tests"):
        read_dataset(folder)


def test_uff_units_are_converted_explicitly(tmp_path):
    import pyuff

    from bayes_update.data.uff_writer import _record_dict

    rec = make_records()[0]
    f = _record_dict(rec, "force", 1, False, FS)
    v = _record_dict(rec, "velocity", 1, False, FS)
    v.update(data=rec.velocity * 1e3, ordinate_axis_units_lab="mm/s")
    path = tmp_path / "mm.uff"
    pyuff.UFF(str(path)).write_sets([f, v], mode="add")
    read = read_uff(path)
    np.testing.assert_allclose(read.tests[0].velocity, rec.velocity, rtol=1e-11)
    assert read.tests[0].meta["uff"]["units_in_file"]["velocity"]["label"] == "mm/s"
    v.update(ordinate_axis_units_lab="furlong/s")
    path.unlink()
    pyuff.UFF(str(path)).write_sets([f, v], mode="add")
    with pytest.raises(DatasetError, match=r"mm.uff.*unknown velocity units label 'furlong/s'"):
        read_uff(path)


# ------------------------------------------------------------- malformed input
def edit_csv(folder, name, edit):
    path = folder / name
    lines = path.read_text().splitlines()
    lines = edit(lines)
    path.write_text("\n".join(lines) + "\n")


def test_missing_column(folder):
    edit_csv(folder, "sine_low.csv", lambda L: [L[0].replace("velocity", "speed")] + L[1:])
    with pytest.raises(MissingColumnError, match=r"sine_low.csv: missing column\(s\) \['velocity'\]"):
        read_dataset(folder)


def test_non_increasing_time(folder):
    def swap(L):
        L[10], L[11] = L[11], L[10]
        return L

    edit_csv(folder, "chirp_high.csv", swap)
    with pytest.raises(
        NonIncreasingTimeError,
        match=r"chirp_high.csv: time is not strictly "
        r"increasing at line 12",
    ):
        read_dataset(folder)


def test_non_uniform_time(folder):
    edit_csv(folder, "chirp_low.csv", lambda L: L[:100] + L[101:])  # a dropped sample
    with pytest.raises(
        NonUniformTimeError,
        match=r"chirp_low.csv: time column is not uniform"
        r".*line 101.*never resamples",
    ):
        read_dataset(folder)


def test_sampling_rate_disagrees_with_time_column(folder):
    meta = json.loads((folder / "dataset.json").read_text())
    meta["sampling_rate_hz"] = 1000.0
    (folder / "dataset.json").write_text(json.dumps(meta))
    with pytest.raises(
        SamplingRateError,
        match=r"chirp_low.csv: the time column implies a "
        r"sampling rate of 1024 Hz but sampling_rate_hz "
        r"is 1000 Hz",
    ):
        read_dataset(folder)


@pytest.mark.parametrize("bad", ["nan", "inf", "-inf"])
def test_nan_or_inf(folder, bad):
    def poison(L):
        t, f, v = L[7].split(",")
        L[7] = ",".join([t, bad, v])
        return L

    edit_csv(folder, "sine_low.csv", poison)
    with pytest.raises(
        NonFiniteError,
        match=r"sine_low.csv: column 'force' has NaN or inf "
        r"\(line 8\)",
    ):
        read_dataset(folder)


def test_row_with_missing_value_is_a_length_mismatch(folder):
    def short(L):
        L[20] = ",".join(L[20].split(",")[:2])
        return L

    edit_csv(folder, "chirp_low.csv", short)
    with pytest.raises(
        LengthMismatchError,
        match=r"chirp_low.csv: line 21 has 2 value\(s\), "
        r"the header has 3",
    ):
        read_dataset(folder)


def test_unparsable_number_names_line(folder):
    edit_csv(folder, "chirp_low.csv", lambda L: L[:5] + ["0.1,abc,0.2"] + L[6:])
    with pytest.raises(DatasetError, match=r"chirp_low.csv: line 6 has 'abc', not a number"):
        read_dataset(folder)


def test_channels_of_different_length_in_memory():
    t = np.arange(10) / FS
    with pytest.raises(LengthMismatchError, match=r"x.csv: channels have different lengths"):
        Record("x.csv", "sine", "low", "validation", t, np.zeros(10), np.zeros(9))
    with pytest.raises(NonFiniteError, match=r"x.csv: channel 'velocity' has NaN or inf"):
        Record("x.csv", "sine", "low", "validation", t, np.zeros(10), np.full(10, np.nan))


def test_unknown_role(folder):
    meta = json.loads((folder / "dataset.json").read_text())
    meta["tests"][1]["role"] = "calibration"
    (folder / "dataset.json").write_text(json.dumps(meta))
    with pytest.raises(
        UnknownRoleError,
        match=r"dataset.json: test chirp_high.csv has unknown "
        r"role 'calibration'",
    ):
        read_dataset(folder)
    with pytest.raises(UnknownRoleError, match="unknown role"):
        Record("x.csv", "sine", "low", "reference", np.arange(3.0), np.zeros(3), np.zeros(3))


def test_missing_file_bad_json_and_bad_rig(folder):
    (folder / "sine_low.csv").unlink()
    with pytest.raises(DatasetError, match=r"sine_low.csv: file listed in dataset.json does not exist"):
        read_dataset(folder)
    meta = json.loads((folder / "dataset.json").read_text())
    meta["rig"]["sensor_position_m"] = 2.0
    meta["tests"] = meta["tests"][:2]  # without the missing file
    (folder / "dataset.json").write_text(json.dumps(meta))
    read = read_dataset(folder)  # the data layer keeps the block; the beam code reads it
    assert read.rig["sensor_position_m"] == 2.0
    with pytest.raises(DatasetError, match=r"dataset.json: bad 'rig' block: sensor_position_m"):
        rig_of(read)
    (folder / "dataset.json").write_text("{not json")
    with pytest.raises(DatasetError, match=r"dataset.json: invalid JSON"):
        read_dataset(folder)


def test_errors_are_value_errors():
    for cls in (
        MissingColumnError,
        LengthMismatchError,
        NonFiniteError,
        NonIncreasingTimeError,
        NonUniformTimeError,
        SamplingRateError,
        UnknownRoleError,
    ):
        assert issubclass(cls, DatasetError) and issubclass(cls, ValueError)


# ------------------------------------------------------------------- UFF errors
def test_uff_wrong_channel_type_rate_and_lengths(tmp_path):
    import pyuff

    from bayes_update.data.uff_writer import _record_dict

    rec = make_records()[0]
    f = _record_dict(rec, "force", 1, False, FS)
    v = _record_dict(rec, "velocity", 1, False, FS)

    def write(name, sets):
        path = tmp_path / name
        pyuff.UFF(str(path)).write_sets(sets, mode="add")
        return path

    acc = dict(v, ordinate_spec_data_type=12, ordinate_axis_units_lab="m/s^2")
    with pytest.raises(
        DatasetError,
        match=r"acc.uff: record 1 .*ordinate type 12 "
        r"\(acceleration\).*does not integrate",
    ):
        read_uff(write("acc.uff", [f, acc]))
    with pytest.raises(MissingColumnError, match=r"novel.uff: load case 1 has no velocity record"):
        read_uff(write("novel.uff", [f]))
    short = dict(v, data=rec.velocity[:-5], x=rec.time[:-5])
    with pytest.raises(
        LengthMismatchError,
        match=r"short.uff: load case 1: force has 512 "
        r"samples, velocity 507",
    ):
        read_uff(write("short.uff", [f, short]))
    path = write("ok.uff", [f, v])
    with pytest.raises(
        SamplingRateError,
        match=r"ok.uff: record 0 .*implies 1024 Hz but the "
        r"declared sampling rate is 2048 Hz",
    ):
        read_uff(path, sampling_rate_hz=2048.0)
    # NaN in the file (pyuff's writer turns NaN into 0, so edit the text)
    text = path.read_text().splitlines()
    last_header = max(i for i, line in enumerate(text) if line.strip().startswith("0    0    0    0"))
    first_value = text[last_header + 1]
    text[last_header + 1] = "%20s" % "nan" + first_value[20:]
    (tmp_path / "nan.uff").write_text("\n".join(text) + "\n")
    with pytest.raises(
        NonFiniteError,
        match=r"nan.uff: record 1 \(velocity, load case 1\) has "
        r"NaN or inf \(sample 0\)",
    ):
        read_uff(tmp_path / "nan.uff")
    bad_role = dict(v, id2="signal=sine level=low role=whatever")
    with pytest.raises(UnknownRoleError, match=r"role.uff: load case 1 .*unknown role 'whatever'"):
        read_uff(write("role.uff", [f, bad_role]))
