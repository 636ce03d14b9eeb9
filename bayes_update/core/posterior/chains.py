"""Steps 4-5 of :func:`~bayes_update.core.posterior.sampler.sample`: the chain on the surrogates
(in a local box re-centred while it cuts the posterior) or on the model itself."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bayes_update.core.likelihood import Likelihood
from bayes_update.core.posterior.design import build_surrogates, gauss_newton_means
from bayes_update.core.posterior.laplace import capped_covariance
from bayes_update.core.posterior.mcmc import (
    XSampler,
    fraction_outside_box,
    initial_walkers,
    run_emcee,
    run_to_convergence,
)
from bayes_update.core.posterior.run import Run
from bayes_update.core.posterior.target import (
    DirectLogPosterior,
    Evaluate,
    ExecutorPool,
    WhitenedEvaluate,
    WhitenedLogPosterior,
    Whitening,
)


@dataclass
class Chain:
    """What a sampling step leaves: the sampler (read in internal coordinates) and,
    on the surrogate path, the surrogates, their design and the local box's record."""

    sampler: object
    burn: int
    thin: int
    gps: dict = field(default_factory=dict)
    design: dict = field(default_factory=dict)
    diagnostics: dict = field(default_factory=dict)
    log_likelihood: dict = field(default_factory=dict)  # stage -> (steps, walkers) of the kept draws
    target: object = None  # the surrogate log posterior (u coordinates)


def walker_covariance(mp, adj) -> np.ndarray:
    """Where the walkers start: the Laplace covariance at the MAP, widened as the curvature
    adjustment widens the likelihood (the tests' disagreement may make it many times wider)."""
    return mp.covariance if adj is None else adj.covariance(mp.covariance)


def direct_chain(run: Run, lik, mp, adj) -> Chain:
    """4-5, direct path: emcee on the model itself.  Its runs are not kept in the run store:
    a chain on the model makes 10^4-10^6 runs of a model cheap enough for it (a few ms), which
    would fill the cache with responses that cost more to write and read than to make."""
    store, run.problem.run_store = run.problem.run_store, None
    try:
        return _direct_emcee(run, lik, mp, adj)
    finally:
        run.problem.run_store = store


def _direct_emcee(run: Run, lik, mp, adj) -> Chain:
    s = run.settings
    with run.steps("mcmc"):
        logp = DirectLogPosterior(Evaluate(run.problem, run.space, run.problem.stages), lik, adj)
        x_init = initial_walkers(
            lambda X: np.array([logp(x)[0] for x in X]),
            mp.x,
            walker_covariance(mp, adj),
            s.direct_walkers,
            run.seeds.walkers,
            scale=1.0,
        )
        sampler = run_emcee(
            logp,
            x_init,
            s.direct_walkers,
            s.direct_steps,
            run.seeds.chain,
            vectorize=False,
            pool=ExecutorPool(run.pool) if run.pool is not None else None,
            progress=run.progress,
            desc="MCMC on the model",
        )

        def extend(n):
            sampler.run_mcmc(None, n, progress=run.progress, progress_kwargs={"desc": "MCMC on the model (more)"})

        burn, thin, conv = run_to_convergence(
            sampler,
            extend,
            run.space.report,
            s.direct_walkers,
            s.direct_burn,
            1,
            s.direct_steps,
            s.direct_max_steps,
            run.log,
        )
        run.steps.add_runs(len(run.problem.stages) * s.direct_walkers * sampler.iteration)
    blobs = sampler.get_blobs(discard=burn, thin=thin)  # (steps, walkers, stages)
    return Chain(
        sampler,
        burn,
        thin,
        diagnostics={"convergence": conv},
        log_likelihood={st: blobs[..., i] for i, st in enumerate(run.problem.stages)},
    )


