"""What ``sample`` and ``calibrate`` draw and write for a displacement data set of a user model:
the truth block only in the model's units (corner.png), every response labelled with the data
set's sensor and unit (predictive.png, calibration_fit.png, the likelihood's noise levels), the
spectra's axes labelled and limited to where the data are, the model's band visible under the data."""

import json

import numpy as np
import pytest
from new_user_kit import TRUTH, make_dataset

FAST = """[sample]
n_replicates = 4
n_global = 0
direct_steps = 120
direct_burn = 40
n_predictive = 6
n_start = 8
"""

SI_TRUTH = {"fn": 23.7, "zeta": 0.031, "k": 4600.0, "units": {"fn": "Hz", "zeta": "", "k": "N/m"}}


@pytest.fixture(scope="module")
def sampled(tmp_path_factory):
    """``bayes-update sample --direct`` (tiny settings) on a displacement data set whose truth block
    states k in N/m while the model's k is in kN/m; the truth and the figures handed to the writer."""
    import bayes_update.reports.posterior_plots as plots
    from bayes_update.cli import main
    from bayes_update.data.folder import write_dataset

    tmp = tmp_path_factory.mktemp("sampled")
    write_dataset(make_dataset(extra={"truth": SI_TRUTH}), tmp / "data")
    (tmp / "fast.toml").write_text(FAST)
    seen = {}
    real = plots.posterior_figures

    def spy(res, truth=None):
        seen["truth"], seen["figures"], seen["res"] = truth, real(res, truth), res
        return seen["figures"]

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(plots, "posterior_figures", spy)
        rc = main(
            [
                "sample",
                "--quick",
                "--direct",
                "--workers",
                "1",
                "--walkers",
                "8",
                "--config",
                str(tmp / "fast.toml"),
                "--model",
                "new_user_kit:Spring",
                "--data",
                str(tmp / "data"),
                "--out",
                str(tmp / "out"),
            ]
        )
    assert rc == 0
    return tmp / "out", seen


# ------------------------------------------------------------------------------------ the truth block
def test_the_truth_block_is_read_only_in_the_models_units():
    from bayes_update.reports.posterior import truth_in_model_units

    units = {"fn": "Hz", "zeta": "", "k": "kN/m"}
    lines = []
    assert truth_in_model_units(SI_TRUTH, units, log=lines.append) == {"fn": 23.7, "zeta": 0.031}
    assert len(lines) == 1 and "k (in 'N/m', the model's unit is 'kN/m')" in lines[0], lines
    lines.clear()
    both = {"k": {"value": 4.6, "unit": "kN/m"}, "fn": {"value": 23.7, "unit": "Hz"}, "seed": 3}
    assert truth_in_model_units(both, units, log=lines.append) == {"k": 4.6, "fn": 23.7} and not lines
    # without stated units: nothing is drawn, and one line says why
    assert truth_in_model_units({"fn": 23.7, "k": 4.6}, units, log=lines.append) is None
    assert len(lines) == 1 and "no unit stated" in lines[0] and "fn" in lines[0] and "k" in lines[0], lines
    assert truth_in_model_units(None, units) is None


def test_corner_draws_only_the_truth_stated_in_the_models_units(sampled):
    out, seen = sampled
    assert seen["truth"] == {"fn": TRUTH["fn"], "zeta": TRUTH["zeta"]}, seen["truth"]
    assert (out / "corner.png").stat().st_size > 10_000


# ------------------------------------------------------------------------------ labels and units
def test_predictive_is_labelled_with_the_sensor_and_drawn_with_the_band_visible(sampled):
    out, seen = sampled
    fig = seen["figures"]["predictive"]
    left = [ax for ax in fig.axes if ax.get_title() and "model - data" not in ax.get_title()]
    right = [ax for ax in fig.axes if "model - data" in ax.get_title()]
    assert len(left) == len(right) == 2
    for ax in left:
        assert ax.get_ylabel() == "displacement [m]", ax.get_ylabel()
        data = [ln for ln in ax.get_lines() if ln.get_label().startswith("data")]
        model = [ln for ln in ax.get_lines() if ln.get_label().startswith("model")]
        band = [c for c in ax.collections if c.get_label().startswith("model")]
        assert len(data) == 1 and model and band
        # the data a thin dark line on top; the model wider, in another colour, under it
        assert data[0].get_zorder() > max(m.get_zorder() for m in model + band)
        assert data[0].get_linewidth() < min(m.get_linewidth() for m in model)
        assert data[0].get_color() != model[0].get_color() and band[0].get_alpha() < 1
        assert ax.get_legend() is not None
    for ax in right:
        assert "m/s" not in ax.get_title() and ax.get_title().endswith(" m)"), ax.get_title()
    # under the full metric set the nonlinear test's compared output is y1 + y2 + y3
    assert any(ax.get_title().startswith("y1 + y2 + y3, loud_high") for ax in left), [a.get_title() for a in left]
    assert (out / "predictive.png").stat().st_size > 20_000


