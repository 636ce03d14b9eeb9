"""The posterior over (eta, c, F, k_s): surrogate-based (default) or direct.

Pipeline of :func:`sample` (each step's numbers go to the result):

1. start: the paper's deterministic updating on coarse grids
   (:func:`bayes_update.calibrate.calibrate`, quick settings), unless a start
   point is given;
2. likelihood scales at the start (:func:`bayes_update.likelihood.estimate_likelihood`:
   noise replicates and the model error against a refined model);
3. MAP by least squares on the metrics' residual vectors (trust-region
   Gauss-Newton on direct model runs, :mod:`bayes_update.mode`; from the
   start and from the best points of a grid on the c-k_s band) and the
   Laplace covariance from the residuals' Jacobian there;
4. surrogate path: coordinates whitened by the Laplace covariance, a Sobol'
   design in the box of +-``box_sd`` in them (points inside the prior), Gaussian processes of
   z = log(1 + e^2 / s^2) per stage, refined in rounds where the surrogate
   posterior has mass (:func:`surrogates.refine`, candidates from short MCMC
   runs on the current surrogate); direct path: no surrogate;
5. emcee (stretch move, seeded) on the surrogate's (or the model's)
   posterior, restricted to the local box; ArviZ data in SI units with P_eff.

Why a local box: the posterior of P_eff is ~0.03 % wide, 1e-4 of the prior
range, so a design over the whole prior box would put no point in it.  The
whole prior box is still searched: by the deterministic start (grids over c,
k_s and eta) and by the global design of the sensitivity analysis.  The
result records the fraction of draws that the box, not the prior, cut
(``box_cut_fraction``); above 1 % the box is re-centred on the draws, 3x
wider, up to ``box_attempts`` times.
"""
from __future__ import annotations

import math
import time
import warnings
from concurrent.futures import Executor
from dataclasses import asdict, dataclass, field
from functools import partial

import numpy as np

import fe
import surrogates

from .beam_rig import rig_of
from .dataset import Dataset
from .evaluation import default_executor, evaluate_many
from .core import check_model
from .likelihood import (UNITS, CurvatureAdjustment, Likelihood, ParameterSpace, curvature_adjustment,
                         estimate_likelihood)
from .metrics import UpdatingProblem