def surrogate_chain(run: Run, lik, mp, adj) -> Chain:
    """4-5, surrogate path: GPs on a design in the whitened local box, emcee on
    them; the box re-centred and widened while it cuts the posterior."""
    s, space, stages = run.settings, run.space, run.problem.stages
    d = len(space.coordinate_names)
    ev = Evaluate(run.problem, space, stages)
    whitening = Whitening.from_covariance(mp.x, capped_covariance(mp.covariance, space, s.box_sd))
    ubox = np.array([[-s.box_sd, s.box_sd]] * d, float)
    run.steps.timing["gp_fit"] = 0.0
    design = None
    for attempt in range(s.box_attempts):
        with run.steps("design_and_gp"):
            means = (
                gauss_newton_means(mp.mode, run.problem, stages, whitening)
                if s.gp_mean == "gauss_newton" and mp.mode is not None
                else None
            )
            earlier = None if design is None else (design["X"], design["z"])
            gps, U, Y, fit_time, n_earlier = build_surrogates(
                WhitenedEvaluate(ev, whitening),
                lik,
                space=space,
                box=ubox,
                whitening=whitening,
                settings=s,
                pool=run.pool,
                cache_dir=None,
                stages=stages,
                seed=run.seeds.design + attempt,
                progress=run.progress,
                log=run.log,
                reused=run.reused,
                means=means,
                earlier=earlier,
            )
            # the earlier box's points were run (and counted) there
            run.steps.add_runs(len(stages) * (int(np.sum(np.all(np.isfinite(Y), axis=1))) - n_earlier))
        run.steps.timing["gp_fit"] += fit_time
        design = {"X": whitening.to_x(U), "z": Y, "whitening": whitening}
        with run.steps("mcmc"):
            logp_u = WhitenedLogPosterior(gps, space, ubox, whitening, adj)
            # the walkers over the (adjusted) Laplace posterior's whole width: from a ball of 0.3 sd
            # the ensemble took longer than a 3000-step chain to spread (R-hat 1.012-1.020)
            L_inv = np.linalg.inv(whitening.L)
            u_init = initial_walkers(
                logp_u,
                whitening.to_u(mp.x)[0],
                L_inv @ walker_covariance(mp, adj) @ L_inv.T,
                s.n_walkers,
                run.seeds.walkers,
                scale=1.0,
            )
            sampler = run_emcee(
                logp_u,
                u_init,
                s.n_walkers,
                s.n_steps,
                run.seeds.chain,
                vectorize=True,
                progress=run.progress,
                desc="MCMC on the surrogate",
            )
        u_draws = sampler.get_chain(discard=s.burn, flat=True)
        cut = fraction_outside_box(logp_u.gp_points(u_draws), s.box_sd, whitening, space)
        if cut <= 0.01 or attempt == s.box_attempts - 1:
            break
        # the Laplace box cut the posterior (a non-Gaussian posterior, or a MAP short of the
        # mode): re-centre and re-whiten on the surrogate posterior's draws, 3x wider (they are
        # truncated by the old box)
        x_draws = whitening.to_x(u_draws)
        run.log(
            f"the local box cut {100 * cut:.1f} % of the draws: re-centred on them, 3x wider "
            f"(attempt {attempt + 2} of {s.box_attempts})"
        )
        whitening = Whitening.from_covariance(
            x_draws.mean(axis=0), capped_covariance(9.0 * np.cov(x_draws.T), space, s.box_sd)
        )
    with run.steps("mcmc"):
        burn, thin, conv = run_to_convergence(
            sampler,
            lambda n: sampler.extend(logp_u, n, run.progress, "MCMC on the surrogate (more)"),
            lambda U: space.report(whitening.to_x(U)),
            s.n_walkers,
            s.burn,
            s.thin,
            s.n_steps,
            s.max_steps,
            run.log,
        )
    diag = {
        "box_cut_fraction": fraction_outside_box(
            logp_u.gp_points(sampler.get_chain(discard=burn, flat=True)), s.box_sd, whitening, space
        ),
        "box_attempts": attempt + 1,
        "convergence": conv,
    }
    kept = sampler.get_chain(discard=burn, thin=thin)
    G = logp_u.gp_points(kept.reshape(-1, d))
    # z = log(1 + e^2 / s^2) >= 0; the GP's mean may dip a hair below it near the mode
    ll = {
        st: Likelihood.log_likelihood_from_z({st: np.maximum(gp.mean_transformed(G), 0.0)}).reshape(kept.shape[:2])
        for st, gp in gps.items()
    }
    return Chain(XSampler(sampler, whitening), burn, thin, gps, design, diag, ll, logp_u)
