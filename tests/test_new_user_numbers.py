"""Numbers printed with the digits their sd needs: never an HDI of "25 - 25"."""

import math
from types import SimpleNamespace

import pytest

from bayes_update.core.numbers import format_sd, format_value


@pytest.mark.parametrize(
    "value, sd, text",
    [
        (25.0312, 0.0043, "25.0312"),
        (-25.0312, 0.0043, "-25.0312"),
        (1234.5, 210.0, "1230"),
        (-1234.5, 210.0, "-1230"),
        (-0.3, 210.0, "0"),  # no "-0"
        (99.96, 0.3, "99.96"),
        (-0.00123, 4e-5, "-0.001230"),
        (1.2345e7, 3e4, "1.2345e+07"),
        (3.2e-6, 4.1e-8, "3.200e-06"),
        (25.0312, 0.0, "25.0312"),  # sd 0: six significant digits
        (25.0312, math.nan, "25.0312"),
        (0.0, 0.0012, "0.0000"),
    ],
)
def test_a_value_gets_the_digits_of_its_sd(value, sd, text):
    assert format_value(value, sd) == text


@pytest.mark.parametrize(
    "sd, text", [(0.0043, "0.0043"), (210.0, "210"), (0.000965, "0.00097"), (4e-5, "4.0e-05"), (0.0, "0")]
)
def test_the_sd_gets_two_significant_digits(sd, text):
    assert format_sd(sd) == text


def test_the_posterior_table_resolves_a_narrow_hdi():
    from bayes_update.core.posterior import PosteriorResult

    summary = {
        "fn": {
            "mean": 25.000121,
            "sd": 0.000097,
            "hdi_3%": 24.999943,
            "hdi_97%": 25.000301,
            "r_hat": 1.0012,
            "ess_bulk": 812.0,
            "ess_tail": 701.0,
            "units": "Hz",
        },
        "k": {
            "mean": 1234.5,
            "sd": 210.0,
            "hdi_3%": 851.2,
            "hdi_97%": 1622.9,
            "r_hat": 1.003,
            "ess_bulk": 640.0,
            "units": "N/mm",
        },
    }
    # "k" has no tail ESS, as in a posterior.json written before it was kept
    table = PosteriorResult.summary_table(SimpleNamespace(summary=summary, diagnostics={}))
    rows = {
        ln.split("|")[1].strip(): [c.strip() for c in ln.split("|")[2:-1]]
        for ln in table.splitlines()[2:]
        if ln.startswith("|")
    }
    assert rows["fn [Hz]"][:3] == ["25.000121", "9.7e-05", "24.999943 - 25.000301"], rows
    assert rows["k [N/mm]"][:3] == ["1230", "210", "850 - 1620"], rows
    assert rows["fn [Hz]"][4:] == ["812", "701"] and rows["k [N/mm]"][5] == "-", rows
    assert table.splitlines()[-1].startswith("converged")


def test_the_calibration_report_prints_the_digits_of_each_value():
    from bayes_update.core.calibrate import Calibration
    from bayes_update.reports.calibration import format_calibration

    cal = Calibration(
        theta={"fn": 25.000121, "k": 1234.5},
        stage1={"fn": 25.00113, "k": 1000.0},
        linear_parameters=["fn", "k"],
        sensitivity={},
        metrics={"e_lin": 0.01, "e_nlin": 0.02},
        metric_set="full",
        prediction_errors={},
        unidentified={},
        noise_sd={},
        fit_warnings=[],
        disagreement=[],
        output_errors={},
        n_functions=(4, 2, 6),
        n_model_runs=1,
        units={"fn": "Hz", "k": "N/mm"},
        problem=None,
        sd={"fn": 0.000097, "k": 210.0},
    )
    rows = {ln.split()[0]: ln.split()[1:] for ln in format_calibration(cal).splitlines()[3:5]}
    assert rows["fn"] == ["25.001130", "25.000121", "9.7e-05", "Hz"], rows
    assert rows["k"] == ["1000", "1230", "210", "N/mm"], rows


def test_calibrate_measures_the_sd_it_prints():
    """The calibration's sd is the posterior's Laplace sd at the calibrated point (the noise
    replicates with the force's noise and the model error: never below the fit's white-noise
    Gauss-Newton sd, which ``uncertainty=False`` gives, footnoted as not an interval), and the
    value's digits follow it."""
    from new_user_kit import Spring, make_dataset

    from bayes_update import calibrate
    from bayes_update.reports.calibration import format_calibration

    data = make_dataset()
    cal = calibrate(data, Spring(), workers=1, n_start=8, progress=False)
    fit_only = calibrate(data, Spring(), workers=1, n_start=8, progress=False, uncertainty=False)
    assert (cal.sd_method, fit_only.sd_method) == ("laplace", "gauss-newton")
    assert cal.theta == fit_only.theta and cal.n_model_runs > fit_only.n_model_runs
    assert set(cal.sd) == {"fn", "zeta", "k"} and all(cal.sd[n] >= fit_only.sd[n] > 0 for n in cal.sd), (
        cal.sd,
        fit_only.sd,
    )
    assert cal.calibration_json()["sd"] == cal.sd and cal.calibration_json()["sd_method"] == "laplace"
    line = next(ln for ln in format_calibration(cal).splitlines() if ln.split()[0] == "k")
    assert line.split()[2] == format_value(cal.theta["k"], cal.sd["k"])
    assert "GN sd*" in format_calibration(fit_only) and "not an interval" in format_calibration(fit_only)