@dataclass(frozen=True)
class PosteriorSettings:
    """Sizes of every step (model runs are counted per test)."""

    # noise replicates for the likelihood scales and the curvature adjustment's noise covariance:
    # at 24 the sandwich from the replicates was itself too noisy (50 SBC truths: the truth beyond
    # the 90 % chi^2_4 point in 14 %, at 96 in 8 %; benchmarks/sbc_linearised.py)
    n_replicates: int = 96
    n_initial: int = 96         # Sobol' points in the local box
    n_rounds: int = 5           # refinement rounds
    batch: int = 32             # points per round
    box_sd: float = 4.0         # half-width of the local box [Laplace marginal sd]
    n_walkers: int = 32
    n_steps: int = 12000        # on the surrogate; direct runs use direct_steps
    burn: int = 2000
    thin: int = 10              # kept draws: every thin-th step after burn-in
    direct_steps: int = 3000
    direct_burn: int = 1000
    box_attempts: int = 3       # re-centred, wider boxes when the first cuts the posterior
    n_linear: int = 64          # design of the linear-only posterior (0: skip it)
    n_global: int = 128         # global design for the sensitivity indices (0: skip)
    sobol_n: int = 1024         # SALib base sample size
    n_predictive: int = 32      # FE runs at posterior draws (bands and surrogate check)
    model_error: bool = True    # add the measured model error to the likelihood
    curvature_adjustment: bool = True   # sandwich-adjust the likelihood's curvature (likelihood.curvature_adjustment)
    map_max_evaluations: int = 600
    n_start: int = 64           # Sobol' points of the start search (models other than the beam)
    seed: int = 0

    def __post_init__(self):
        for name in ("n_replicates", "n_initial", "n_rounds", "batch", "n_walkers", "n_steps", "burn", "thin",
                     "direct_steps", "direct_burn", "box_attempts",
                     "n_linear", "n_global", "sobol_n", "n_predictive", "map_max_evaluations", "n_start"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < 0:
                raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
        if self.n_walkers < 8 or self.n_steps <= self.burn or self.direct_steps <= self.direct_burn:
            raise ValueError("need n_walkers >= 8, n_steps > burn and direct_steps > direct_burn")
        if self.thin < 1 or self.box_attempts < 1:
            raise ValueError("thin and box_attempts must be >= 1")
        if self.n_initial < 8:
            raise ValueError("n_initial must be at least 8")
        if not self.box_sd > 1:
            raise ValueError("box_sd must be > 1")

    @classmethod
    def quick(cls, **kw) -> "PosteriorSettings":
        """Small sizes for tests and a first look (about a fifth of the runs)."""
        base = dict(n_replicates=12, n_initial=40, n_rounds=2, batch=16, n_walkers=24, n_steps=3000,
                    burn=1000, thin=5, direct_steps=1000, direct_burn=400, n_linear=32, n_global=48,
                    sobol_n=256, n_predictive=8, map_max_evaluations=250)
        base.update(kw)
        return cls(**base)


# ------------------------------------------------------------ model callables
@dataclass
class Evaluate:
    """Picklable ``x (internal coordinates) -> metrics dict`` on the model."""

    problem: UpdatingProblem
    space: ParameterSpace
    stages: tuple

    def __call__(self, x):
        return self.problem.evaluate(self.space.to_parameters(np.asarray(x, float)), self.stages)


@dataclass
class DirectLogPosterior:
    """Picklable log posterior on direct model runs (emcee's ``log_prob_fn``)."""

    evaluate: Evaluate
    likelihood: Likelihood
    adjustment: CurvatureAdjustment | None = None

    def __call__(self, x):
        lp = float(self.evaluate.space.log_prior(x)[0])
        if not np.isfinite(lp):
            return -np.inf
        if self.adjustment is not None:
            # the likelihood's argument, kept in the bounding box the model is run in (near a
            # bound it may step outside; a -inf there would cut the posterior at the bound)
            box = self.evaluate.space.box()
            x = np.clip(self.adjustment(x)[0], box[:, 0], box[:, 1])
        return lp + self.likelihood.log_likelihood(self.evaluate(x))


class _ExecutorPool:
    """The ``map`` emcee wants, on a concurrent.futures executor."""

    def __init__(self, executor, chunks_per_worker: int = 1):
        self.executor = executor
        self.workers = getattr(executor, "_max_workers", None) or 2
        self.chunks = chunks_per_worker

    def map(self, func, iterable):
        items = list(iterable)
        chunk = max(1, math.ceil(len(items) / (self.workers * self.chunks)))
        try:
            return list(self.executor.map(func, items, chunksize=chunk))
        except TypeError:            # executors without chunksize
            return list(self.executor.map(func, items))


@dataclass
class SurrogateLogPosterior:
    """Vectorised log posterior from GP means of z per stage (restricted to ``box``)."""

    gps: dict            # stage -> fitted GPSurrogate of z
    space: ParameterSpace
    box: np.ndarray

    def __call__(self, X):
        X = np.atleast_2d(X)
        lp = self.space.log_prior(X)
        inside = np.all((X >= self.box[:, 0]) & (X <= self.box[:, 1]), axis=1) & np.isfinite(lp)
        out = np.full(len(X), -np.inf)
        if inside.any():
            z = {st: gp.predict_transformed(X[inside])[0] for st, gp in self.gps.items()}
            out[inside] = lp[inside] + Likelihood.log_likelihood_from_z(z)
        return out


@dataclass(frozen=True)
class Whitening:
    """Affine map x = center + L u from coordinates u in which the Laplace
    approximation is a standard normal.  The GPs live in u: the posterior's
    valleys are diagonal in x (c and k_s trade off, correlation -0.96 on the
    default data), and an axis-aligned kernel fits a diagonal valley badly
    (measured: median error of e_nlin at posterior draws 25 % in x, 4 % in u,
    same 256 runs)."""

    center: np.ndarray
    L: np.ndarray

    @classmethod
    def from_covariance(cls, center, cov) -> "Whitening":
        w, V = np.linalg.eigh(cov)
        return cls(np.asarray(center, float), V * np.sqrt(np.maximum(w, 1e-300)))

    def to_x(self, U):
        return self.center + np.atleast_2d(U) @ self.L.T

    def to_u(self, X):
        return np.linalg.solve(self.L, (np.atleast_2d(X) - self.center).T).T


@dataclass
class WhitenedEvaluate:
    """``u -> metrics`` for the surrogate stage; points outside the prior are
    not run (NaN metrics), since they carry no posterior mass."""

    evaluate: Evaluate
    whitening: Whitening

    def __call__(self, u):
        x = self.whitening.to_x(np.asarray(u, float))[0]
        if not np.isfinite(self.evaluate.space.log_prior(x)[0]):
            out = {Likelihood.key(st): math.nan for st in self.evaluate.stages}
            out["error"] = "outside the prior box"
            return out
        return self.evaluate(x)


@dataclass
class WhitenedLogPosterior:
    """Vectorised log posterior on u from GP means of z per stage (restricted
    to the u ``box`` and the prior)."""

    gps: dict
    space: ParameterSpace
    box: np.ndarray
    whitening: Whitening
    adjustment: CurvatureAdjustment | None = None

    def gp_points(self, U) -> np.ndarray:
        """Where the GPs are read for the parameters U: U itself, or the
        adjusted likelihood's argument."""
        U = np.atleast_2d(U)
        if self.adjustment is None:
            return U
        return self.whitening.to_u(self.adjustment(self.whitening.to_x(U)))

    def __call__(self, U):
        U = np.atleast_2d(U)
        lp = self.space.log_prior(self.whitening.to_x(U))
        G = self.gp_points(U)
        # the GPs are read where they were trained (the u box); the adjusted argument G
        # may lie a little outside the prior near a bound, where the GP is still smooth
        inside = np.all((G >= self.box[:, 0]) & (G <= self.box[:, 1]), axis=1) & np.isfinite(lp)
        out = np.full(len(U), -np.inf)
        if inside.any():
            z = {st: gp.predict_transformed(G[inside])[0] for st, gp in self.gps.items()}
            out[inside] = lp[inside] + Likelihood.log_likelihood_from_z(z)
        return out


# ------------------------------------------------------------------ MAP, box
@dataclass
class MapResult:
    x: np.ndarray
    value: float
    steps: np.ndarray
    covariance: np.ndarray
    n_evaluations: int
    mode: object = field(default=None, repr=False)


@dataclass
class _BaseMap:
    """Picklable ``x -> (model, parameters)`` of the baseline model."""

    space: ParameterSpace
    model: object

    def __call__(self, x):
        return self.model, self.space.to_parameters(x)


def find_map(evaluate: Evaluate, lik: Likelihood, x0, executor=None, max_evaluations: int = 600,
             progress: bool = False) -> MapResult:
    """MAP by least squares on the residual vectors (:mod:`bayes_update.mode`)
    and its Gauss-Newton Laplace covariance.

    Starts: ``x0`` and the two best of a 3 x 3 grid on the (c, k_s) band at
    x0's (eta, P_eff) (the low level pins eta and P_eff; along the band the
    nonlinear misfit can have more than one valley).  The uniform prior's
    density (K_b + k_s) / K_b in these coordinates varies by < 1 % over the
    posterior and is left out of the mode, kept in ``value``."""
    from .mode import ResidualFunction, find_mode

    space = evaluate.space
    stages = tuple(evaluate.stages)
    fun = ResidualFunction(evaluate.problem, stages, tuple(lik.scales[s].sd for s in stages),
                           _BaseMap(space, evaluate.problem.model))
    box = space.box()
    x0 = np.clip(np.asarray(x0, float), box[:, 0], box[:, 1])
    steps = 1e-4 * (box[:, 1] - box[:, 0])
    starts = [x0]
    grid = space.extra_starts(x0)
    if grid and len(stages) > 1:
        cost = [0.5 * float(np.sum(r ** 2)) for r in evaluate_many(fun, grid, executor, progress=False)]
        starts += [grid[i] for i in np.argsort(cost)[:2]]
    iterations = max(5, int(max_evaluations) // (len(starts) * (len(x0) + 1)))
    mode = find_mode(fun, starts, box[:, 0], box[:, 1], steps, executor, max_iterations=iterations)
    cov = mode.covariance(scale=box[:, 1] - box[:, 0])
    value = mode.cost - float(space.log_prior(mode.x)[0])
    return MapResult(x=mode.x, value=value, steps=np.sqrt(1.0 / np.diag(mode.precision).clip(1e-300)),
                     covariance=cov, n_evaluations=mode.n_evaluations + len(grid), mode=mode)


def capped_covariance(cov, space: ParameterSpace, box_sd: float) -> np.ndarray:
    """``cov`` with the prior's width added as information: precision
    cov^-1 + diag((box_sd / width)^2), so that box_sd sd is at most about the
    prior's width in any coordinate.  A direction the data hardly constrain
    (k_s along the band when the nonlinear level says little) would otherwise
    give a whitened box mostly outside the prior.  The cap is the whole width
    on either side (not half of it) so that a box centred anywhere in the
    prior still reaches both bounds: a cap at half the width cut 3 % of the
    default data set's posterior at the k_s bounds, however often the box
    was re-centred."""
    width = np.diff(space.box(), axis=1)[:, 0]
    P = np.linalg.inv(cov) + np.diag((box_sd / width) ** 2)
    return np.linalg.inv(P)


def local_box(space: ParameterSpace, x_map, cov, box_sd: float, free=()) -> np.ndarray:
    """MAP +- box_sd marginal sd, clipped to the prior's bounding box; the
    coordinates named in ``free`` span the prior."""
    prior = space.box()
    sd = np.sqrt(np.diag(cov))
    box = np.column_stack([x_map - box_sd * sd, x_map + box_sd * sd])
    box[:, 0] = np.maximum(box[:, 0], prior[:, 0])
    box[:, 1] = np.minimum(box[:, 1], prior[:, 1])
    for name in free:
        i = space.coordinate_names.index(name)
        box[i] = prior[i]
    return box


# -------------------------------------------------------------------- emcee
def run_emcee(log_prob, x_init, n_walkers: int, n_steps: int, seed, *, vectorize: bool,
              pool=None, progress: bool = True):
    """emcee's stretch move from ``x_init`` (n_walkers, d), seeded.

    A vectorised log probability (the GP surrogates) runs with one BLAS thread:
    its matrices are a few hundred wide at most, where threads cost more than
    they bring (on a loaded 2-core machine a 72-point GP's triangular solve for
    16 walkers took 5 ms with the default threads)."""
    import emcee
    from threadpoolctl import threadpool_limits

    sampler = emcee.EnsembleSampler(n_walkers, x_init.shape[1], log_prob, vectorize=vectorize, pool=pool)
    sampler.random_state = np.random.RandomState(np.random.SeedSequence(seed).generate_state(1)[0]).get_state()
    with threadpool_limits(1 if vectorize else None):
        sampler.run_mcmc(x_init, n_steps, progress=progress)
    return sampler


def initial_walkers(log_prob_vec, x_map, cov, n_walkers, seed, scale: float = 0.3) -> np.ndarray:
    """Walkers drawn from N(x_map, scale^2 cov), kept where the density is finite."""
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
    raise RuntimeError("could not place the MCMC walkers where the posterior is finite")


def to_inference_data(chain, log_prob, space, attrs: dict):
    """ArviZ InferenceData (chain = walker) of the space's reported variables
    (``space.report``: the beam's in SI with P_eff, a model's in its parameters' units)."""
    import arviz as az

    X = np.swapaxes(chain, 0, 1)                    # (walker, draw, d)
    values = space.report(X.reshape(-1, X.shape[-1]))
    post = {k: v.reshape(X.shape[:2]) for k, v in values.items()}
    idata = az.from_dict(posterior=post, sample_stats={"lp": np.swapaxes(log_prob, 0, 1)},
                         attrs={**attrs, **{f"units_{k}": u for k, u in space.report_units.items()}})
    return idata


def summarize(idata, space, hdi_prob: float = 0.94) -> dict:
    """Per variable: mean, sd, hdi_3%, hdi_97%, r_hat, ess_bulk, ess_tail (in
    ``space.report_units``) and, when ``space.display`` shows other units (the
    beam's paper units), the same in those under ``paper_units``."""
    import arviz as az

    s = az.summary(idata, hdi_prob=hdi_prob, round_to="none")
    lo, hi = f"hdi_{100 * (1 - hdi_prob) / 2:g}%", f"hdi_{100 * (1 + hdi_prob) / 2:g}%"
    out = {}
    # a space that shows other units than it reports in (the beam: SI vs paper units) shows all of them
    shown_apart = any(space.display[v] != (u, 1.0) for v, u in space.report_units.items())
    for var, unit in space.report_units.items():
        row = s.loc[var]
        out[var] = {"mean": float(row["mean"]), "sd": float(row["sd"]), "hdi_3%": float(row[lo]),
                    "hdi_97%": float(row[hi]), "r_hat": float(row["r_hat"]),
                    "ess_bulk": float(row["ess_bulk"]), "ess_tail": float(row["ess_tail"]),
                    "units": unit}
        shown, factor = space.display[var]
        if shown_apart:
            out[var]["paper_units"] = {"unit": shown, "mean": float(row["mean"]) / factor,
                                       "sd": float(row["sd"]) / factor, "hdi_3%": float(row[lo]) / factor,
                                       "hdi_97%": float(row[hi]) / factor}
    return out


# ------------------------------------------------------------------ results
@dataclass
class PosteriorResult:
    idata: object
    summary: dict
    likelihood: Likelihood
    space: ParameterSpace
    map: MapResult
    box: np.ndarray
    start: dict
    diagnostics: dict
    timing: dict
    n_model_runs: dict
    settings: PosteriorSettings
    direct: bool
    problem: UpdatingProblem = field(repr=False, default=None)
    surrogates: dict = field(repr=False, default_factory=dict)
    design: dict = field(repr=False, default_factory=dict)
    draws: np.ndarray = field(repr=False, default=None)     # flat internal-coordinate draws
    linear_only: dict = field(repr=False, default_factory=dict)
    predictive: dict = field(repr=False, default_factory=dict)
    sensitivity: dict = field(repr=False, default_factory=dict)
    n_model_runs_reused: dict = field(default_factory=dict)  # found in the cache instead of run

    def summary_json(self) -> dict:
        return {"parameters": self.summary, "map": dict(zip(self.space.coordinate_names, map(float, self.map.x))),
                "map_units": dict(self.space.units), "likelihood": self.likelihood.to_dict(),
                "prior": self.space.to_dict(),
                "laplace_box": dict(zip(self.space.coordinate_names, self.box.tolist())),
                "start": self.start, "diagnostics": self.diagnostics, "direct": self.direct,
                "settings": asdict(self.settings),
                "linear_only": {k: v for k, v in self.linear_only.items() if not k.startswith("_")},
                "surrogate_check": {k: v for k, v in self.predictive.items() if not k.startswith("_")},
                "sensitivity": self.sensitivity}

    def run_json(self) -> dict:
        """How the run went (not what it found): wall time per step [s] and model
        runs per step, which a resumed run or another machine changes while the
        posterior stays the same."""
        return {"timing_s": self.timing, "n_model_runs": self.n_model_runs,
                "n_model_runs_reused": self.n_model_runs_reused}


class _XSampler:
    """An emcee sampler run in u, read in x (chains, log probabilities, tau)."""

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
        return emcee.autocorr.integrated_time(self.get_chain(discard=kw.get("discard", 0)), quiet=True)


def _box_cut_fraction(U, box_sd: float, whitening: Whitening, space: ParameterSpace) -> float:
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


def _chain_diagnostics(sampler, burn: int, names) -> dict:
    chain = sampler.get_chain(discard=burn)
    tau = sampler.get_autocorr_time(discard=burn, quiet=True)
    return {"autocorr_time_steps": dict(zip(names, map(float, tau))),
            "acceptance_fraction": float(np.mean(sampler.acceptance_fraction)),
            "n_draws": int(chain.shape[0] * chain.shape[1])}


def sample(dataset: Dataset, model=None, settings: PosteriorSettings | None = None, *,
           executor: Executor | None = None, workers: int | None = None, direct: bool = False,
           start=None, space=None, likelihood: Likelihood | None = None, cache_dir=None,
           metrics: str | None = None, progress: bool = True, log=print) -> PosteriorResult:
    """Sample the posterior of a model's parameters given ``dataset`` (module docstring).

    model : the updating model: any model of the contract
        (:mod:`bayes_update.core.model`: declared ``parameters`` and
        ``simulate(theta, force, fs)``), or the beam (``fe.BeamModel``, the
        default, or ``fe.ModalROM``; parameters eta, c, F, k_s).
    space : the prior (default: the model's declared parameters; the beam's
        :class:`ParameterSpace` box of DESIGN.md).
    direct : run emcee on the model itself (no surrogate); sensible with a
        model of a few ms per run (``fe.ModalROM``: about 2 ms per evaluation).
    start : skip the start search and begin at these parameters (theta, or
        ``fe.Parameters`` for the beam).
    likelihood : use these scales instead of measuring them at the start
        (e.g. to compare a direct and a surrogate posterior under one likelihood).
    cache_dir : folder of the netCDF evaluation cache (an interrupted run resumes).
    metrics : the metric set, ``"paper"`` or ``"full"`` (:mod:`bayes_update.core.problem`;
        default ``full`` for a model of the contract, ``paper`` for the beam).
    """
    settings = settings or PosteriorSettings()
    problem, space = make_problem(dataset, model, space, metrics)
    if "nonlinear" not in problem.stages:
        raise ValueError(f"{problem.source}: the posterior needs a test with role 'nonlinear' "
                         "(the high-level chirp) as well as the 'linear' one")
    stages = problem.stages
    timing, runs, reused = {}, {}, {}
    t_all = time.perf_counter()
    own_pool = executor is None and (workers or 2) > 1
    pool = default_executor(workers) if own_pool else executor
    try:
        return _sample(dataset, problem, space, settings, pool, direct, start, likelihood, cache_dir, progress,
                       log, stages, timing, runs, reused, t_all)
    finally:
        if own_pool:
            pool.shutdown()


def make_problem(dataset: Dataset, model=None, space=None, metrics=None):
    """(problem, space) for ``model`` on ``dataset``: a model of the contract
    (declared ``parameters``; checked with one run here, before any heavy work)
    gets a :class:`bayes_update.core.Problem` and its :class:`ParameterSet`; the
    beam (``fe.BeamModel`` or ``fe.ModalROM``, the default) gets
    :class:`UpdatingProblem` and the (eta, c, P_eff, k_s) :class:`ParameterSpace`.

    metrics : the metric set (default: ``full`` for a model of the contract,
        ``paper`` for the beam).  Under ``full`` the linear test's J1 follows
        the parameters it moves (:func:`bayes_update.core.calibrate.screen_linear`,
        d + 1 runs of the linear test)."""
    if model is not None and hasattr(model, "parameters"):
        from .core.calibrate import problem_for

        checked = check_model(model, dataset.by_role("linear")[0].force if dataset.by_role("linear")
                              else dataset.tests[0].force, dataset.sampling_rate_hz)
        space = space if space is not None else checked
        return problem_for(dataset, model, space, metrics)[0], space
    model = model if model is not None else fe.BeamModel(rig=rig_of(dataset))
    return UpdatingProblem(dataset, model, metrics=metrics), space if space is not None else ParameterSpace(rig_of(dataset))


def default_start(dataset, problem, space, pool, n_points: int, seed, progress, log):
    """(start point, model runs): the beam's is the paper's deterministic updating
    on coarse grids; any other model's the generic two-stage calibration
    (:mod:`bayes_update.core.calibrate`) on the problem as built."""
    if isinstance(problem, UpdatingProblem):
        from .calibrate import CalibrationSettings, calibrate

        log("start: the deterministic two-stage updating on coarse grids")
        cal = calibrate(dataset, problem.model, CalibrationSettings.quick(), executor=pool,
                        progress=progress, log=lambda *a: None)
        return cal.final_params, cal.setup["n_model_runs"]
    from .core.calibrate import screen_linear, two_stage

    log(f"start: the two-stage calibration (Sobol' designs of {n_points} points, then least squares)")
    names, _, runs = screen_linear(problem, space, pool)
    found = two_stage(problem, space, names, n_start=n_points, seed=seed, executor=pool, progress=progress)
    return space.to_parameters(found.x), runs + found.n_model_runs


def _sample(dataset, problem, space, settings, pool, direct, start, likelihood, cache_dir, progress, log,
            stages, timing, runs, reused, t_all):
    seeds = np.random.SeedSequence(settings.seed).spawn(8)
    seed_of = [int(s.generate_state(1)[0]) for s in seeds]
    # 1. start ---------------------------------------------------------------
    t0 = time.perf_counter()
    if start is None:
        start, runs["start"] = default_start(dataset, problem, space, pool, settings.n_start, seed_of[7],
                                             progress, log)
    else:
        space.check(start, "start")
        runs["start"] = 0
    start_info = space.describe(start)
    if not space.contains(start):
        start = space.to_parameters(np.clip(space.to_internal(start), space.box()[:, 0], space.box()[:, 1]))
    timing["start"] = time.perf_counter() - t0
    # 2. likelihood scales ------------------------------------------------------
    t0 = time.perf_counter()
    if likelihood is None:
        lik = estimate_likelihood(problem, start, model_error=settings.model_error,
                                  n_replicates=settings.n_replicates, seed=seed_of[0], space=space)
        # replicates, the estimate, the refined model, 8 runs for the sensitivity span
        runs["likelihood_scales"] = len(stages) * (settings.n_replicates + 9 + int(settings.model_error))
    else:
        if set(likelihood.stages) != set(stages):
            raise ValueError(f"the likelihood covers stages {likelihood.stages}, the data {stages}")
        lik = likelihood
        runs["likelihood_scales"] = 0
    timing["likelihood_scales"] = time.perf_counter() - t0
    for st, sc in lik.scales.items():
        log(f"likelihood {st}: noise sd {100 * sc.noise_sd:.3f} % per direction of the parameters' span "
            f"({sc.span_rank}), model error "
            f"{100 * sc.model_error:.3f} %, s = {100 * sc.sd:.3f} %")
    # 3. MAP and local box --------------------------------------------------------
    t0 = time.perf_counter()
    ev = Evaluate(problem, space, stages)
    mp = find_map(ev, lik, space.to_internal(start), pool, settings.map_max_evaluations, progress=False)
    box = local_box(space, mp.x, mp.covariance, settings.box_sd)
    runs["map_laplace"] = len(stages) * mp.n_evaluations
    timing["map_laplace"] = time.perf_counter() - t0
    log("MAP: " + ", ".join(f"{n} = {v:.4g} {space.units[n]}" for n, v in zip(space.coordinate_names, mp.x))
        + "; Laplace sd: " + ", ".join(f"{v:.3g}" for v in np.sqrt(np.diag(mp.covariance))))
    adj = None
    if settings.curvature_adjustment and mp.mode is not None:
        adj = curvature_adjustment(lik, mp.mode.jacobian, mp.x, np.diff(space.box(), axis=1)[:, 0], stages,
                                   names=space.coordinate_names)
        if adj is not None:
            log("curvature adjustment: noise variance / likelihood's along the parameters' directions "
                + ", ".join(f"{v:.2f}" for v in adj.variance_ratios) + "; sd x "
                + ", ".join(f"{n} {v:.2f}" for n, v in zip(space.coordinate_names, adj.sd_ratios)))
    result = dict(design={}, surrogates={})
    # 4-5. sampling -----------------------------------------------------------------
    if direct:
        t0 = time.perf_counter()
        logp = DirectLogPosterior(ev, lik, adj)
        x_init = initial_walkers(lambda X: np.array([logp(x) for x in X]), mp.x, mp.covariance,
                                 settings.n_walkers, seed_of[1])
        sampler = run_emcee(logp, x_init, settings.n_walkers, settings.direct_steps, seed_of[2],
                            vectorize=False, pool=_ExecutorPool(pool) if pool is not None else None,
                            progress=progress)
        runs["mcmc"] = len(stages) * settings.n_walkers * settings.direct_steps
        timing["mcmc"] = time.perf_counter() - t0
        gps = {}
    else:
        t0 = time.perf_counter()
        whitening = Whitening.from_covariance(mp.x, capped_covariance(mp.covariance, space, settings.box_sd))
        ubox = np.array([[-settings.box_sd, settings.box_sd]] * len(space.coordinate_names), float)
        timing["gp_fit"], timing["mcmc"], runs["design"] = 0.0, 0.0, 0
        for attempt in range(settings.box_attempts):
            t0 = time.perf_counter()
            gps, U, Y, fit_time = _build_surrogates(WhitenedEvaluate(ev, whitening), lik, space, ubox, whitening,
                                                    settings, pool, cache_dir, stages, seed_of[3] + attempt,
                                                    progress, log, reused)
            runs["design"] += len(stages) * int(np.sum(np.all(np.isfinite(Y), axis=1)))
            timing["design_and_gp"] = timing.get("design_and_gp", 0.0) + time.perf_counter() - t0
            timing["gp_fit"] += fit_time
            result["design"] = {"X": whitening.to_x(U), "z": Y, "whitening": whitening}
            t0 = time.perf_counter()
            logp_u = WhitenedLogPosterior(gps, space, ubox, whitening, adj)
            u_init = initial_walkers(logp_u, np.zeros(len(space.coordinate_names)), np.eye(len(space.coordinate_names)), settings.n_walkers,
                                     seed_of[1])
            sampler = run_emcee(logp_u, u_init, settings.n_walkers, settings.n_steps, seed_of[2],
                                vectorize=True, progress=progress)
            timing["mcmc"] += time.perf_counter() - t0
            u_draws = sampler.get_chain(discard=settings.burn, flat=True)
            cut = _box_cut_fraction(logp_u.gp_points(u_draws), settings.box_sd, whitening, space)
            if cut <= 0.01 or attempt == settings.box_attempts - 1:
                break
            # the Laplace box cut the posterior (a non-Gaussian posterior, or a
            # MAP short of the mode): re-centre and re-whiten on the surrogate
            # posterior's draws, 3x wider (they are truncated by the old box)
            x_draws = whitening.to_x(u_draws)
            log(f"the local box cut {100 * cut:.1f} % of the draws: re-centred on them, 3x wider "
                f"(attempt {attempt + 2} of {settings.box_attempts})")
            whitening = Whitening.from_covariance(x_draws.mean(axis=0),
                                                  capped_covariance(9.0 * np.cov(x_draws.T), space,
                                                                    settings.box_sd))
        diag_attempts = attempt + 1
        sampler = _XSampler(sampler, whitening)
    burn = settings.direct_burn if direct else settings.burn
    thin = 1 if direct else settings.thin
    diag = _chain_diagnostics(sampler, burn, space.coordinate_names)
    if isinstance(sampler, _XSampler):
        diag["box_cut_fraction"] = _box_cut_fraction(
            logp_u.gp_points(sampler.sampler.get_chain(discard=burn, flat=True)), settings.box_sd,
            sampler.whitening, space)
    diag["thin"] = thin
    diag["curvature_adjustment"] = adj.to_dict() if adj is not None else None
    if not direct:
        diag["box_attempts"] = diag_attempts
    chain = sampler.get_chain(discard=burn, thin=thin)
    lp = sampler.get_log_prob(discard=burn, thin=thin)
    idata = to_inference_data(chain, lp, space, {"source": str(problem.source), "direct": int(direct),
                                                  "model": type(problem.model).__name__})
    summary = summarize(idata, space)
    diag["max_r_hat"] = max(v["r_hat"] for v in summary.values())
    diag["min_ess_bulk"] = min(v["ess_bulk"] for v in summary.values())
    if diag.get("box_cut_fraction", 0.0) > 1e-2:
        warnings.warn(f"after {diag['box_attempts']} boxes the surrogate's box still cuts "
                      f"{100 * diag['box_cut_fraction']:.2f} % of the draws: the posterior is wider than the "
                      "Laplace approximation says; raise box_sd or box_attempts", RuntimeWarning)
    flat = chain.reshape(-1, chain.shape[-1])
    res = PosteriorResult(idata=idata, summary=summary, likelihood=lik, space=space, map=mp, box=box,
                          start=start_info, diagnostics=diag, timing=timing, n_model_runs=runs,
                          n_model_runs_reused=reused,
                          settings=settings, direct=direct, problem=problem, surrogates=gps,
                          design=result["design"], draws=flat)
    # extras: linear-only posterior, predictive check, sensitivity ----------------------------
    if settings.n_predictive:
        t0 = time.perf_counter()
        res.predictive = posterior_predictive(res, settings.n_predictive, pool, seed_of[4], progress)
        runs["predictive"] = len(stages) * settings.n_predictive
        timing["predictive"] = time.perf_counter() - t0
    if settings.n_linear and not direct and getattr(space, "has_ridge", False):
        t0 = time.perf_counter()
        res.linear_only = linear_only_posterior(res, pool, seed_of[5], cache_dir, progress, log, reused)
        runs["linear_only"] = res.linear_only["n_model_runs"]
        timing["linear_only"] = time.perf_counter() - t0
    if settings.n_global:
        t0 = time.perf_counter()
        from .sensitivity import sobol_indices
        res.sensitivity = sobol_indices(problem, space, settings.n_global, settings.sobol_n, pool, seed_of[6],
                                        progress)
        runs["sensitivity"] = len(stages) * settings.n_global
        timing["sensitivity"] = time.perf_counter() - t0
    timing["total"] = time.perf_counter() - t_all
    runs["total"] = int(sum(v for k, v in runs.items() if k != "total"))
    return res


def _gp_factory(box, seed, names):
    return surrogates.GPSurrogate(box, transform="none", names=list(names), n_restarts_optimizer=2, seed=seed)


def _build_surrogates(ev: WhitenedEvaluate, lik, space, box, whitening, settings, pool, cache_dir, stages, seed,
                      progress, log, reused=None):
    """Design in the whitened box (inside the prior), GPs of z per stage,
    refinement rounds; all in u coordinates."""
    from threadpoolctl import threadpool_limits

    ss = np.random.SeedSequence(seed).spawn(3)
    # a Sobol' design of the u box, keeping the points inside the prior
    # (near a corner of the prior most of the box is outside: draw more)
    for factor in (8, 64, 512):
        cand = surrogates.design(box, factor * settings.n_initial, "sobol", seed=int(ss[0].generate_state(1)[0]))
        inside = np.isfinite(space.log_prior(whitening.to_x(cand)))
        if inside.sum() >= settings.n_initial:
            break
    else:
        raise RuntimeError(f"only {inside.sum()} of {len(cand)} design candidates fall inside the prior box")
    U0 = cand[inside][:settings.n_initial]
    cache = _cache(cache_dir, ev.evaluate, "design", whitening, reused)
    evaluate = partial(surrogates.cached_evaluate, cache=cache) if cache is not None else evaluate_many
    res = evaluate(ev, list(U0), executor=pool, progress=progress)

    def target(r):
        return [float(lik.to_z(st, r[Likelihood.key(st)])) for st in stages]

    Y0 = np.array([target(r) for r in res])

    def weight(surs):
        return WhitenedLogPosterior(dict(zip(stages, surs)), space, box, whitening)

    def candidates(surs, rng):
        # draws of a short MCMC on the current surrogate posterior, plus Sobol' points
        logp = weight(surs)
        init = initial_walkers(logp, np.zeros(len(box)), np.eye(len(box)), 16, int(rng.integers(2 ** 31)))
        smp = run_emcee(logp, init, 16, 400, int(rng.integers(2 ** 31)), vectorize=True, progress=False)
        draws = smp.get_chain(discard=200, thin=2, flat=True)
        sob = surrogates.design(box, 512, "sobol", seed=int(rng.integers(2 ** 31)))
        return np.vstack([draws, sob])

    def factory():
        return _gp_factory(box, seed=0, names=space.coordinate_names)

    with threadpool_limits(2):
        t = time.perf_counter()
        ref = surrogates.refine(ev, factory, U0, Y0, weight, settings.n_rounds, settings.batch, pool,
                                seed=int(ss[1].generate_state(1)[0]), candidates=candidates, target=target,
                                log_weight=True, evaluate=evaluate, progress=progress)
        t_fit = time.perf_counter() - t
    gps = dict(zip(stages, ref.surrogate))
    for st, gp in gps.items():
        log(f"GP of z_{st}: {int(np.isfinite(ref.y[:, 0]).sum())} runs; " + gp.summary().splitlines()[0])
    return gps, ref.X, ref.y, t_fit


def _cache(cache_dir, ev: Evaluate, name: str, whitening: Whitening | None = None, reused: dict | None = None):
    """The evaluation cache of ``name`` under ``cache_dir`` (None: no cache); ``reused``
    counts the model runs its entries on disk save, per name."""
    if cache_dir is None:
        return None
    from pathlib import Path

    from .metrics import describe_basis
    config = {"what": name, "stages": list(ev.stages), "model": ev.problem.describe()["model"],
              "basis": describe_basis(ev.problem.basis), "metric_set": ev.problem.metrics,
              "data": ev.problem.data_fingerprint,
              "rig": ev.problem.rig.to_dict() if ev.problem.rig is not None else None,
              "coordinates": list(ev.space.coordinate_names)}
    if whitening is not None:     # points are stored in the whitened coordinates
        config["whitening"] = {"center": whitening.center.tolist(), "L": whitening.L.tolist()}
    path = Path(cache_dir)
    path.mkdir(parents=True, exist_ok=True)
    cache = surrogates.EvaluationCache(path / name, config)
    if reused is not None:
        reused[name] = reused.get(name, 0) + cache.n_loaded * len(ev.stages)
    return cache


# ---------------------------------------------------------------- extras
@dataclass
class _Predict:
    problem: UpdatingProblem
    space: ParameterSpace

    def __call__(self, x):
        p = self.space.to_parameters(np.asarray(x, float))
        out = {}
        for st in self.problem.stages:
            try:
                v = self.problem.simulate(p, st)
            except self.problem.failures:
                return None
            out[st] = self.problem.output(st, self.problem.components(st, v))
            out[Likelihood.key(st)] = self.problem.metric(st, v)
        return out


def posterior_predictive(res: PosteriorResult, n: int, pool, seed, progress) -> dict:
    """FE runs at ``n`` posterior draws: bands of y1 (linear test) and y2 + y3
    (nonlinear test), and the surrogate's metrics against the model's there."""
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(res.draws), size=min(n, len(res.draws)), replace=False)
    X = res.draws[idx]
    out = evaluate_many(_Predict(res.problem, res.space), list(X), pool, progress=progress,
                        desc="posterior predictive")
    ok = [i for i, o in enumerate(out) if o is not None]
    pred = {"n_draws": len(X), "n_failed": len(X) - len(ok)}
    bands = {}
    for st in res.problem.stages:
        Y = np.array([out[i][st] for i in ok])
        ref = res.problem.reference_components(st)
        bands[st] = {"low": np.percentile(Y, 5, axis=0), "high": np.percentile(Y, 95, axis=0),
                     "median": np.median(Y, axis=0), "reference": res.problem.output(st, ref)}
        e_model = np.array([out[i][Likelihood.key(st)] for i in ok])
        pred[f"{Likelihood.key(st)}_model_median"] = float(np.median(e_model))
        if res.surrogates:
            z = res.surrogates[st].predict_transformed(res.design["whitening"].to_u(X[ok]))[0]
            e_gp = res.likelihood.from_z(st, z)
            rel = np.abs(e_gp - e_model) / e_model
            pred[f"{Likelihood.key(st)}_gp_median_rel_error"] = float(np.median(rel))
            pred[f"{Likelihood.key(st)}_gp_max_rel_error"] = float(np.max(rel))
            pred[f"_{st}_pairs"] = (e_model, e_gp)
    pred["_bands"] = bands
    return pred


def linear_only_posterior(res: PosteriorResult, pool, seed, cache_dir, progress, log, reused=None) -> dict:
    """The posterior from the low-level test alone: (F, k_s) on a ridge of
    constant P_eff, c unidentified.  Its own design (c and k_s over the
    prior), GP of z_lin and emcee."""
    s = res.settings
    lik = res.likelihood.restricted(("linear",))
    ev = Evaluate(res.problem, res.space, ("linear",))
    sd = np.sqrt(np.diag(res.map.covariance))
    box = local_box(res.space, res.map.x, res.map.covariance, s.box_sd, free=("c", "k_s"))
    # the high level pins eta and P_eff: widen them for the low level alone
    for i in (0, 2):
        box[i] = [max(res.map.x[i] - 3 * s.box_sd * sd[i], res.space.box()[i, 0]),
                  min(res.map.x[i] + 3 * s.box_sd * sd[i], res.space.box()[i, 1])]
    ss = np.random.SeedSequence(seed).spawn(3)
    X = surrogates.design(box, s.n_linear, "sobol", seed=int(ss[0].generate_state(1)[0]))
    cache = _cache(cache_dir, ev, "linear_only", reused=reused)
    evaluate = partial(surrogates.cached_evaluate, cache=cache) if cache is not None else evaluate_many
    r = evaluate(ev, list(X), executor=pool, progress=progress)
    y = np.array([float(lik.to_z("linear", q["e_lin"])) for q in r])

    def weight(sur):
        return SurrogateLogPosterior({"linear": sur}, res.space, box)

    ref = surrogates.refine(ev, lambda: _gp_factory(box, 0, res.space.coordinate_names), X, y, weight, 1, max(8, s.n_linear // 4), pool,
                            seed=int(ss[1].generate_state(1)[0]), candidates=2048,
                            target=lambda q: float(lik.to_z("linear", q["e_lin"])), log_weight=True,
                            evaluate=evaluate, progress=progress)
    logp = SurrogateLogPosterior({"linear": ref.surrogate}, res.space, box)
    init = initial_walkers(logp, res.map.x, np.diag(((box[:, 1] - box[:, 0]) / 20) ** 2), s.n_walkers,
                           int(ss[2].generate_state(1)[0]))
    smp = run_emcee(logp, init, s.n_walkers, s.n_steps, int(ss[2].generate_state(2)[1]), vectorize=True,
                    progress=progress)
    draws = smp.get_chain(discard=s.burn, thin=s.thin, flat=True)
    F = res.space.F_of(draws)
    corr = float(np.corrcoef(F, draws[:, 3])[0, 1])
    full = res.draws
    out = {"n_model_runs": len(ref.X), "corr_F_k_s": corr,
           "sd": {"eta": float(draws[:, 0].std()), "c": float(draws[:, 1].std()),
                  "P_eff": float(draws[:, 2].std()), "k_s": float(draws[:, 3].std()), "F": float(F.std())},
           "sd_full": {"eta": float(full[:, 0].std()), "c": float(full[:, 1].std()),
                       "P_eff": float(full[:, 2].std()), "k_s": float(full[:, 3].std()),
                       "F": float(res.space.F_of(full).std())},
           "units": dict(UNITS), "_draws": draws}
    out["narrowing"] = {k: out["sd"][k] / out["sd_full"][k] for k in ("c", "k_s")}
    # the high level leaves a band in (c, k_s), not a point: the joint spread
    # (sqrt of the determinant of the covariance) says how much it removes
    det = [np.sqrt(np.linalg.det(np.cov(D[:, [1, 3]].T))) for D in (draws, full)]
    out["narrowing"]["c_k_s_area"] = float(det[0] / det[1])
    log(f"linear-only posterior: corr(F, k_s) = {corr:.3f}; adding the high level narrows c "
        f"{out['narrowing']['c']:.1f}x, k_s {out['narrowing']['k_s']:.1f}x (sd ratio), the (c, k_s) "
        f"area {out['narrowing']['c_k_s_area']:.1f}x")
    return out


def write_posterior(res: PosteriorResult, out, truth: dict | None = None, figures: bool = True):
    """``posterior.nc`` (ArviZ), ``posterior_summary.json`` (what was found: the
    same seed and data give the same bytes), ``run.json`` (wall times and model
    runs) and the figures (PNG) in folder ``out``; ``truth`` (paper units) only
    marks the plots."""
    import json
    from pathlib import Path

    from .posterior_plots import posterior_figures

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    res.idata.to_netcdf(str(out / "posterior.nc"))
    (out / "posterior_summary.json").write_text(json.dumps(res.summary_json(), indent=1, default=float))
    (out / "run.json").write_text(json.dumps(res.run_json(), indent=1, default=float))
    if figures:
        for name, fig in posterior_figures(res, truth).items():
            fig.savefig(out / f"{name}.png", dpi=110)
    return out


def format_summary(res: PosteriorResult) -> str:
    """Markdown table of the posterior (the beam's in paper units)."""
    lines = ["| parameter | mean | sd | 94 % HDI | R-hat | bulk ESS |", "|---|---|---|---|---|---|"]
    for var, v in res.summary.items():
        p = v.get("paper_units", {**v, "unit": v["units"]})
        lines.append(f"| {var} [{p['unit']}] | {p['mean']:.5g} | {p['sd']:.3g} | "
                     f"{p['hdi_3%']:.5g} - {p['hdi_97%']:.5g} | {v['r_hat']:.4f} | {v['ess_bulk']:.0f} |")
    return "\n".join(lines)
