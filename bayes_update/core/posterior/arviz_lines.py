"""ArviZ's two lines behind the few calls the project makes.

ArviZ 0.x keeps a posterior in an ``InferenceData``; ArviZ 1.x (the ``arviz``
1.x namespace re-exports ``arviz_base`` and ``arviz_stats``) in an xarray
``DataTree``, with other signatures: ``from_dict`` takes ``{group: {var:
array}}``, ``summary`` reports an equal-tailed interval unless asked for the
HDI, the tail ESS takes its quantiles.  Every ArviZ call of the package goes
through this module, so that one of each call exists and both lines are tested
(the 1.x line through ``arviz_base`` and ``arviz_stats``, which the dev extra
installs beside ArviZ 0.x).

Both lines write the same netCDF groups (``posterior``, ``sample_stats``,
``log_likelihood``, ``observed_data``, ``posterior_predictive``): a file written
under one opens under the other (``az.from_netcdf`` on 0.x,
``xarray.open_datatree`` on 1.x).
"""

from __future__ import annotations

import warnings
from contextlib import contextmanager

import numpy as np


def _installed_line() -> int:
    """0 for ArviZ 0.x, 1 for 1.x (or ``arviz_base`` without ``arviz``), read
    from the installed metadata (importing ArviZ takes a second)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return 0 if int(version("arviz").split(".")[0]) < 1 else 1
    except PackageNotFoundError:
        return 1


#: the ArviZ line the package talks to (tests set it to run both)
LINE = _installed_line()

#: the quantiles of the tail ESS, ArviZ 0.x's (1.x asks for them)
TAIL_QUANTILES = (0.05, 0.95)


def _stats():
    if LINE == 0:
        import arviz

        return arviz
    import arviz_stats

    return arviz_stats


@contextmanager
def _many_chains():
    """ArviZ 0.x warns when the chains outnumber the draws: the package's kept draws are many
    walkers (each a chain) of a few thinned draws each, on purpose (:mod:`.mcmc`)."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="More chains", category=UserWarning)
        yield


def from_dict(groups: dict, dims: dict, coords: dict, attrs: dict):
    """A posterior's InferenceData (0.x) or DataTree (1.x).

    ``groups``: {group name: {variable: array (chain, draw, ...)}} (observed
    data without the two sample dimensions); ``dims``: {variable: [dimension
    names after chain and draw]}; ``coords``: {dimension: labels}; ``attrs``:
    the root's attributes (the run's record)."""
    if LINE == 0:
        import arviz as az

        with _many_chains():
            return az.from_dict(**groups, dims=dims, coords=coords, attrs=dict(attrs))
    import arviz_base

    tree = arviz_base.from_dict(groups, dims=dims, coords=coords)
    tree.attrs.update(attrs)
    return tree


def add_group(idata, name: str, variables: dict, dims: dict) -> None:
    """Add the group ``name`` ({variable: (chain, draw, ...)}) to a posterior."""
    if LINE == 0:
        import arviz as az

        idata.add_groups({name: getattr(az.from_dict(**{name: variables}, dims=dims), name)})
        return
    import arviz_base

    idata[name] = arviz_base.from_dict({name: variables}, dims=dims)[name]


def rhat(values) -> float:
    """Rank-normalised split R-hat of a (chain, draw) array."""
    with _many_chains():
        return float(_stats().rhat(np.asarray(values, float), method="rank"))


def ess(values, method: str) -> float:
    """Bulk or tail effective sample size of a (chain, draw) array."""
    values = np.asarray(values, float)
    with _many_chains():
        if method == "tail" and LINE == 1:
            return float(_stats().ess(values, method="tail", prob=TAIL_QUANTILES))
        return float(_stats().ess(values, method=method))


def hdi(values, prob: float) -> tuple[float, float]:
    """Highest-density interval of a sample (one dimension)."""
    values = np.asarray(values, float).ravel()
    if LINE == 0:
        lo, hi = _stats().hdi(values, hdi_prob=prob)
    else:
        lo, hi = _stats().hdi(values, prob=prob)
    return float(lo), float(hi)


def summary(idata, prob: float):
    """ArviZ's summary table (pandas), one row per posterior variable, with the
    columns ``mean``, ``sd``, ``hdi_lo``, ``hdi_hi`` (the ``prob`` highest-density
    interval), ``r_hat``, ``ess_bulk`` and ``ess_tail`` on both lines; ``sd`` with
    n - 1 in the denominator as 0.x has it (1.x divides by n)."""
    if LINE == 0:
        import arviz as az

        with _many_chains():
            s = az.summary(idata, hdi_prob=prob, round_to="none")
        lo, hi = f"hdi_{100 * (1 - prob) / 2:g}%", f"hdi_{100 * (1 + prob) / 2:g}%"
    else:
        s = _stats().summary(idata, ci_kind="hdi", ci_prob=prob, round_to="none")
        post = idata["posterior"]
        n = post.sizes["chain"] * post.sizes["draw"]
        s["sd"] = s["sd"] * np.sqrt(n / (n - 1))
        # arviz_stats 0.8's summary draws its interval otherwise than its own hdi
        # (1.6 % of an sd apart on AR(1) chains): the pooled draws' hdi, as 0.x has it
        bounds = np.array([hdi(post[v].values, prob) for v in s.index])
        lo, hi = f"hdi{100 * prob:g}_lb", f"hdi{100 * prob:g}_ub"
        s[lo], s[hi] = bounds[:, 0], bounds[:, 1]
        # and its tail ESS at the interval's quantiles, not 0.x's 5 % and 95 %
        s["ess_tail"] = [ess(post[v].values, "tail") for v in s.index]
    return s.rename(columns={lo: "hdi_lo", hi: "hdi_hi"})


def open_posterior(path):
    """A ``posterior.nc`` (written under either line) opened under the installed one."""
    if LINE == 0:
        import arviz as az

        return az.from_netcdf(str(path))
    import xarray as xr

    return xr.open_datatree(str(path))


__all__ = ["LINE", "add_group", "ess", "from_dict", "hdi", "open_posterior", "rhat", "summary"]
