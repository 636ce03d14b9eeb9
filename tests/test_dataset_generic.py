"""Data sets for any model (issue 22): response kinds, several sensors, no rig block;
the data layer imports no fe; the beam reads its rig through beam_rig.rig_of."""

import json
import subprocess
import sys

import numpy as np
import pytest

from bayes_update.data.dataset import (
    Dataset,
    DatasetError,
    MissingColumnError,
    Record,
    SensorError,
    UnknownResponseError,
)
from bayes_update.data.folder import read_dataset, write_dataset

FS = 2000.0
N = 400
TWO = (("tip_acc", "acceleration"), ("mid_disp", "displacement"))


def signals(seed=0, k=1):
    rng = np.random.default_rng(seed)
    t = np.arange(N) / FS
    force = rng.standard_normal(N)
    response = 1e-4 * rng.standard_normal((N, k))
    return t, force, response[:, 0] if k == 1 else response


def write_folder(folder, meta, columns):
    """A hand-written data-set folder: ``columns`` maps file -> {column: values}."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "dataset.json").write_text(json.dumps(meta))
    for name, cols in columns.items():
        header = ",".join(cols)
        rows = np.column_stack(list(cols.values()))
        np.savetxt(folder / name, rows, delimiter=",", header=header, comments="", fmt="%.17g")
    return folder


def displacement_folder(tmp_path):
    t, f, y = signals(0)
    t2, f2, y2 = signals(1)
    meta = {
        "sampling_rate_hz": FS,
        "response": "displacement",
        "tests": [
            {"file": "low.csv", "role": "linear"},
            {"file": "high.csv", "role": "nonlinear", "level": "high", "note": 3},
        ],
    }
    return write_folder(
        tmp_path / "user",
        meta,
        {
            "low.csv": {"time": t, "force": f, "displacement": y},
            "high.csv": {"time": t2, "force": f2, "displacement": y2},
        },
    ), (y, y2)


def two_sensor_dataset(rig=None):
    tests = []
    for i, (name, role) in enumerate((("low.csv", "linear"), ("high.csv", "nonlinear"))):
        t, f, y = signals(i, k=2)
        tests.append(Record(name, "multisine", name[:-4], role, t, f, y, sensors=TWO))
    return Dataset("two", FS, rig, tests, extra={"truth": {"k": 1.0}})


# ------------------------------------------------------------- one sensor, no rig
def test_user_data_set_without_rig_with_displacement(tmp_path):
    folder, (y_low, y_high) = displacement_folder(tmp_path)
    ds = read_dataset(folder)
    assert ds.rig is None
    assert ds.sensors == [("displacement", "displacement")] and ds.response_kind == "displacement"
    assert ds.units == {"time": "s", "force": "N", "displacement": "m"}
    low, high = ds.tests
    assert low.response.shape == (N,)
    np.testing.assert_array_equal(low.response, y_low)
    np.testing.assert_array_equal(high.channel("displacement"), y_high)
    assert (low.signal, low.level) == ("unknown", "unknown")  # optional keys' defaults
    assert high.level == "high" and high.meta == {"note": 3}
    with pytest.raises(
        SensorError,
        match=r"low.csv: Record.velocity is the response of a single "
        r"velocity sensor.*use Record.response",
    ):
        low.velocity
    with pytest.raises(SensorError, match="Record.response"):
        low.velocity = np.zeros(N)

    out = write_dataset(ds, tmp_path / "a")
    meta = json.loads((out / "dataset.json").read_text())
    assert meta["response"] == "displacement" and "rig" not in meta and "sensors" not in meta
    assert list(meta)[:3] == ["name", "sampling_rate_hz", "response"]
    assert (out / "low.csv").read_text().splitlines()[0] == "time,force,displacement"
    back = read_dataset(out)
    assert back.sensors == ds.sensors and back.rig is None
    np.testing.assert_allclose(back.tests[1].response, y_high, rtol=1e-9, atol=0)
    again = write_dataset(back, tmp_path / "b")
    for f in ("dataset.json", "low.csv", "high.csv"):
        assert (again / f).read_bytes() == (out / f).read_bytes()


def test_fingerprint_follows_the_response_and_its_kind(tmp_path):
    folder, _ = displacement_folder(tmp_path)
    ds = read_dataset(folder)
    fp = ds.fingerprint()
    assert read_dataset(folder).fingerprint() == fp
    ds.tests[1].response = ds.tests[1].response.copy()
    ds.tests[1].response[7] *= 1.000001
    assert ds.fingerprint() != fp
    # the same numbers declared as a velocity are another data set
    meta = json.loads((folder / "dataset.json").read_text())
    meta["response"] = "velocity"
    (folder / "dataset.json").write_text(json.dumps(meta))
    for f in ("low.csv", "high.csv"):
        text = (folder / f).read_text().replace("displacement", "velocity", 1)
        (folder / f).write_text(text)
    as_velocity = read_dataset(folder)
    np.testing.assert_array_equal(as_velocity.tests[0].velocity, read_dataset(folder).tests[0].response)
    assert as_velocity.fingerprint() != fp


# ------------------------------------------------------------------ two sensors
def test_two_sensors_round_trip(tmp_path):
    ds = two_sensor_dataset()
    assert ds.sensors == list(TWO)
    assert ds.units == {"time": "s", "force": "N", "tip_acc": "m/s^2", "mid_disp": "m"}
    assert ds.tests[0].response.shape == (N, 2)
    with pytest.raises(SensorError, match=r"2 sensors"):
        ds.response_kind
    with pytest.raises(SensorError, match="Record.velocity"):
        ds.tests[0].velocity
    out = write_dataset(ds, tmp_path / "a")
    meta = json.loads((out / "dataset.json").read_text())
    assert meta["sensors"] == [
        {"name": "tip_acc", "response": "acceleration"},
        {"name": "mid_disp", "response": "displacement"},
    ]
    assert "response" not in meta and "rig" not in meta and meta["truth"] == {"k": 1.0}
    assert (out / "high.csv").read_text().splitlines()[0] == "time,force,tip_acc,mid_disp"
    back = read_dataset(out)
    assert back.sensors == list(TWO)
    for x, y in zip(ds.tests, back.tests):
        assert y.response.shape == (N, 2)
        np.testing.assert_allclose(y.response, x.response, rtol=1e-9, atol=0)
        np.testing.assert_allclose(y.channel("mid_disp"), x.response[:, 1], rtol=1e-9, atol=0)
    assert back.fingerprint() != ds.fingerprint()  # ten significant digits on disk
    assert read_dataset(out).fingerprint() == back.fingerprint()
    again = write_dataset(back, tmp_path / "b")
    for f in ("dataset.json", "low.csv", "high.csv"):
        assert (again / f).read_bytes() == (out / f).read_bytes()


def test_sensor_columns_are_found_by_name_in_any_order(tmp_path):
    t, f, y = signals(0, k=2)
    meta = {
        "sampling_rate_hz": FS,
        "response": "acceleration",
        "sensors": [{"name": "a2"}, {"name": "a1", "response": "acceleration"}],
        "tests": [{"file": "x.csv", "role": "linear"}],
    }
    write_folder(
        tmp_path / "d", meta, {"x.csv": {"a1": y[:, 0], "force": f, "comment": f * 0, "time": t, "a2": y[:, 1]}}
    )
    ds = read_dataset(tmp_path / "d")
    assert ds.sensors == [("a2", "acceleration"), ("a1", "acceleration")]
    np.testing.assert_array_equal(ds.tests[0].response, y[:, ::-1])


# ------------------------------------------------------------------------ errors
def user_meta(**keys):
    return dict({"sampling_rate_hz": FS, "tests": [{"file": "x.csv", "role": "linear"}]}, **keys)


@pytest.mark.parametrize(
    "keys, error, message",
    [
        (
            {"response": "strain"},
            UnknownResponseError,
            r"dataset.json: unknown response kind 'strain' \('response'\); kinds are",
        ),
        (
            {"sensors": [{"name": "a", "response": "jerk"}]},
            UnknownResponseError,
            r"dataset.json: sensor 'a' has unknown response kind 'jerk'",
        ),
        (
            {"sensors": [{"name": "a", "response": "velocity"}, {"name": "a", "response": "displacement"}]},
            SensorError,
            r"dataset.json: duplicate sensor name\(s\) \['a'\]; give each sensor its own name",
        ),
        (
            {"response": "acceleration", "sensors": [{"name": "a"}, {"name": "b", "response": "displacement"}]},
            SensorError,
            r"dataset.json: sensor 'b' has response 'displacement' but the top-level "
            r"'response' is 'acceleration'; drop the top-level 'response'",
        ),
        (
            {"sensors": [{"name": "time", "response": "velocity"}]},
            SensorError,
            r"dataset.json: sensor name 'time' is not usable as a CSV column",
        ),
        ({"sensors": []}, SensorError, r"dataset.json: 'sensors' must be a non-empty list"),
        (
            {"sensors": [{"name": "a", "unit": "mm"}]},
            SensorError,
            r"dataset.json: sensor 'a' has unknown key\(s\) \['unit'\]",
        ),
    ],
)
def test_bad_sensor_declarations(tmp_path, keys, error, message):
    t, f, y = signals()
    write_folder(tmp_path / "d", user_meta(**keys), {"x.csv": {"time": t, "force": f, "a": y}})
    with pytest.raises(error, match=message):
        read_dataset(tmp_path / "d")
    assert issubclass(error, DatasetError) and issubclass(error, ValueError)


def test_csv_lacking_a_sensor_column(tmp_path):
    t, f, y = signals()
    meta = user_meta(sensors=[{"name": "tip", "response": "velocity"}, {"name": "root", "response": "velocity"}])
    write_folder(tmp_path / "d", meta, {"x.csv": {"time": t, "force": f, "tip": y}})
    with pytest.raises(
        MissingColumnError,
        match=r"x.csv: missing column\(s\) \['root'\]; header is "
        r"\['time', 'force', 'tip'\]; .*dataset.json declares "
        r"the sensor\(s\).*name the response column\(s\) after "
        r"the sensors",
    ):
        read_dataset(tmp_path / "d")
    write_folder(tmp_path / "e", user_meta(response="acceleration"), {"x.csv": {"time": t, "force": f, "velocity": y}})
    with pytest.raises(MissingColumnError, match=r"x.csv: missing column\(s\) \['acceleration'\]"):
        read_dataset(tmp_path / "e")


def test_in_memory_checks():
    t, f, y = signals(k=2)
    with pytest.raises(DatasetError, match=r"x.csv: the response must have shape \(n, 2\)"):
        Record("x.csv", "s", "l", "linear", t, f, y[:, 0], sensors=TWO)
    with pytest.raises(SensorError, match=r"x.csv: duplicate sensor name"):
        Record("x.csv", "s", "l", "linear", t, f, y, sensors=(("a", "velocity"), ("a", "velocity")))
    with pytest.raises(UnknownResponseError, match=r"x.csv: sensor 'a' has unknown response kind"):
        Record("x.csv", "s", "l", "linear", t, f, y[:, 0], sensors=(("a", "strain"),))
    one = Record("x.csv", "s", "l", "linear", t, f, y[:, :1])  # (n, 1) is one sensor
    assert one.response.shape == (N,)
    one.velocity = 2 * one.velocity  # the beam's alias writes
    np.testing.assert_array_equal(one.response, 2 * y[:, 0])
    mixed = Dataset(
        "m",
        FS,
        None,
        [
            Record("a.csv", "s", "l", "linear", t, f, y, sensors=TWO),
            Record("b.csv", "s", "l", "nonlinear", t, f, y[:, 0]),
        ],
    )
    with pytest.raises(
        SensorError,
        match=r"test b.csv has sensors .* every test of a data set has "
        r"the same sensors",
    ):
        mixed.validate()
    with pytest.raises(DatasetError, match=r"extra key\(s\) \['response'\]"):
        Dataset("m", FS, None, [one], extra={"response": "velocity"}).validate()


def test_uff_holds_a_single_velocity_only(tmp_path):
    from bayes_update.data.uff import write_uff

    with pytest.raises(SensorError, match=r"two.uff: UFF files hold force and velocity records only"):
        write_uff(two_sensor_dataset(), tmp_path / "two.uff")
    t, f, y = signals()
    beam = Dataset("b", FS, None, [Record("x.csv", "s", "l", "linear", t, f, y)])
    (tmp_path / "d").mkdir()
    write_uff(beam, tmp_path / "d" / "x.uff")
    (tmp_path / "d" / "dataset.json").write_text(
        json.dumps({"sampling_rate_hz": FS, "response": "displacement", "tests": [{"file": "x.uff", "role": "linear"}]})
    )
    with pytest.raises(
        SensorError,
        match=r"x.uff: a UFF test file holds force and velocity records "
        r"only.*write this test as a CSV file",
    ):
        read_dataset(tmp_path / "d")


# ----------------------------------------------------------------- beam and layers
def test_rig_block_is_kept_raw_and_read_by_the_beam_code(tmp_path):
    import fe
    from bayes_update.models.beam.rig import rig_of

    folder, _ = displacement_folder(tmp_path)
    assert rig_of(read_dataset(folder)) == fe.Rig()  # absent block: the paper's rig
    meta = json.loads((folder / "dataset.json").read_text())
    meta["rig"] = {"sensor_position_m": 0.3, "length_m": 0.6}
    (folder / "dataset.json").write_text(json.dumps(meta))
    ds = read_dataset(folder)
    assert ds.rig == {"sensor_position_m": 0.3, "length_m": 0.6}  # as written, key order too
    assert rig_of(ds) == fe.Rig(length_m=0.6, sensor_position_m=0.3)  # factor 1.0 when absent
    out = write_dataset(ds, tmp_path / "w")
    assert json.loads((out / "dataset.json").read_text())["rig"] == {"sensor_position_m": 0.3, "length_m": 0.6}
    rig = fe.Rig(bending_stiffness_factor=1.24)  # the beam builds with an fe.Rig
    built = two_sensor_dataset(rig)
    assert built.rig is rig and rig_of(built) is rig
    assert json.loads((write_dataset(built, tmp_path / "r") / "dataset.json").read_text())["rig"] == rig.to_dict()
    with pytest.raises(DatasetError, match="rig must be None, the rig block"):
        two_sensor_dataset(rig=3.0).validate()


def test_default_data_set_reads_as_before():
    from bayes_update.models.beam.virtual_rig import load_default_dataset

    ds = load_default_dataset()
    assert ds.sensors == [("velocity", "velocity")] and ds.response_kind == "velocity"
    assert ds.tests[0].velocity is ds.tests[0].response
    # the fingerprint caches key on: unchanged by the sensors (issue 22)
    assert ds.fingerprint() == "66dbb1fac3f76708116fc3b70d41170a9562e1570bd3732663e0dba3a75203d1"


@pytest.mark.parametrize("module", ["bayes_update.data.dataset", "bayes_update.data.uff"])
def test_data_layer_imports_no_fe(module):
    code = f"import sys, {module}; print('fe' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", f"importing {module} imports fe"
