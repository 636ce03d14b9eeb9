"""The discrepancy workflow's rules for real records, each against something
independent: nested fits that are fits (a candidate with a prior so wide that a
start a tenth of its range from the null is far from anything the data allow),
the held-out gain's noise (Monte Carlo over noise realisations of a record), and
"tests disagree" only where a prediction would show it."""

import numpy as np
import pytest
from test_user_discrepancy import Duffing, make_dataset

from bayes_update import Parameter
from bayes_update.core.checks import test_disagreement as disagreement
from bayes_update.core.effects import DECISIVE
from bayes_update.core.held_out import describe, held_out_comparison


class WideDuffing(Duffing):
    """The Duffing with a candidate quadratic spring allowed a thousand times the force
    any test could show: its fits start +-0.1 of that range from the null."""

    def candidate_effects(self):
        return {
            "k2": [Parameter("k2", -2.0e4, 2.0e4, unit="1e5 N/m^2", null=0.0)],
            "c2": [Parameter("c2", 0.0, 5.0, unit="N s^2/m^2", null=0.0)],
        }

    def simulate(self, theta, force, fs):
        from bayes_update import ModelError

        y = super().simulate(theta, force, fs)
        if not np.all(np.isfinite(y)):  # such a spring throws the oscillator off
            raise ModelError("the response diverges")
        return y


def test_a_far_start_never_gives_a_bayes_factor_below_a_failed_fit():
    from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy

    res = find_discrepancy(
        make_dataset(), WideDuffing(), settings=DiscrepancySettings.quick(), workers=2, log=lambda *a: None
    )
    for rnd in res.rounds:
        for row in rnd["candidates"]:
            # a nested fit ends no worse than the model without it (the null is one of its starts)
            assert row["failed_fit"] or row["delta_log_likelihood"] >= -0.5, row
            # evidence below -6 only with a note: a failed fit, or an effect the data pin at its null
            assert row["failed_fit"] or row["two_ln_B"] >= -DECISIVE or row["at_null"], row
    assert res.named == [], res.named


class _Test:
    def __init__(self, response):
        self.response = response


class _Problem:
    """What held_out_comparison reads: the validation records and their noise."""

    def __init__(self, records, sigma):
        self.validation = {k: _Test(v) for k, v in records.items()}
        self.sigma = sigma

    def test_noise(self, name):
        return np.array([self.sigma])


def test_the_held_out_gain_of_two_equal_models_is_noise_of_the_stated_sd():
    rng = np.random.default_rng(0)
    n, sigma = 3000, 0.2
    truth = np.sin(np.linspace(0, 60, n))
    m0 = truth + 0.05 * np.cos(np.linspace(0, 17, n))  # two models as far from the truth,
    m1 = truth - 0.05 * np.cos(np.linspace(0, 17, n))  # on either side of it
    z = []
    for _ in range(2000):
        y = truth + sigma * rng.standard_normal(n)
        c = held_out_comparison(_Problem({"t": y}, sigma), {"t": m0}, {"t": m1})
        z.append(c["z"])
    z = np.array(z)
    # no model is better: the gain over its stated sd is a standard normal (mean 0, sd 1)
    assert abs(z.mean()) < 0.1 and abs(z.std() - 1.0) < 0.05, (z.mean(), z.std())
    assert np.mean(z > 3.0) < 0.005
    # a model nearer the truth gains beyond the noise
    y = truth + sigma * rng.standard_normal(n)
    better = held_out_comparison(_Problem({"t": y}, sigma), {"t": m0}, {"t": truth + 0.005 * np.cos(np.arange(n))})
    assert better["improves"] and better["tests"]["t"]["after"] < better["tests"]["t"]["before"]
    # a model that moves the prediction toward the truth by far less than the noise: z is large
    # (the residual's projection on a direction), but no record could tell the two apart
    tiny = held_out_comparison(_Problem({"t": y}, sigma), {"t": m0}, {"t": m0 + 1e-6 * (truth - m0)})
    assert tiny["z"] > 3.0 and tiny["sd"] < 1.0 and not tiny["improves"], tiny
    assert "the same prediction within the noise" in describe(tiny)


