"""A test whose force has no energy (zero, or constant, over the whole record) is refused where
the framework builds its problem, with a DatasetError naming the file and the test; a record
with quiet sections is not."""

import numpy as np
import pytest
from new_user_kit import N_SAMPLES, Spring, band_noise, make_dataset

from bayes_update import DatasetError, Problem


@pytest.mark.parametrize(
    "test, force, what",
    [
        ("quiet_low", np.zeros(N_SAMPLES), "zero"),
        ("medium_check", np.zeros(N_SAMPLES), "zero"),
        ("loud_high", np.full(N_SAMPLES, 2.75), "constant"),
    ],
)
def test_a_force_without_energy_is_refused_naming_file_and_test(test, force, what):
    data = make_dataset(forces={test: force})
    with pytest.raises(DatasetError) as info:
        Problem(data, Spring())
    text = str(info.value)
    assert f"{test}.csv" in text and f"test {test!r}" in text and what in text, text


def test_the_command_line_refuses_a_dead_validation_force_in_one_line(tmp_path, capsys):
    from bayes_update.cli import main
    from bayes_update.data.folder import write_dataset

    write_dataset(make_dataset(forces={"medium_check": np.zeros(N_SAMPLES)}), tmp_path / "data")
    rc = main(
        [
            "calibrate",
            "--quick",
            "--workers",
            "1",
            "--model",
            "new_user_kit:Spring",
            "--data",
            str(tmp_path / "data"),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2, err
    line = [ln for ln in err.splitlines() if "error:" in ln]
    assert len(line) == 1 and str(tmp_path / "data" / "medium_check.csv") in line[0] and "zero" in line[0], err


def test_quiet_sections_are_fine():
    f = band_noise(N_SAMPLES, 0.4, 3)
    f[: N_SAMPLES // 3] = 0.0  # the shaker switched on late
    g = band_noise(N_SAMPLES, 1.3, 4)
    g[N_SAMPLES // 2 :] = 0.0  # and off early: a free decay
    problem = Problem(make_dataset(forces={"quiet_low": f, "medium_check": g}), Spring())
    assert set(problem.validation) == {"medium_check"}