def test_the_likelihoods_noise_levels_name_the_sensor_and_its_unit(sampled):
    out, _ = sampled
    lik = json.loads((out / "posterior_summary.json").read_text())["likelihood"]
    for stage in ("linear", "nonlinear"):
        levels = lik[stage]["noise_levels"]
        # the record's channels under their own names, each with its unit and how its noise was found
        assert set(levels) == {"force", "displacement"}, levels
        assert levels["force"]["unit"] == "N" and levels["displacement"]["unit"] == "m", levels
        assert levels["displacement"]["sd"] > 0 and levels["displacement"]["method"], levels


def test_each_sensor_has_a_key_with_its_name_and_unit():
    from types import SimpleNamespace

    from new_user_kit import AccelerationSpring

    from bayes_update import Problem

    data = make_dataset(kind="acceleration", sensor_name="tip_acc", seed=12)
    assert Problem(data, AccelerationSpring()).sensor_keys == ("tip_acc_m_s2",)
    several = SimpleNamespace(sensors=(("tip_acc", "acceleration"), ("mid", "displacement"), ("velocity", "velocity")))
    assert Problem.sensor_keys.fget(several) == ("tip_acc_m_s2", "mid_m", "velocity_m_s")


@pytest.fixture(scope="module")
def calibrated():
    from bayes_update import calibrate

    return calibrate(make_dataset(), __import__("new_user_kit").Spring(), workers=1, n_start=8, progress=False)


def test_calibration_fit_labels_both_axes_and_limits_the_spectra(calibrated, tmp_path):
    from bayes_update.reports.calibration import fit_figure, write_calibration

    fig = fit_figure(calibrated)
    time_axes, spectrum_axes = fig.axes[0::2], fig.axes[1::2]
    assert len(time_axes) == 3
    for ax in time_axes:
        assert ax.get_xlabel() == "time [s]" and ax.get_ylabel() == "displacement [m]", ax.get_ylabel()
    for ax, t in zip(spectrum_axes, ["quiet_low", "loud_high", "medium_check"]):
        assert ax.get_xlabel() == "frequency [Hz]" and ax.get_ylabel() == "amplitude [m]", ax.get_ylabel()
        measured = next(ln for ln in ax.get_lines() if ln.get_label() == "measured").get_ydata()
        low, high = ax.get_ylim()
        assert low == pytest.approx(1e-4 * np.percentile(measured, 99), rel=1e-6), (t, low)
        assert high >= measured.max()
    write_calibration(calibrated, tmp_path)
    assert (tmp_path / "calibration_fit.png").stat().st_size > 20_000


def test_predictive_draws_a_row_per_sensor_of_a_several_sensor_data_set():
    from bayes_update.reports.posterior_plots import predictive_bands

    n = 300
    t = np.arange(2 * n) / 100.0
    ref = np.sin(7 * t)
    band = {"reference": ref, "low": ref - 0.1, "high": ref + 0.1, "median": ref + 0.01}
    fig = predictive_bands(
        {"linear": band, "nonlinear": band},
        100.0,
        {"linear": "a", "nonlinear": "b"},
        sensors=[("tip", "acceleration"), ("mid", "displacement")],
        unit="noise sd",
        metrics="paper",
    )
    left = [ax for ax in fig.axes if "model - data" not in ax.get_title()]
    assert [ax.get_ylabel() for ax in left] == ["tip (acceleration) [noise sd]", "mid (displacement) [noise sd]"] * 2
    assert [ax.get_title() for ax in left] == ["y1, a, tip", "y1, a, mid", "y2 + y3, b, tip", "y2 + y3, b, mid"]
    assert all(len(ax.get_lines()[0].get_xdata()) == n for ax in left)
