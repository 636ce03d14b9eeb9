"""emcee runs (seeded), walker placement, ArviZ data and the summary table."""

from __future__ import annotations

import numpy as np

from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior.arviz_lines import add_group, ess, from_dict, rhat, summary
from bayes_update.core.posterior.target import Whitening


# -------------------------------------------------------------------- emcee
def run_emcee(
    log_prob,
    x_init,
    n_walkers: int,
    n_steps: int,
    seed,
    *,
    vectorize: bool,
    pool=None,
    progress: bool = True,
    desc: str = "MCMC (emcee)",
):
    """emcee's stretch move from ``x_init`` (n_walkers, d), seeded.

    A vectorised log probability (the GP surrogates) runs in
    :func:`~bayes_update.core.posterior.stretch.stretch_sample`, emcee's own
    sampler and move over arrays (the same chain for a seed, twice as fast), with
    one BLAS thread: its matrices are a few hundred wide at most, where threads
    cost more than they bring (on a loaded 2-core machine a 72-point GP's
    triangular solve for 16 walkers took 5 ms with the default threads).  A
    log probability of one point (a model run each) runs in emcee, through
    ``pool``."""
    import emcee
    from threadpoolctl import threadpool_limits

    from bayes_update.core.posterior.stretch import stretch_sample

    random = np.random.RandomState(np.random.SeedSequence(seed).generate_state(1)[0])
    if len(x_init) != n_walkers:
        raise ValueError(f"{len(x_init)} initial points for {n_walkers} walkers")
    if vectorize and pool is None:
        with threadpool_limits(1):
            return stretch_sample(log_prob, x_init, n_steps, random, progress=progress, desc=desc)
    sampler = emcee.EnsembleSampler(n_walkers, x_init.shape[1], log_prob, vectorize=vectorize, pool=pool)
    sampler.random_state = random.get_state()
    with threadpool_limits(1 if vectorize else None):
        # a labelled bar on a terminal only (tqdm's disable=None): a log file gets no carriage returns
        sampler.run_mcmc(x_init, n_steps, progress=progress, progress_kwargs={"desc": desc, "disable": None})
    return sampler


def initial_walkers(log_prob_vec, x_map, cov, n_walkers, seed, scale: float = 0.3) -> np.ndarray:
    """Walkers drawn from N(x_map, scale^2 cov), kept where the density is finite
    (the scale shrinks by 0.7 while too few are)."""
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(cov + 1e-12 * np.diag(np.diag(cov)))
    out = []
    for _ in range(200):
        X = x_map + scale * rng.standard_normal((4 * n_walkers, len(x_map))) @ L.T
        ok = np.isfinite(log_prob_vec(X))
        out.extend(X[ok])
        if len(out) >= n_walkers:
            return np.array(out[:n_walkers])
        scale *= 0.7
    from bayes_update.core.checks import ModelFitError

    raise ModelFitError(
        "could not place the MCMC walkers where the posterior is finite: around the mode the "
        "prior or the model (failed runs) rule out every point; check the prior's bounds and "
        "where the model raises ModelError, or widen the prior"
    )


# ------------------------------------------------------------ convergence
#: a chain is converged when every reported variable has a rank-normalised split R-hat
#: below this (Vehtari et al. 2021: 1.01) ...
RHAT_TARGET = 1.01
#: ... and a bulk and a tail ESS of at least this (ArviZ's draws: every walker a chain)
MIN_ESS = 400
#: the kept draws are thinned to at most this many (the pointwise log-likelihood of
#: every kept draw goes into posterior.nc)
MAX_KEPT_DRAWS = 8000


def chain_convergence(draws: dict) -> dict:
    """R-hat and bulk and tail ESS of ``{variable: (walkers, draws) array}`` (ArviZ,
    each walker a chain), per variable, and whether all meet :data:`RHAT_TARGET`
    and :data:`MIN_ESS`."""
    per = {k: {"r_hat": rhat(v), "ess_bulk": ess(v, "bulk"), "ess_tail": ess(v, "tail")} for k, v in draws.items()}
    worst = {
        "max_r_hat": max(p["r_hat"] for p in per.values()),
        "min_ess_bulk": min(p["ess_bulk"] for p in per.values()),
        "min_ess_tail": min(p["ess_tail"] for p in per.values()),
    }
    ok = worst["max_r_hat"] < RHAT_TARGET and min(worst["min_ess_bulk"], worst["min_ess_tail"]) >= MIN_ESS
    return {**worst, "converged": bool(ok), "per_variable": per}


