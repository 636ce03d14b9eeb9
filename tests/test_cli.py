"""The command line: help, simulate on the default chirp and on a data-set folder."""

import json

import numpy as np
import pytest

from bayes_update.cli import main
from bayes_update.data.dataset import Dataset, DatasetError, Record
from bayes_update.data.folder import read_dataset, write_dataset
from fe import Rig


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "simulate" in capsys.readouterr().out


def small_dataset(tmp_path):
    fs = 1024.0
    t = np.arange(512) / fs
    force = 0.001 * np.sin(2 * np.pi * 30 * t)
    tests = [
        Record("sine_low.csv", "sine", "low", "validation", t, force, np.zeros_like(t)),
        Record("sine_high.csv", "sine", "high", "validation", t, 5 * force, np.zeros_like(t)),
    ]
    ds = Dataset("tiny", fs, Rig(), tests, extra={"truth": {"F": 77.0}})
    return write_dataset(ds, tmp_path / "data")


def test_simulate_writes_a_dataset_of_the_same_form(tmp_path):
    data = small_dataset(tmp_path)
    out = tmp_path / "out"
    assert main(["simulate", "--data", str(data), "--out", str(out), "--elements", "6"]) == 0
    result = read_dataset(out)
    source = read_dataset(data)
    assert [t.file for t in result.tests] == [t.file for t in source.tests]
    for a, b in zip(result.tests, source.tests):
        np.testing.assert_allclose(a.time, b.time)
        np.testing.assert_allclose(a.force, b.force, rtol=1e-9)
        assert np.abs(a.velocity).max() > 0
    # linear regime: five times the force gives five times the response
    v_low, v_high = result.tests[0].velocity, result.tests[1].velocity
    assert np.linalg.norm(v_high - 5 * v_low) < 0.02 * np.linalg.norm(v_high)
    assert result.extra["truth"] == {"F": 77.0}  # extra keys preserved
    assert (out / "sine_low.png").is_file()


def test_simulate_default_chirp(tmp_path):
    out = tmp_path / "out"
    assert main(["simulate", "--out", str(out)]) == 0
    summary = json.loads((out / "simulate.json").read_text())
    assert summary["P_eff_N"] == pytest.approx(74.06, abs=0.01)
    assert summary["f1_hz"] == pytest.approx(29.80, abs=0.02)


def test_simulate_reports_bad_input(tmp_path, capsys):
    assert main(["simulate", "--out", str(tmp_path / "o"), "--F", "-3"]) == 2
    assert "F must be non-negative" in capsys.readouterr().err
    assert main(["simulate", "--out", str(tmp_path / "o"), "--F", "200", "--k-s", "0"]) == 2
    assert "buckling" in capsys.readouterr().err
    assert main(["simulate", "--data", str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "not a folder" in capsys.readouterr().err
    # a value in another unit (eta in Pa s, the option in MPa s) is named, not simulated
    assert main(["simulate", "--out", str(tmp_path / "o"), "--eta", "3e6"]) == 2
    assert "MPa s" in capsys.readouterr().err and not (tmp_path / "o").exists()


def test_reader_rejects_non_uniform_time(tmp_path):
    data = small_dataset(tmp_path)
    csv = data / "sine_low.csv"
    lines = csv.read_text().splitlines()
    lines[5] = lines[5].replace(lines[5].split(",")[0], "1.0e+00", 1)
    csv.write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match="sine_low.csv"):
        read_dataset(data)
