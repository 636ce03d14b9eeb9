"""The surrogates of the posterior: a Sobol' design in the whitened local box, Gaussian
processes of z = log(1 + e^2 / s^2) per stage, refinement rounds where the posterior is until
the surrogate posterior stops moving; the evaluation cache an interrupted run resumes from."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import partial

import numpy as np

import surrogates
from bayes_update.core.likelihood import Likelihood
from bayes_update.core.model import ModelSpecError
from bayes_update.core.posterior.mcmc import initial_walkers, run_emcee
from bayes_update.core.posterior.target import Evaluate, WhitenedEvaluate, WhitenedLogPosterior, Whitening
from surrogates.evaluation import evaluate_many


def design_gp(box, seed, names, prior_mean=None):
    # fast: the hyperparameters by surrogates.gp_fit (scikit-learn's objective and optimiser, its
    # gradient in numpy), the fits of a design costing a fraction of scikit-learn's own
    return surrogates.GPSurrogate(
        box, transform="none", names=list(names), n_restarts_optimizer=2, seed=seed, prior_mean=prior_mean, fast=True
    )


@dataclass
class GaussNewtonMean:
    """A stage's ``z = log(1 + e^2 / s^2)`` as the Gauss-Newton model at the MAP predicts it, in u:
    ``e^2 / s^2 = ||r + J dx||^2`` with the MAP's scaled residual r and Jacobian J of the stage
    and ``dx = x(u) - x_MAP``, an exact quadratic in u, ``c + 2 g.u + u.H.u`` (clipped at 0).

    The GP of z models what the model does beyond its linearisation at the MAP: zero
    where the posterior is Gaussian, and far from the design points the prediction
    falls back on the Laplace picture, not on a constant."""

    c: float
    g: np.ndarray
    H: np.ndarray

    @classmethod
    def at_mode(cls, residual, jacobian, x_map, whitening: Whitening) -> "GaussNewtonMean":
        r, J = np.asarray(residual, float), np.asarray(jacobian, float)
        b = whitening.center - np.asarray(x_map, float)  # dx = L u + b
        rb = r + J @ b
        JL = J @ whitening.L
        return cls(c=float(rb @ rb), g=JL.T @ rb, H=JL.T @ JL)

    def __call__(self, U) -> np.ndarray:
        U = np.atleast_2d(U)
        q = self.c + U @ (2.0 * self.g) + np.sum((U @ self.H) * U, axis=1)
        return np.log1p(np.maximum(q, 0.0))


def gauss_newton_means(mode, problem, stages, whitening: Whitening) -> list:
    """One :class:`GaussNewtonMean` per stage from a mode search's residual and Jacobian
    (the stages' rows in ``problem.stages`` order, scaled by the likelihood's s)."""
    means, row = {}, 0
    for st in problem.stages:
        n = problem.output(st, problem.reference_components(st)).size
        means[st] = GaussNewtonMean.at_mode(
            mode.residual[row : row + n], mode.jacobian[row : row + n], mode.x, whitening
        )
        row += n
    return [means[st] for st in stages]


def build_surrogates(
    ev: WhitenedEvaluate,
    lik,
    *,
    space,
    box,
    whitening,
    settings,
    pool,
    cache_dir,
    stages,
    seed,
    progress,
    log,
    reused=None,
    means=None,
    earlier=None,
):
    """Design in the whitened box (inside the prior), GPs of z per stage,
    refinement rounds; all in u coordinates.  ``means``: a prior mean per stage
    (:func:`gauss_newton_means`), else constant means.  ``earlier``: (X, z) of
    runs already made (an earlier box's design, X in the model's internal
    coordinates): those inside this box join its initial design.  Returns the GPs, the
    design (u, z), the GP fits' time [s] and how many of its points were ``earlier``'s."""
    from threadpoolctl import threadpool_limits

    ss = np.random.SeedSequence(seed).spawn(3)
    # a Sobol' design of the u box, keeping the points inside the prior
    # (near a corner of the prior most of the box is outside: draw more)
    n0 = n_initial(settings, len(box))
    for factor in (8, 64, 512):
        cand = surrogates.design(box, factor * n0, "sobol", seed=int(ss[0].generate_state(1)[0]))
        inside = np.isfinite(space.log_prior(whitening.to_x(cand)))
        if inside.sum() >= n0:
            break
    else:
        raise ModelSpecError(
            f"the surrogates' design: only {inside.sum()} of {len(cand)} candidate points of the "
            f"local box around the MAP ({settings.box_sd:g} sd wide) fall inside the prior: the MAP "
            "sits in a corner of the prior, or the prior is far narrower than the posterior; "
            "widen the prior where the MAP is on a bound (--prior NAME=LO:HI), or sample on the "
            "model itself (--direct)"
        )
    U0 = cand[inside][:n0]
    cache = design_cache(cache_dir, ev.evaluate, "design", whitening, reused)
    evaluate = partial(surrogates.cached_evaluate, cache=cache) if cache is not None else evaluate_many
    res = evaluate(ev, list(U0), executor=pool, progress=progress)

    def target(r):
        return [float(lik.to_z(st, r[Likelihood.key(st)])) for st in stages]

    Y0 = np.array([target(r) for r in res])
    n_earlier = 0
    if earlier is not None:
        U_old = whitening.to_u(earlier[0])
        keep = (
            np.all(np.abs(U_old) <= box[:, 1], axis=1)
            & np.all(np.isfinite(earlier[1]), axis=1)
            & np.isfinite(space.log_prior(earlier[0]))
        )
        U0, Y0 = np.vstack([U0, U_old[keep]]), np.vstack([Y0, earlier[1][keep]])
        n_earlier = int(keep.sum())
        log(f"the design starts with {int(keep.sum())} runs of the earlier box inside this one")

    def weight(surs):
        return WhitenedLogPosterior(dict(zip(stages, surs)), space, box, whitening)

    check_rng = np.random.default_rng(ss[2])

    def log_likelihood(Z):
        return Likelihood.log_likelihood_from_z({st: Z[:, k] for k, st in enumerate(stages)})

    stability = _Stability(weight, len(box), settings.stop_tolerance, check_rng, log, log_likelihood)

    def candidates(surs, rng):
        # draws of a short MCMC on the current surrogate posterior (the stability check's when
        # the design stops on it), plus Sobol' points
        if settings.stop_tolerance > 0:
            draws = stability.draws(surs)
            draws = draws[rng.permutation(len(draws))[:1600]]
        else:
            logp = weight(surs)
            init = initial_walkers(logp, np.zeros(len(box)), np.eye(len(box)), 16, int(rng.integers(2**31)))
            smp = run_emcee(logp, init, 16, 400, int(rng.integers(2**31)), vectorize=True, progress=False)
            draws = smp.get_chain(discard=200, thin=2, flat=True)
        sob = surrogates.design(box, 512, "sobol", seed=int(rng.integers(2**31)))
        return np.vstack([draws, sob])

    def factory():
        if means is None:
            return design_gp(box, seed=0, names=space.coordinate_names)
        return [design_gp(box, seed=0, names=space.coordinate_names, prior_mean=m) for m in means]

    with threadpool_limits(2):
        ref = surrogates.refine(
            ev,
            factory,
            U0,
            Y0,
            weight,
            settings.n_rounds,
            n_batch(settings, len(box)),
            pool,
            seed=int(ss[1].generate_state(1)[0]),
            candidates=candidates,
            target=target,
            log_weight=True,
            evaluate=evaluate,
            progress=progress,
            until=stability if settings.stop_tolerance > 0 else None,
            warm_start=True,
            parallel_fits=True,
        )
    # the GP fits alone (the refinement's wall time also holds its model runs, its stopping
    # rule's chains and the choice of points, which were all reported as the GP fits' before)
    t_fit = ref.seconds["fit"]
    log("design's wall time by part: " + ", ".join(f"{k} {v:.1f} s" for k, v in ref.seconds.items()))
    if settings.stop_tolerance > 0 and not stability.stopped:
        msg = (
            f"the design used all {settings.n_rounds} refinement rounds without its stopping rule firing "
            f"(last round: {stability.last or 'none'}): the surrogates may still be wrong where the posterior "
            "is; raise n_rounds, or check them with n_predictive"
        )
        log("WARNING: " + msg)
        warnings.warn(msg, RuntimeWarning)
    gps = dict(zip(stages, ref.surrogate))
    for st, gp in gps.items():
        log(
            f"GP of z_{st}: {int(np.isfinite(ref.y[:, 0]).sum())} runs in {len(ref.rounds)} fits; "
            + gp.summary().splitlines()[0]
        )
    return gps, ref.X, ref.y, t_fit, n_earlier


def n_initial(settings, d: int) -> int:
    """Points of the initial design: ``settings.n_initial``, else 4 per dimension (at least 8)."""
    return settings.n_initial if settings.n_initial else max(8, 4 * d)


def n_batch(settings, d: int) -> int:
    """Points per refinement round: ``settings.batch``, else 2 per dimension."""
    return settings.batch if settings.batch else max(4, 2 * d)


#: walkers of the stopping rule's chains
STABILITY_WALKERS = 64
#: the design stops only when the surrogate predicted the last round's runs within this many nats of
#: log likelihood, at those of them in the posterior's mass (within MASS_LEVEL of the best run so far,
#: in chi-square terms: half the 99 % quantile for the number of parameters)
ACCURACY_NATS = 1.0
MASS_LEVEL = 0.99
#: one quiet round stops the design when its move and its runs' prediction error are below this
#: share of the tolerance and of ACCURACY_NATS (else two quiet rounds in a row)
SETTLED = 0.1


class _Stability:
    """The design's stopping rule: the surrogate posterior no longer moving.

    Called with the current surrogates before every refinement round: draws of
    the previous round's surrogate posterior (an emcee run, whitened
    coordinates, where the Laplace posterior has unit sd) are reweighted to the
    current one (importance weights p_now / p_before on the same draws, so that
    the comparison carries no Monte Carlo noise of two separate chains); the
    move is the largest shift of a mean in sd and the largest relative change
    of an sd.  Stable when both stay below ``tolerance`` twice in a row (one
    quiet round can be luck: a round whose points all land where the surrogate
    was already right), or once when they stay below a tenth of it and the
    round's runs were predicted within a tenth of :data:`ACCURACY_NATS`
    (:data:`SETTLED`), and the weights' effective sample size is above half
    the draws (otherwise the posterior moved too far for the reweighting to
    tell).  Each round's chain starts from the previous one's walkers.

    A surrogate posterior can stop moving while it is wrong: on a curved ridge
    the GPs extrapolate along the valley alike round after round (the portal
    frame whose modulus and joint trade, benchmarks/ridge_frame.py: stable
    twice in a row with errors of 8-20 nats at the ridge's end, the truth
    outside every 90 % interval).  So the rule also reads what each round's
    runs were before they were run: with ``log_likelihood`` (z per stage ->
    log likelihood), the design stops only when the surrogate predicted the
    last round's runs that lie in the posterior's mass within
    :data:`ACCURACY_NATS` (a held-out check that costs no run)."""

    def __init__(self, weight, d: int, tolerance: float, rng, log, log_likelihood=None):
        self.weight, self.d, self.tolerance, self.rng, self.log = weight, d, tolerance, rng, log
        self.log_likelihood = log_likelihood
        self.previous, self.quiet, self._cache, self._last = None, 0, (None, None, None), None
        self.stopped, self.last = False, ""  # whether it fired; the last round's line

    def prediction_error(self, rounds) -> float:
        """The largest |log likelihood predicted - run| [nats] over the last round's runs in
        the posterior's mass (0 when none is, nan without a round or ``log_likelihood``)."""
        if self.log_likelihood is None or not rounds or "y_pred" not in rounds[-1]:
            return float("nan")
        from scipy import stats

        # z per stage, (runs, stages): the design's rounds
        ll_ran, ll_pred = self.log_likelihood(rounds[-1]["y_new"]), self.log_likelihood(rounds[-1]["y_pred"])
        ll_all = self.log_likelihood(np.vstack([r["y_new"] for r in rounds]))
        best = float(np.max(ll_all[np.isfinite(ll_all)], initial=-np.inf))
        inside = np.isfinite(ll_ran) & (np.maximum(ll_ran, ll_pred) >= best - 0.5 * stats.chi2.ppf(MASS_LEVEL, self.d))
        return float(np.max(np.abs(ll_ran - ll_pred)[inside], initial=0.0))

    def _run(self, surs):
        if self._cache[0] is not surs:
            logp = self.weight(surs)
            # from the previous round's walkers where the new surrogate allows them (burnt in
            # already: 100 steps, 25 discarded), else from the Laplace posterior (250, 125); the
            # walkers of a step are one vectorised call, so 64 of them for a quarter of the steps
            # 16 took (the same 4800 draws a round, a quarter of the time)
            last = self._last if self._last is not None and np.all(np.isfinite(logp(self._last))) else None
            init = (
                last
                if last is not None
                else initial_walkers(
                    logp, np.zeros(self.d), np.eye(self.d), STABILITY_WALKERS, int(self.rng.integers(2**31))
                )
            )
            n, burn = (100, 25) if last is not None else (250, 125)
            smp = run_emcee(
                logp, init, STABILITY_WALKERS, n, int(self.rng.integers(2**31)), vectorize=True, progress=False
            )
            self._last = smp.get_last_sample().coords
            self._cache = (surs, smp.get_chain(discard=burn, flat=True), smp.get_log_prob(discard=burn, flat=True))
        return self._cache[1], self._cache[2]

    def draws(self, surs) -> np.ndarray:
        return self._run(surs)[0]

    def __call__(self, surs, rounds=()) -> bool:
        stable = False
        error = self.prediction_error(rounds)
        if self.previous is not None:
            x, lp_before = self.previous
            lp_now = self.weight(surs)(x)
            logw = np.where(np.isfinite(lp_now), lp_now - lp_before, -np.inf)
            w = np.exp(logw - np.max(logw))
            w /= w.sum()
            ess = 1.0 / np.sum(w**2) / len(w)
            m0, s0 = x.mean(axis=0), x.std(axis=0)
            m1 = w @ x
            s1 = np.sqrt(np.maximum(w @ (x - m1) ** 2, 1e-300))
            shift = float(np.max(np.abs(m1 - m0) / s0))
            spread = float(np.max(np.abs(np.log(s1 / s0))))
            self.quiet = self.quiet + 1 if max(shift, spread) < self.tolerance and ess > 0.5 else 0
            predicted = not error > ACCURACY_NATS  # nan (no check): not in the way
            # one round is enough when it moved nothing and its runs were predicted, each by a
            # tenth of the bars: a round that landed only where the surrogate was right already
            # would still have had to be predicted there (the 6-parameter lab chain: 0.005 sd,
            # 0.01 nats; a second round 0.002 sd, 0.00 nats, 24 runs)
            settled = (
                self.quiet >= 1 and max(shift, spread) < SETTLED * self.tolerance and error < SETTLED * ACCURACY_NATS
            )
            stable = self.stopped = (self.quiet >= 2 and predicted) or bool(settled)
            self.last = (
                f"the surrogate posterior moved {shift:.3f} sd (means), {100 * spread:.1f} % (sds), "
                f"reweighting ESS {100 * ess:.0f} %"
                + (f"; its runs predicted within {error:.2f} nats" if np.isfinite(error) else "")
            )
            self.log(f"  design round: {self.last}" + ("; stable: the design stops" if stable else ""))
        self.previous = self._run(surs)
        return stable


def design_cache(cache_dir, ev: Evaluate, name: str, whitening: Whitening | None = None, reused: dict | None = None):
    """The evaluation cache of ``name`` under ``cache_dir`` (None: no cache); ``reused``
    counts the model runs its entries on disk save, per name."""
    if cache_dir is None:
        return None
    from pathlib import Path

    from bayes_update.core.basis import describe_basis

    config = {
        "what": name,
        "stages": list(ev.stages),
        "model": ev.problem.describe()["model"],
        "basis": describe_basis(ev.problem.basis),
        "metric_set": ev.problem.metrics,
        "data": ev.problem.data_fingerprint,
        "coordinates": list(ev.space.coordinate_names),
    }
    if whitening is not None:  # points are stored in the whitened coordinates
        config["whitening"] = {"center": whitening.center.tolist(), "L": whitening.L.tolist()}
    path = Path(cache_dir)
    path.mkdir(parents=True, exist_ok=True)
    cache = surrogates.EvaluationCache(path / name, config)
    if reused is not None:
        reused[name] = reused.get(name, 0) + cache.n_loaded * len(ev.stages)
    return cache