def kept_slice(n_steps: int, n_walkers: int, burn: int, thin: int) -> tuple[int, int]:
    """(burn, thin) of a chain of ``n_steps``: at least ``burn`` and a third of the
    chain discarded (a chain extended for convergence keeps its later part), and
    thinned to at most :data:`MAX_KEPT_DRAWS` draws."""
    burn = max(int(burn), n_steps // 3)
    thin = max(int(thin), -(-(n_steps - burn) * n_walkers // MAX_KEPT_DRAWS))
    return burn, thin


def run_to_convergence(
    sampler, extend, report, n_walkers: int, burn: int, thin: int, chunk: int, max_steps: int, log=None
) -> tuple[int, int, dict]:
    """Extend a chain by ``chunk`` steps at a time until its kept draws
    (:func:`kept_slice`) meet :func:`chain_convergence`, or it is ``max_steps`` long.

    ``sampler``: has ``iteration`` (or emcee's) and ``get_chain``; ``extend(n)``
    runs n more steps; ``report((m, d) draws) -> {variable: (m,) values}`` (the
    reported variables: R-hat is computed on what the summary shows).  Returns
    (burn, thin, convergence record with ``n_steps`` and ``cap_reached``)."""
    while True:
        steps = int(sampler.iteration)
        b, t = kept_slice(steps, n_walkers, burn, thin)
        chain = sampler.get_chain(discard=b, thin=t)  # (draws, walkers, d)
        values = report(chain.reshape(-1, chain.shape[-1]))
        conv = chain_convergence({k: np.swapaxes(v.reshape(chain.shape[:2]), 0, 1) for k, v in values.items()})
        conv.update(n_steps=steps, cap_reached=False)
        if conv["converged"]:
            return b, t, conv
        if steps + chunk > max_steps:
            conv["cap_reached"] = True
            return b, t, conv
        if log is not None:
            log(
                f"chain of {steps} steps: R-hat {conv['max_r_hat']:.4f}, ESS bulk {conv['min_ess_bulk']:.0f}, "
                f"tail {conv['min_ess_tail']:.0f}: {chunk} steps more"
            )
        extend(chunk)


def to_inference_data(
    chain, log_prob, space, attrs: dict, log_likelihood: dict | None = None, observed: dict | None = None
):
    """ArviZ InferenceData (0.x) or DataTree (1.x) (chain = walker) of the space's reported variables
    (:meth:`ParameterSet.report`: the parameters in their units, then derived
    coordinates such as the beam's P_eff), each with its ``units`` attribute;
    ``sample_stats`` with the log posterior ``lp``; ``log_likelihood`` (the
    pointwise log-likelihood of every observation at each draw,
    :mod:`bayes_update.core.posterior.pointwise`: {test: (steps, walkers, n_obs)}
    like ``chain``, stored as one variable ``observations`` whose coordinate
    ``observation`` names the test and direction of each, so that ``az.loo(idata)``
    and ``az.compare`` need no argument) and ``observed_data`` (one variable per
    test: its record, {name: (values (n,) or (n, k), units)}) when given."""
    X = np.swapaxes(chain, 0, 1)  # (walker, draw, d)
    values = space.report(X.reshape(-1, X.shape[-1]))
    post = {k: v.reshape(X.shape[:2]) for k, v in values.items()}
    groups, dims, coords = {"posterior": post, "sample_stats": {"lp": np.swapaxes(log_prob, 0, 1)}}, {}, {}
    if log_likelihood:
        groups["log_likelihood"] = {
            "observations": np.swapaxes(np.concatenate(list(log_likelihood.values()), axis=-1), 0, 1)
        }
        dims["observations"] = ["observation"]
        coords["observation"] = [f"{k}[{j}]" for k, v in log_likelihood.items() for j in range(v.shape[-1])]
    if observed:
        groups["observed_data"] = {k: v for k, (v, _) in observed.items()}
        dims.update({k: _record_dims(k, v) for k, (v, _) in observed.items()})
    idata = from_dict(groups, dims, coords, attrs)
    for var, unit in space.report_units.items():
        idata.posterior[var].attrs["units"] = unit
    for k, (_, unit) in (observed or {}).items():
        idata.observed_data[k].attrs["units"] = unit
    return idata


def _record_dims(name: str, values) -> list:
    return [f"{name}_time"] + ([f"{name}_sensor"] if np.ndim(values) == 2 else [])


def add_posterior_predictive(idata, draws: dict, units: dict) -> None:
    """Add the ``posterior_predictive`` group: {test: (n draws, n samples[, sensors])}
    of the predicted record at posterior draws (one chain), on the dimensions of
    ``observed_data``."""
    variables = {k: v[None] for k, v in draws.items()}
    add_group(idata, "posterior_predictive", variables, {k: _record_dims(k, v[0]) for k, v in draws.items()})
    for k in draws:
        idata.posterior_predictive[k].attrs["units"] = units.get(k, "")


def summarize(idata, space, hdi_prob: float = 0.94) -> dict:
    """Per variable: mean, sd, hdi_3%, hdi_97%, r_hat, ess_bulk, ess_tail and its
    ``units`` (:attr:`ParameterSet.report_units`)."""
    s = summary(idata, hdi_prob)
    out = {}
    for var, unit in space.report_units.items():
        row = s.loc[var]
        out[var] = {
            "mean": float(row["mean"]),
            "sd": float(row["sd"]),
            "hdi_3%": float(row["hdi_lo"]),
            "hdi_97%": float(row["hdi_hi"]),
            "r_hat": float(row["r_hat"]),
            "ess_bulk": float(row["ess_bulk"]),
            "ess_tail": float(row["ess_tail"]),
            "units": unit,
        }
    return out


class XSampler:
    """A sampler run in u (emcee or its vectorised move), read in x (chains, log probabilities, tau)."""

    def __init__(self, sampler, whitening: Whitening):
        self.sampler, self.whitening = sampler, whitening
        self.acceptance_fraction = sampler.acceptance_fraction

    def get_chain(self, **kw):
        flat = kw.pop("flat", False)
        c = self.sampler.get_chain(**kw)
        x = self.whitening.to_x(c.reshape(-1, c.shape[-1])).reshape(c.shape)
        return x.reshape(-1, x.shape[-1]) if flat else x

    def get_log_prob(self, **kw):
        return self.sampler.get_log_prob(**kw)

    def get_autocorr_time(self, **kw):
        import emcee

        return emcee.autocorr.integrated_time(
            self.get_chain(discard=kw.get("discard", 0)), tol=kw.get("tol", 50), quiet=kw.get("quiet", True)
        )


def fraction_outside_box(U, box_sd: float, whitening: Whitening, space: ParameterSet) -> float:
    """Fraction of draws within 0.25 of the u box's edge where the prior goes
    on beyond it (pushing them 0.5 further out stays inside the prior): the
    box, not the prior, cut the posterior there."""
    near = np.abs(U) > box_sd - 0.25
    cut = np.zeros(len(U), bool)
    for i in range(U.shape[1]):
        idx = np.flatnonzero(near[:, i])
        if idx.size:
            pushed = U[idx].copy()
            pushed[:, i] += 0.5 * np.sign(pushed[:, i])
            cut[idx] |= np.isfinite(space.log_prior(whitening.to_x(pushed)))
    return float(cut.mean())


def chain_diagnostics(sampler, burn: int, names) -> dict:
    chain = sampler.get_chain(discard=burn)
    # emcee's own check (a chain of 50 autocorrelation times, else a logged warning) is
    # stricter than an ensemble of 128 walkers needs for its means and quantiles: the
    # length in autocorrelation times is recorded instead (the default's 40-70 on the
    # beam and the Duffing), with R-hat and the bulk ESS beside it
    tau = sampler.get_autocorr_time(discard=burn, tol=0)
    return {
        "autocorr_time_steps": dict(zip(names, map(float, tau))),
        "chain_length_in_autocorr_times": float(chain.shape[0] / max(float(np.max(tau)), 1e-300)),
        "acceptance_fraction": float(np.mean(sampler.acceptance_fraction)),
        "n_draws": int(chain.shape[0] * chain.shape[1]),
    }
