"""``find_discrepancy`` on a displacement data set (tests/new_user_chain.py: a two-mass chain whose
ground spring is quadratic in the data): the validation error it reports after the re-update is
the one its own final parameters give when the model is run on the same data.

The displacement-specific path: a record's mean is a sensor offset (removed from the force before
the model sees it and from the response, :class:`bayes_update.core.problem.Problem`), while a
quadratic spring gives the model's displacement a mean of its own (here about 2 % of its RMS).
The comparison must treat the model's output as it treats the record: both without their means."""

import json

import numpy as np
import pytest
from new_user_chain import FS, TRUTH, Chain, make_dataset

HIDDEN = {"kq": 1.5}  # [MN/m^2]: about 10 % of the ground spring's force at the high level


def offset_free_error(model, theta, record) -> float:
    """||y - y_model|| / ||y|| with the record's means removed as sensor offsets (the force's before
    the model runs) and the model output's mean removed alike (docs/models.md)."""
    force = record.force - record.force.mean()
    y = record.response - record.response.mean()
    y_model = model.simulate(theta, force, FS)
    return float(np.linalg.norm(y - (y_model - y_model.mean())) / np.linalg.norm(y))


@pytest.fixture(scope="module")
def found(tmp_path_factory):
    from bayes_update import DiscrepancySettings, find_discrepancy, write_discrepancy

    data = make_dataset(HIDDEN)
    res = find_discrepancy(
        data, Chain(), settings=DiscrepancySettings.quick(n_start=8, n_replicates=4), workers=1, log=lambda *a: None
    )
    out = tmp_path_factory.mktemp("discrepancy")
    write_discrepancy(res, out)
    return data, res, json.loads((out / "discrepancy.json").read_text()), out


def test_the_reported_validation_error_is_the_final_parameters_error(found):
    data, res, doc, _ = found
    final = doc["final_mode"]
    theta = {n: v["mode"] for n, v in final["parameters"].items()}
    for values in final["effects"].values():
        theta.update({n: v["mode"] for n, v in values.items()})
    assert set(theta) >= set(TRUTH)
    model = Chain()
    for record in data.by_role("validation"):
        y_model = model.simulate(theta, record.force - record.force.mean(), FS)
        # the path is exercised: the final model's displacement has a mean of its own
        assert abs(y_model.mean()) > 0.005 * np.std(y_model), (theta, y_model.mean())
        reported = doc["gap_after"]["held_out_tests"][record.name]["relative_error"]
        assert reported == pytest.approx(offset_free_error(model, theta, record), abs=1e-6), (theta, reported)


def test_sensor_offsets_on_a_displacement_record_change_no_prediction_error():
    """Offsets of 0.3 (force) and 0.5 (displacement) x each channel's RMS on every test: the
    prediction error at the truth is the offset-free one, and that of the data without offsets."""
    from bayes_update import Problem

    theta = {**TRUTH, **HIDDEN}
    clean = Problem(make_dataset(HIDDEN), Chain())
    shifted_data = make_dataset(HIDDEN, offsets=(0.3, 0.5))
    shifted = Problem(shifted_data, Chain())
    e_clean, e_shifted = clean.prediction_errors(theta)["noise_mid"], shifted.prediction_errors(theta)["noise_mid"]
    record = shifted_data.test("noise_mid")
    assert e_shifted == pytest.approx(offset_free_error(Chain(), theta, record), abs=1e-9)
    assert e_shifted == pytest.approx(e_clean, rel=0.02) and e_clean < 0.015, (e_clean, e_shifted)


def test_the_gap_figure_is_labelled_and_titled_with_the_reported_errors(found):
    from bayes_update.reports.discrepancy import gap_figure

    _, res, doc, out = found
    fig = gap_figure(res)
    for ax in fig.axes:
        assert ax.get_ylabel() == "displacement amplitude [m]" and ax.get_xlabel() == "frequency [Hz]"
    title = next(ax.get_title() for ax in fig.axes if ax.get_title().startswith("noise_mid"))
    after = doc["gap_after"]["held_out_tests"]["noise_mid"]["relative_error"]
    assert f"{100 * after:.2f} %" in title, (title, after)
    assert (out / "gap_before_after.png").stat().st_size > 20_000
