"""The posterior written and read on both ArviZ lines (0.x InferenceData, 1.x DataTree).

The 1.x line is reached through ``arviz_base`` and ``arviz_stats`` (what the
``arviz`` 1.x namespace re-exports; the dev extra installs them beside ArviZ
0.x).  Each line is checked against the other (two code bases: arviz_stats is a
rewrite) and against numpy, on AR(1) chains whose mean and sd are known:

* the summary's mean and sd equal numpy's; its HDI, R-hat and ESS agree across
  the lines to 1e-9 (the same estimators, written twice);
* a file written on either line opens on the other, where ``summary`` and
  ``loo`` run and give the same elpd (to 1e-6);
* the units, the root's record and the posterior predictive group survive.
"""

from __future__ import annotations

import arviz_stats  # the dev extra installs it: a missing one fails here, as the project's rule says
import numpy as np
import pytest

from bayes_update import Parameter
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior import arviz_lines, mcmc

SPACE = ParameterSet([Parameter("k", 1.0, 3.0, unit="N/m"), Parameter("c", 0.01, 1.0, unit="N s/m", log=True)])


def _chains(seed=3, steps=600, walkers=6):
    """(steps, walkers, 2) internal coordinates: AR(1) chains (rho 0.6) around (2, log 0.1)."""
    rng = np.random.default_rng(seed)
    x = np.zeros((steps, walkers, 2))
    for t in range(1, steps):
        x[t] = 0.6 * x[t - 1] + 0.8 * rng.standard_normal((walkers, 2))
    return x * [0.1, 0.2] + [2.0, np.log(0.1)], rng.standard_normal((steps, walkers))


def _posterior(line, monkeypatch):
    monkeypatch.setattr(arviz_lines, "LINE", line)
    chain, lp = _chains()
    rng = np.random.default_rng(5)
    log_lik = {"low": -0.5 - 0.1 * rng.random((600, 6, 4)), "high": -0.7 - 0.1 * rng.random((600, 6, 3))}
    observed = {"low": (rng.standard_normal(4), "m/s^2"), "high": (rng.standard_normal((3, 2)), "m/s^2")}
    idata = mcmc.to_inference_data(chain, lp, SPACE, {"seed": 3}, log_lik, observed)
    mcmc.add_posterior_predictive(idata, {"high": rng.standard_normal((5, 3, 2))}, {"high": "m/s^2"})
    return idata, chain


@pytest.mark.parametrize("line", [0, 1])
def test_summary_equals_numpy_on_each_line(line, monkeypatch):
    idata, chain = _posterior(line, monkeypatch)
    summary = mcmc.summarize(idata, SPACE)
    k = chain[..., 0]
    assert summary["k"]["mean"] == pytest.approx(k.mean(), rel=1e-12)
    assert summary["k"]["sd"] == pytest.approx(k.std(ddof=1), rel=1e-12)
    assert summary["c"]["mean"] == pytest.approx(np.exp(chain[..., 1]).mean(), rel=1e-12)
    assert summary["k"]["units"] == "N/m" and idata["posterior"]["c"].attrs["units"] == "N s/m"
    assert idata["observed_data"]["high"].attrs["units"] == "m/s^2"
    assert idata["posterior_predictive"]["high"].shape == (1, 5, 3, 2)


def test_both_lines_give_the_same_diagnostics(monkeypatch):
    by_line = {line: mcmc.summarize(_posterior(line, monkeypatch)[0], SPACE) for line in (0, 1)}
    for name in ("k", "c"):
        for key in ("hdi_3%", "hdi_97%", "r_hat", "ess_bulk", "ess_tail"):
            assert by_line[1][name][key] == pytest.approx(by_line[0][name][key], rel=1e-9), (name, key)
    walkers = np.swapaxes(_chains()[0][..., 0], 0, 1)
    conv = {}
    for line in (0, 1):
        monkeypatch.setattr(arviz_lines, "LINE", line)
        conv[line] = mcmc.chain_convergence({"k": walkers})["per_variable"]["k"]
    assert conv[1] == pytest.approx(conv[0], rel=1e-9)
    # an AR(1) chain of rho 0.6 holds (1 - rho) / (1 + rho) = 1/4 of its draws' information
    assert 0.18 < conv[0]["ess_bulk"] / walkers.size < 0.33


@pytest.mark.parametrize("written, read", [(0, 1), (1, 0)])
def test_a_file_written_on_one_line_opens_on_the_other(written, read, monkeypatch, tmp_path):
    import arviz as az

    idata, _ = _posterior(written, monkeypatch)
    mean = mcmc.summarize(idata, SPACE)["k"]["mean"]
    path = tmp_path / "posterior.nc"
    idata.to_netcdf(str(path))
    monkeypatch.setattr(arviz_lines, "LINE", read)
    opened = arviz_lines.open_posterior(path)
    assert {"posterior", "sample_stats", "log_likelihood", "observed_data", "posterior_predictive"} <= set(
        opened.groups() if read == 0 else opened.children
    )
    assert opened.attrs["seed"] == 3 and opened["posterior"]["k"].attrs["units"] == "N/m"
    assert mcmc.summarize(opened, SPACE)["k"]["mean"] == pytest.approx(mean, rel=1e-12)
    elpd = float(az.loo(opened).elpd_loo) if read == 0 else float(arviz_stats.loo(opened).elpd)
    assert elpd == pytest.approx(float(az.loo(az.from_netcdf(str(path))).elpd_loo), rel=1e-6)


@pytest.mark.parametrize("line", [0, 1])
def test_the_figures_read_either_line(line, monkeypatch):
    from types import SimpleNamespace

    from bayes_update.reports.posterior_plots import corner, traces

    idata, chain = _posterior(line, monkeypatch)
    res = SimpleNamespace(idata=idata, space=SPACE)
    fig = corner(res, truth={"k": 2.0, "c": 0.1})
    assert len(fig.axes) == 4 and fig.axes[2].get_xlabel() == "k [N/m]"
    assert len(traces(res).axes[0].lines) == chain.shape[1]


def test_hdi_is_the_same_on_both_lines(monkeypatch):
    x = np.random.default_rng(0).gamma(2.0, size=5000)
    by_line = {}
    for line in (0, 1):
        monkeypatch.setattr(arviz_lines, "LINE", line)
        by_line[line] = arviz_lines.hdi(x, 0.9)
    assert by_line[1] == pytest.approx(by_line[0], rel=1e-12)
    lo, hi = by_line[0]
    assert np.mean((x >= lo) & (x <= hi)) == pytest.approx(0.9, abs=1e-3)
