"""The sizes of every step of :func:`bayes_update.core.posterior.sample`."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PosteriorSettings:
    """Sizes of every step (model runs are counted per test)."""

    # The defaults are sized for expensive models: some 220-310 model runs per posterior of
    # four parameters (docs/posterior.md); an SBC of 28 truths (benchmarks/sbc.py --budget budget)
    # covered as the former sizes on the same truths, with sds 8-15 % narrower.  thorough()
    # gives the former, four to five times costlier sizes (the reference for the defaults).
    #
    # noise replicates for the likelihood scales and the curvature adjustment's noise covariance:
    # at 24 the sandwich from the replicates was itself too noisy (50 SBC truths: the truth beyond
    # the 90 % chi^2_4 point in 14 %, at 96 in 8 %; benchmarks/sbc_linearised.py).  With
    # model_replicates = k their force noise's response comes from a linear time-invariant estimate
    # of the model (one run), corrected by k replicates run on the model (likelihood.estimate_likelihood;
    # None: every replicate a model run)
    n_replicates: int = 96
    model_replicates: int | None = 16
    n_initial: int = 0  # Sobol' points in the local box (0: 4 per parameter, at least 8; with the
    #                             Gauss-Newton mean 6 per parameter bought nothing on the Duffing: 177 runs, 0.017 sd,
    #                             overlap 0.972, KS 0.020 against a 768 000-run chain, where 6 took 189 runs)
    n_rounds: int = 12  # refinement rounds (at most, with stop_tolerance)
    batch: int = 0  # points per round (0: 2 per parameter)
    stop_tolerance: float = 0.1  # > 0: the design stops when the surrogate posterior's means move less than
    #                             this many sd and its sds less than this share, twice in a row, or once
    #                             by a tenth of it (design._Stability; 0: all rounds)
    box_sd: float = 4.0  # half-width of the local box [Laplace marginal sd]
    # the GPs' prior mean: "gauss_newton", each stage's z as the MAP's residual and Jacobian
    # predict it (design.GaussNewtonMean; the GP models the rest), or "constant"
    gp_mean: str = "gauss_newton"
    # the chain on the surrogates: its cost is per step (the walkers of a step are one vectorised
    # call), so more walkers and fewer steps.  On the ROM's surrogate posterior, against a 256 x 20000
    # chain (benchmarks/chain_geometry.py): 64 x 6000 and 128 x 3000 and 256 x 1500 sample it alike
    # (mean shifts 0.01-0.04 sd, KS at the comparison's floor) in 13, 10 and 6 s; ArviZ's R-hat,
    # which takes every walker for a chain, reads 1.012-1.014, 1.019-1.022 and 1.047-1.056 (shorter
    # chains, not worse draws): 128 x 3000 keeps it near 1.02
    n_walkers: int = 128
    n_steps: int = 3000  # on the surrogate; direct runs use direct_walkers x direct_steps
    burn: int = 500  # at least; a third of the chain is discarded (mcmc.kept_slice)
    thin: int = 5  # kept draws: every thin-th step after burn-in (at least; at most 8000 kept)
    # the chain is extended by n_steps at a time until every reported variable has R-hat < 1.01 and
    # bulk and tail ESS >= 400 (mcmc.run_to_convergence), up to max_steps (a warning says when not):
    # on the surrogates a step costs no model run, on the direct path every walker's step does; a
    # curved ridge (benchmarks/ridge_frame.py --top-only) needed 21000 steps (R-hat 1.0155 at 15000)
    max_steps: int = 30000
    direct_walkers: int = 64  # the direct path: every walker's step is a model run per test
    direct_steps: int = 3000
    direct_burn: int = 1000
    direct_max_steps: int = 6000
    box_attempts: int = 3  # re-centred, wider boxes when the first cuts the posterior
    n_linear: int = 64  # design of the linear-only posterior (0: skip it)
    n_global: int = 0  # global design for the sensitivity indices (opt-in: 128 is a good size)
    sobol_n: int = 1024  # SALib base sample size
    n_predictive: int = 0  # model runs at posterior draws: bands and surrogate check (opt-in: 32)
    model_error: bool = True  # add the measured model error to the likelihood
    curvature_adjustment: bool = True  # sandwich-adjust the likelihood's curvature (adjustment.curvature_adjustment)
    map_max_evaluations: int = 600
    n_start: int = 16  # Sobol' points of the start search (models without a start hook)
    coarse_start: bool = True  # the start a search goes on from (the beam: eta and P_eff only; others: no polish)
    frugal_map: bool = True  # the MAP from the start alone, its model's other starts only where they beat it
    seed: int = 0

    def __post_init__(self):
        if self.model_replicates is not None and (
            isinstance(self.model_replicates, bool)
            or int(self.model_replicates) != self.model_replicates
            or self.model_replicates < 4
        ):
            raise ValueError(f"model_replicates must be None or an integer >= 4, got {self.model_replicates!r}")
        if self.gp_mean not in ("gauss_newton", "constant"):
            raise ValueError(f"gp_mean must be 'gauss_newton' or 'constant', got {self.gp_mean!r}")
        if not self.stop_tolerance >= 0:
            raise ValueError(f"stop_tolerance must be >= 0, got {self.stop_tolerance!r}")
        for name in (
            "n_replicates",
            "n_initial",
            "n_rounds",
            "batch",
            "n_walkers",
            "direct_walkers",
            "n_steps",
            "burn",
            "thin",
            "direct_steps",
            "direct_burn",
            "box_attempts",
            "max_steps",
            "direct_max_steps",
            "n_linear",
            "n_global",
            "sobol_n",
            "n_predictive",
            "map_max_evaluations",
            "n_start",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < 0:
                raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
        if (
            min(self.n_walkers, self.direct_walkers) < 8
            or self.n_steps <= self.burn
            or self.direct_steps <= self.direct_burn
        ):
            raise ValueError("need n_walkers and direct_walkers >= 8, n_steps > burn and direct_steps > direct_burn")
        if self.max_steps < self.n_steps or self.direct_max_steps < self.direct_steps:
            raise ValueError("max_steps must be >= n_steps and direct_max_steps >= direct_steps")
        if self.thin < 1 or self.box_attempts < 1:
            raise ValueError("thin and box_attempts must be >= 1")
        if 0 < self.n_initial < 8:
            raise ValueError("n_initial must be 0 (4 per parameter, at least 8) or at least 8")
        if not self.box_sd > 1:
            raise ValueError("box_sd must be > 1")

    @classmethod
    def thorough(cls, **kw) -> "PosteriorSettings":
        """The former default sizes, some 1200-1400 model runs: every noise replicate
        a model run, the full two-stage start, the MAP from every start the model
        offers, a 96 + 5 x 32 design, 32 x 12000 steps (the reference the defaults
        were measured against in ``benchmarks/runs_per_posterior.py``)."""
        return cls(**{**THOROUGH, **kw})

    @classmethod
    def budget(cls, **kw) -> "PosteriorSettings":
        """The default sizes (the name of a release in which they were opt-in)."""
        return cls(**kw)

    @classmethod
    def quick(cls, **kw) -> "PosteriorSettings":
        """The default pipeline at small sizes, for tests and a first look on a cheap model:
        the same steps (the coarse start, the frugal MAP, the Gauss-Newton GP mean, the
        design's stopping rule, model-run replicates corrected by an LTI estimate) with
        fewer noise replicates (24, 8 of them model runs), a smaller linear-only design,
        fewer walkers and steps.  The opt-in steps (global sensitivity, predictive runs)
        stay off, as in the defaults."""
        base = dict(QUICK_SIZES, **kw)
        # a longer chain asked for keeps room to extend it (the caps follow unless given)
        base["max_steps"] = kw.get("max_steps", max(base["max_steps"], base["n_steps"]))
        base["direct_max_steps"] = kw.get("direct_max_steps", max(base["direct_max_steps"], base["direct_steps"]))
        return cls(**base)


#: the sizes :meth:`PosteriorSettings.quick` changes (``--quick``): sizes only, no step on or off
QUICK_SIZES = dict(
    n_replicates=24,
    model_replicates=8,
    n_linear=32,
    n_walkers=32,
    n_steps=2000,
    burn=500,
    max_steps=8000,
    direct_walkers=24,
    direct_steps=1000,
    direct_burn=400,
    direct_max_steps=2000,
    sobol_n=256,
    map_max_evaluations=250,
)


#: the sizes of :meth:`PosteriorSettings.thorough` (``bayes-update sample --thorough``)
THOROUGH = dict(
    model_replicates=None,
    n_initial=96,
    n_rounds=5,
    batch=32,
    stop_tolerance=0.0,
    n_walkers=32,
    direct_walkers=32,
    n_steps=12000,
    burn=2000,
    thin=10,
    max_steps=48000,
    n_start=64,
    coarse_start=False,
    frugal_map=False,
    gp_mean="constant",
)