def test_one_test_predicted_worse_is_not_hidden_by_another_predicted_better():
    """Two held-out tests: the new model is much nearer the truth on one and farther from it
    (by many noise sd) on the other; the summed gain is large, but the held-out tests are not
    predicted better."""
    rng = np.random.default_rng(3)
    n, sigma = 3000, 0.05
    truth = np.sin(np.linspace(0, 60, n))
    off = np.cos(np.linspace(0, 17, n))
    y = {t: truth + sigma * rng.standard_normal(n) for t in ("random", "sweep")}
    before = {"random": truth + 0.3 * off, "sweep": truth + 0.05 * off}
    after = {"random": truth + 0.01 * off, "sweep": truth + 0.08 * off}
    c = held_out_comparison(_Problem(y, sigma), before, after)
    assert c["z"] > 30 and c["tests"]["sweep"]["z"] < -3 and c["tests"]["random"]["z"] > 3, c
    assert not c["improves"], c
    # the same gain on the first test with the second one unchanged is an improvement
    after["sweep"] = before["sweep"]
    assert held_out_comparison(_Problem(y, sigma), before, after)["improves"]


def test_a_model_that_cannot_run_a_held_out_test_does_not_predict_it_better():
    """A softening spring past its barrier on the strongest held-out test: the new model cannot
    run it (its response None) while it predicts the other far better; the held-out tests are not
    predicted better, and the line says which test it cannot run.  The other way round (the new
    model runs where the old one could not) is an improvement."""
    rng = np.random.default_rng(4)
    n, sigma = 2000, 0.05
    truth = np.sin(np.linspace(0, 40, n))
    off = np.cos(np.linspace(0, 11, n))
    y = {t: truth + sigma * rng.standard_normal(n) for t in ("mid", "sweep")}
    before = {"mid": truth + 0.3 * off, "sweep": truth + 0.3 * off}
    after = {"mid": truth + 0.01 * off, "sweep": None}
    c = held_out_comparison(_Problem(y, sigma), before, after)
    assert c["tests"]["mid"]["z"] > 3 and c["worse"] == ["sweep"] and not c["improves"], c
    assert c["tests"]["sweep"]["after"] == np.inf
    assert "sweep 30.7 % -> cannot run (+97.5 sd on the tests both run)" in describe(c), describe(c)
    back = held_out_comparison(_Problem(y, sigma), {"mid": before["mid"], "sweep": None}, before)
    assert back["improves"] and back["worse"] == [] and back["tests"]["sweep"]["z"] == np.inf, back
    # a test neither model runs is left out of the comparison
    neither = held_out_comparison(_Problem(y, sigma), {**before, "sweep": None}, after)
    assert list(neither["tests"]) == ["mid"] and neither["improves"], neither


def test_tests_disagree_only_where_a_prediction_would_show_it():
    """Two tests of n rows each (noise units), one parameter, their own estimates 10 combined sd
    apart: the difference moves a test's output by 10 sqrt(2 / n) noise sd (rms over its rows), so
    a long record's sharp estimate disagrees by many sd where no prediction would show it."""
    rng = np.random.default_rng(1)

    def case(n):
        J = rng.standard_normal((2 * n, 1))
        H = [float(J[:n, 0] @ J[:n, 0]), float(J[n:, 0] @ J[n:, 0])]
        delta = 10.0 * np.sqrt(1.0 / H[0] + 1.0 / H[1])  # 10 combined sd
        r = np.concatenate([J[:n, 0] * delta / 2, -J[n:, 0] * delta / 2])
        return disagreement(J, r, {"low": slice(0, n), "high": slice(n, 2 * n)}, ["k"], np.array([1e3]))

    found = case(20)  # 3.2 noise sd: told
    assert found and found[0]["sd"] == pytest.approx(10.0, rel=1e-6) and found[0]["prediction_change_noise_sd"] > 2
    assert case(20000) == []  # 0.1 noise sd: not worth a warning
