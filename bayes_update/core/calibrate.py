"""Deterministic two-stage calibration of any model of the contract.

The paper's idea (first the linear parameters from the linear test, then the
nonlinear ones from both tests) in a form that needs nothing of the model but
its declared parameters:

1. **screen**: which parameters move the linear test's compared output y1?
   One forward step of 5 % of each prior range from the prior's centre; a
   parameter whose step moves y1 by at least 5 % of the largest move is a
   *linear parameter*.  Under the ``full`` metric set the linear test's
   J1 then follows their number (:func:`linear_n_functions`: y1 has more
   coefficients than there are parameters to identify).
2. **stage 1**: e_lin over the linear parameters (the others at their prior
   centre), by least squares from the best points of a Sobol' design over
   the prior.
3. **stage 2**: every parameter free, from the stage-1 point and the best
   points of a Sobol' design over the other parameters (the linear ones at
   their stage-1 values, as the paper's second grid).  Stage 2 must free the linear parameters too:
   on a measured record the damping the high-level test needs was 2.5 %
   above the low-level one, and a fit that froze it at stage 1 predicted
   held-out data with 2.4x the error of a joint fit.  The objective is
   ``sum_stage ||r_stage||^2 / s_stage^2``: under ``full`` s is the test's
   measured noise (:meth:`Problem.noise_sd`), so the tests weigh by their
   information, not by their energy; under ``paper`` s = ||reference||,
   i.e. e_lin^2 + e_nlin^2.
4. **identifiability**: at each stage's end, the directions of the
   parameters (in prior-range units) along which the data's chi-square
   changes by less than 4 over a whole prior range (the Gauss-Newton
   posterior sd along them exceeds half the range) are reported as
   *unidentified*, with their loadings, instead of returning an arbitrary
   point of a valley without a word.
5. **uncertainty** (``uncertainty=True``): each parameter's sd from steps 2-3
   of ``sample`` at the calibrated point
   (:func:`bayes_update.core.posterior.laplace_steps.laplace_at`: the noise
   replicates with the force's noise, the model error against ``refined()``,
   the Laplace covariance with the curvature adjustment), some 50 runs.  The
   Gauss-Newton covariance of the fit alone assumes white noise of one level
   per test and no model error: on laboratory-like records it was 9-20x below
   the estimates' scatter over noise realisations and 20-150x below their
   error about the truth (with ``uncertainty=False`` it is what
   :attr:`Calibration.sd` holds, said so in :attr:`Calibration.sd_method`).

Every model run goes through the executor; the least-squares engine is
:func:`bayes_update.core.mode.find_mode`.  Steps 1-4 (the search) are
:mod:`bayes_update.core.two_stage`; this module builds the problem
(:func:`problem_for`), finds where the other workflows start
(:func:`find_start`) and runs the whole calibration with step 5
(:func:`calibrate_model`).
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass, field

import numpy as np

import volterra
from bayes_update.core.basis import DEFAULT_N_FUNCTIONS, linear_n_functions
from bayes_update.core.checks import disagreement_sentence, fit_warnings, output_errors
from bayes_update.core.effects import WithNulls
from bayes_update.core.identifiability import parameter_sd
from bayes_update.core.logs import info
from bayes_update.core.preflight import preflight
from bayes_update.core.problem import Problem
from bayes_update.core.two_stage import TwoStage, screen_linear, two_stage
from surrogates.evaluation import executor_for

__all__ = [
    "SETTINGS",
    "Calibration",
    "TwoStage",
    "calibrate_model",
    "check_settings",
    "find_start",
    "problem_for",
    "screen_linear",
    "two_stage",
]


@dataclass
class Calibration:
    """Result of :func:`calibrate_model` (values in each parameter's unit)."""

    theta: dict
    stage1: dict
    linear_parameters: list
    sensitivity: dict  # name -> move of y1 per prior range (relative to ||y1_ref||)
    metrics: dict  # each stage's metric at theta (e_lin, e_nlin, ...: metrics.metric_key)
    metric_set: str
    prediction_errors: dict  # validation test -> ||y - y_model|| / ||y||
    unidentified: dict  # stage -> [{"direction": {name: loading}, "sd_over_range": float}]
    noise_sd: dict  # stage -> measured noise [response unit]
    fit_warnings: list  # plain sentences (bayes_update.core.checks)
    disagreement: list  # parameters the two tests pull apart (bayes_update.core.checks)
    output_errors: dict  # test -> {"rel": output error, "noise_floor": what noise alone gives}
    n_functions: tuple
    n_model_runs: int
    units: dict
    problem: Problem = field(repr=False)
    #: sd of each parameter, in its unit: the Laplace approximation of the posterior (step 5 of the
    #: module docstring), or where that is off or failed the white-noise Gauss-Newton covariance of the
    #: fit (a scale for the report's digits, not an interval); which one: ``sd_method``
    sd: dict = field(default_factory=dict)
    sd_method: str = "gauss-newton"
    #: the posterior's mode where the sd is the Laplace approximation's (else {})
    laplace_mode: dict = field(default_factory=dict)

    def calibration_json(self) -> dict:
        """One key per parameter (its unit), e_lin, e_nlin, and how they were found."""
        return {
            **self.theta,
            **self.metrics,
            "metric_set": self.metric_set,
            "units": self.units,
            "prediction_errors": self.prediction_errors,
            "stage_1": self.stage1,
            "linear_parameters": self.linear_parameters,
            "linear_sensitivity": self.sensitivity,
            "unidentified_directions": self.unidentified,
            "noise_sd": self.noise_sd,
            "noise": {t: {ch: e.to_dict() for ch, e in chans.items()} for t, chans in self.problem.noise.items()},
            "representation_floor": {
                self.problem.tests[st].name: self.problem.representation_floor(st) for st in self.problem.stages
            },
            "output_errors": self.output_errors,
            "fit_warnings": self.fit_warnings,
            "test_disagreement": self.disagreement,
            "sd": self.sd,
            "sd_method": self.sd_method,
            "laplace_mode": self.laplace_mode,
            "n_functions": list(self.n_functions),
            "n_model_runs": self.n_model_runs,
            "setup": self.problem.describe(),
        }


def problem_for(
    dataset, model, space=None, metrics=None, executor=None, *, effects: bool = False, store=None
) -> Problem:
    """The one builder of a :class:`Problem` for ``model`` on ``dataset``.

    First the check before any long step (:func:`bayes_update.core.preflight.preflight`:
    the model's contract, the data set's roles, one model run), then the
    problem (the basis fit, the noise estimate).  Under the ``full`` metric set
    the linear test's J1 follows the number of parameters it moves (step 1's
    screen, d + 1 runs of the linear test; :func:`linear_n_functions`): the
    problem is rebuilt with it and keeps the screen's result in
    ``linear_parameters``, ``linear_sensitivity`` and ``n_screen_runs``.

    space : the prior (default: the model's declared parameters), kept as
        ``problem.space``.
    effects : the discrepancy workflow's problem: the model's candidate
        effects checked, kept as ``problem.effects``, and every one passed at
        its null (:class:`~bayes_update.core.effects.WithNulls`).
    store : a :class:`~bayes_update.core.runs.RunStore` the problem's runs are kept in
        and found in (the check's and the screen's already), or None.
    """
    # the discrepancy workflow's model is wrapped (its effects at their nulls): no store there
    store = None if effects else store
    checked = preflight(dataset, model, space, effects=effects, store=store)
    space = checked.space
    if effects:
        model = WithNulls(model, checked.nulls)
    problem = Problem(dataset, model, metrics=metrics)
    problem.space, problem.n_screen_runs, problem.effects, problem.run_store = space, 0, checked.effects, store
    if problem.metrics == "full":
        names, sens, runs = screen_linear(problem, space, executor)
        basis = problem.basis
        n_functions = linear_n_functions(len(names), n_modes=len(basis.modes(1)), feedthrough=basis.has_feedthrough(1))
        if n_functions != DEFAULT_N_FUNCTIONS:  # the same poles, more functions per mode
            basis = volterra.KautzBasis(basis.poles, n_functions, basis.feedthrough)
            problem = Problem(dataset, model, basis=basis, metrics=problem.metrics, noise=problem.noise)
            problem.space, problem.effects, problem.run_store = space, checked.effects, store
        problem.linear_parameters, problem.linear_sensitivity, problem.n_screen_runs = tuple(names), sens, runs
    return problem


def find_start(
    dataset,
    problem: Problem,
    space,
    *,
    n_points: int = 64,
    seed: int = 0,
    executor=None,
    progress: bool = False,
    log=info,
    coarse: bool = False,
) -> tuple[dict, int]:
    """(theta, model runs): where ``sample`` and ``find_discrepancy`` start.

    The model's own ``start(dataset, executor, progress)`` when it offers one
    (the beam: the paper's grids; ``coarse``: a start for a search that goes on
    from it, and ``store``, the problem's run store, each passed where the hook
    takes it), else this module's two-stage
    calibration (Sobol' designs of ``n_points`` points, then least squares)."""
    hook = getattr(problem.model, "start", None)
    if callable(hook):
        log("start: the model's own start search" + (" (coarse)" if coarse else ""))
        accepts = inspect.signature(hook).parameters
        kw = {"coarse": True} if coarse and "coarse" in accepts else {}
        if problem.run_store is not None and "store" in accepts:
            kw["store"] = problem.run_store  # its runs kept and found like every other step's
        return hook(dataset, executor=executor, progress=progress, **kw)
    log(f"start: the two-stage calibration (Sobol' designs of {n_points} points, then least squares)")
    names, runs = problem.linear_parameters, 0
    if names is None:
        names, problem.linear_sensitivity, runs = screen_linear(problem, space, executor)
        problem.linear_parameters = tuple(names)
    found = two_stage(
        problem,
        space,
        names,
        n_start=n_points,
        seed=seed,
        executor=executor,
        progress=progress,
        log=log,
        **({"n_best": 2, "polish": False} if coarse else {}),
    )
    return space.to_parameters(found.x), runs + found.n_model_runs


#: the settings of :func:`calibrate_model` (a ``[calibrate]`` table of ``--config`` for a model of your own)
SETTINGS = {"n_start": 64, "n_best": 3, "max_iterations": 40, "seed": 0}


def check_settings(settings: dict, where: str = "calibrate") -> dict:
    """``settings`` if every key is one of :data:`SETTINGS` with an integer value, else a
    ``ValueError`` naming the key and the known ones."""
    unknown = sorted(set(settings) - set(SETTINGS))
    if unknown:
        raise ValueError(f"{where}: unknown setting(s) {unknown}; known: {sorted(SETTINGS)}")
    bad = {k: v for k, v in settings.items() if isinstance(v, bool) or not isinstance(v, int)}
    if bad:
        raise ValueError(f"{where}: setting(s) {bad} must be whole numbers")
    return dict(settings)


def calibrate_model(
    dataset,
    model,
    *,
    metrics: str = "full",
    n_start: int = SETTINGS["n_start"],
    n_best: int = SETTINGS["n_best"],
    max_iterations: int = SETTINGS["max_iterations"],
    seed: int = SETTINGS["seed"],
    space=None,
    executor=None,
    workers=None,
    progress: bool = True,
    log=info,
    cache_dir=None,
    uncertainty: bool = True,
) -> Calibration:
    """The two-stage calibration of the module docstring.

    Parameters
    ----------
    dataset : tests with roles ``linear`` and ``nonlinear`` (and optionally
        ``validation``, for :attr:`Calibration.prediction_errors`).
    model : a model of the contract (checked with one run first).
    metrics : ``"full"`` (default) or ``"paper"``.
    n_start, n_best : Sobol' points per stage and how many of the best start
        a least-squares search.
    space : the prior (default: the model's declared parameters).
    cache_dir : folder whose ``runs`` keep every model run (:mod:`bayes_update.core.runs`): a
        rerun makes none of them again, and ``sample`` given the same folder starts from this
        calibration's best point.
    uncertainty : each parameter's sd from the Laplace approximation of the posterior at the
        result (step 5 of the module docstring; about 50 model runs); False: the fit's
        white-noise Gauss-Newton sd (no runs; not an interval).
    """
    from bayes_update.core.runs import store_in

    store = store_in(cache_dir, "calibrate") if cache_dir is not None else None
    with executor_for(executor, workers) as pool:
        problem = problem_for(dataset, model, space, metrics=metrics, executor=pool, store=store)
        space, runs = problem.space, 1 + problem.n_screen_runs
        if problem.linear_parameters is None:  # the paper's set: no J1 to adapt, screen here
            problem.linear_parameters, problem.linear_sensitivity, n = screen_linear(problem, space, pool)
            runs += n
        lin_names, sens = list(problem.linear_parameters), problem.linear_sensitivity
        n_functions = tuple(problem.basis.n_functions[k] for k in (1, 2, 3))
        log(f"linear parameters (screen): {', '.join(lin_names)}; J = {n_functions}")
        found = two_stage(
            problem,
            space,
            lin_names,
            n_start=n_start,
            n_best=n_best,
            max_iterations=max_iterations,
            seed=seed,
            executor=pool,
            progress=progress,
            log=log,
        )
        theta = space.to_parameters(found.x)
        metrics_at = problem.evaluate(theta)
        errors = output_errors(problem, theta, executor=pool)
        pred = {name: errors[name][0] for name in problem.validation}
        runs += found.n_model_runs + len(problem.stages) + len(errors)
        laplace = _laplace(dataset, problem, theta, pool, log) if uncertainty else None
        runs += laplace["n_model_runs"] if laplace else 0
    for d in found.unidentified["nonlinear"]:
        log(
            "WARNING: the data do not identify the direction "
            + ", ".join(f"{k} {v:+.2f}" for k, v in d["direction"].items())
            + f" (prior-range units; sd "
            f"{d['sd_over_range']:.2f} of the range): the point returned is one of many along it"
        )
    warnings = fit_warnings(problem, theta, errors) + [disagreement_sentence(d) for d in found.disagreement]
    for w in warnings:
        log(f"WARNING: {w}")
    return Calibration(
        theta=theta,
        stage1=space.to_parameters(found.x1),
        linear_parameters=lin_names,
        sensitivity=sens,
        metrics={k: v for k, v in metrics_at.items() if k != "error"},
        metric_set=problem.metrics,
        prediction_errors=pred,
        unidentified=found.unidentified,
        noise_sd={st: problem.noise_sd(st) for st in problem.stages},
        fit_warnings=warnings,
        disagreement=found.disagreement,
        output_errors={k: {"rel": e, "noise_floor": f} for k, (e, f) in errors.items()},
        n_functions=n_functions,
        n_model_runs=runs,
        units={p.name: p.unit for p in space.parameters},
        problem=problem,
        **_sd_fields(laplace, space, found),
    )


def _laplace(dataset, problem, theta, executor, log) -> dict | None:
    """:func:`~bayes_update.core.posterior.laplace_steps.laplace_at` at the result; None (said in
    the log) where the model cannot run there or the Laplace approximation fails."""
    from bayes_update.core.posterior.laplace_steps import laplace_at

    try:
        return laplace_at(dataset, problem, theta, executor=executor, log=lambda *a: None)
    except problem.failures + (ValueError, np.linalg.LinAlgError) as exc:
        log(
            f"WARNING: no Laplace sd at the calibrated point ({type(exc).__name__}: {exc}); the report's sd is the "
            "fit's white-noise Gauss-Newton sd, not an interval"
        )
        return None


def _sd_fields(laplace, space, found) -> dict:
    if laplace is not None:
        return {"sd": laplace["sd"], "sd_method": "laplace", "laplace_mode": laplace["mode"]}
    sd = parameter_sd(space, found.x, found.covariance) if found.covariance is not None else {}
    return {"sd": sd, "sd_method": "gauss-newton"}
