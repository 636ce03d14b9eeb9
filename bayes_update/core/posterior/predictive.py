"""Posterior predictive check: the model's time response at posterior draws on every
test, estimation and validation alike, with the error model of each
(:mod:`bayes_update.core.error_model`); the share of each record's samples inside the
50 % and 90 % bands; the prediction errors of the posterior's mean, median and MAP;
and the surrogate's metrics against the model's at the draws."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtr

from bayes_update.core.error_model import error_models
from bayes_update.core.likelihood import Likelihood
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.problem import Problem
from surrogates.evaluation import evaluate_many

#: samples of each record drawn in the predictive figure (a window around its largest response)
FIGURE_SAMPLES = 1500
#: error draws per posterior draw for the figure's bands and posterior.nc's predictive group
ERROR_DRAWS = 8


@dataclass
class _Predict:
    """Picklable model runs of the predictive, None where the model cannot run:
    ``("stages", x, None)`` -> {stage: compared output, e_lin/e_nlin, "time": {test:
    response}} on the estimation tests, ``("test", x, name)`` -> the response on
    test ``name``."""

    problem: Problem
    space: ParameterSet

    def __call__(self, task):
        kind, x, name = task
        problem = self.problem
        p = self.space.to_parameters(np.asarray(x, float))
        try:
            if kind == "test":
                test = problem.validation.get(name) or next(t for t in problem.tests.values() if t.name == name)
                return problem.compared_response(problem.run(p, test.force)).astype(np.float32)
            out = {"time": {}}
            for st, test in problem.tests.items():
                v = problem.simulate(p, st)
                out[st] = problem.output(st, problem.components(st, v))
                out[Likelihood.key(st)] = problem.metric(st, v)
                out["time"][test.name] = problem.compared_response(v).astype(np.float32)
            return out
        except problem.failures:
            return None


@dataclass
class _PredictionErrors:
    problem: Problem
    space: ParameterSet

    def __call__(self, x):
        return self.problem.prediction_errors(self.space.to_parameters(np.asarray(x, float)))


def posterior_predictive(res, n: int, pool, seed, progress) -> dict:
    """Model runs at ``n`` posterior draws on every test (module docstring).

    Returns a dict: ``coverage`` {test: {sensor: {"50", "90"}}} (the share of the
    record's samples inside the central 50 % and 90 % predictive bands, read off
    each sample's predictive CDF), ``error_model`` {test: its ErrorModel},
    ``prediction_error`` {validation test: {"map", "posterior_mean",
    "posterior_median"}} (relative output error, as calibrate's), the
    surrogate's check, and for the figures and posterior.nc (keys with ``_``)
    the bands and the predictive draws."""
    problem = res.problem
    rng = np.random.default_rng(seed)
    idx = rng.choice(len(res.draws), size=min(n, len(res.draws)), replace=False)
    X = res.draws[idx]
    run = _Predict(problem, res.space)
    checks = evaluate_many(run, [("stages", x, None) for x in X], pool, progress=progress, desc="posterior predictive")
    ok = [i for i, o in enumerate(checks) if o is not None]
    # the model runs, counted as they are asked for: every estimation test at every draw
    pred = {"n_draws": len(X), "n_failed": len(X) - len(ok), "n_model_runs": len(X) * len(problem.tests)}
    if not ok:
        return pred
    pred.update(_surrogate_check(res, X, [checks[i] for i in ok], ok))
    records = {t.name: t.response for t in list(problem.tests.values()) + list(problem.validation.values())}
    draws = test_draws(res, X[ok])
    pred["parameters_by_test"] = None if draws is None else "recentred at each test's level (the tests disagree)"
    own = [] if draws is None else list(problem.tests.values())
    names = [t.name for t in own] + list(problem.validation)
    tasks = [("test", draws[name][i] if draws is not None else X[j], name) for name in names for i, j in enumerate(ok)]
    runs = evaluate_many(run, tasks, pool, progress=False)
    pred["n_model_runs"] += len(tasks)
    responses = {name: runs[k * len(ok) : (k + 1) * len(ok)] for k, name in enumerate(names)}
    if draws is None:
        responses.update({t.name: [checks[j]["time"][t.name] for j in ok] for t in problem.tests.values()})
    errors = error_models(problem, res.likelihood)
    sensors = [name for name, _ in problem.sensors]
    pred["error_model"] = {t: e.to_dict(sensors) for t, e in errors.items()}
    pred["coverage"], pred["_time"], pred["_draws"] = {}, {}, {}
    for name, y in records.items():
        Y = np.array([v for v in responses[name] if v is not None], float)  # (m, n[, k])
        if not len(Y):
            continue
        Y, y2 = Y.reshape(len(Y), len(y), -1), y.reshape(len(y), -1)
        sd = errors[name].sd(np.sqrt(np.mean(np.median(Y, axis=0) ** 2, axis=0)))
        pred["coverage"][name] = {s: band_coverage(Y[:, :, j], y2[:, j], sd[j]) for j, s in enumerate(sensors)}
        # posterior.nc's predictive draws: each model draw with one draw of its errors
        pred["_draws"][name] = (Y + sd * rng.standard_normal(Y.shape)).astype(np.float32).reshape((len(Y),) + y.shape)
        pred["_time"][name] = _window_bands(Y, y2, sd, rng)
    pred["prediction_error"] = prediction_errors(res, pool)
    pred["n_model_runs"] += len(PREDICTION_POINTS) * len(problem.validation)
    return pred


def test_draws(res, X) -> dict | None:
    """Where the tests disagree (the curvature adjustment's ``between_tests``), the
    parameters each test is predicted with: the posterior's draws with the spread
    one test leaves (``within``), about the point that test's level prefers, each
    estimation test's own best point, in between interpolated in the log of the level
    (the force's rms), beyond the tests held at the nearest one's.  Why: a model that
    lacks an amplitude-dependent effect needs other parameters at each level; its
    posterior spans the levels tested, and its draws taken as they are would put a
    band of every level's parameters on every test.  None where the tests agree
    (every test is predicted with the posterior's draws)."""
    adj = res.adjustment
    if adj is None or not adj.between_tests or adj.within is None:
        return None
    problem, box = res.problem, res.space.box()
    c = adj.center
    Y = c + (np.asarray(X, float) - c) @ adj.within.T
    stages = [
        (float(np.log(_rms(t.force))), np.asarray(adj.between_tests["offsets"][st], float))
        for st, t in problem.tests.items()
    ]
    stages.sort(key=lambda s: s[0])
    levels = np.array([s[0] for s in stages])
    offsets = np.array([s[1] for s in stages])
    out = {}
    for t in list(problem.tests.values()) + list(problem.validation.values()):
        a = np.log(_rms(t.force))
        b = np.array([np.interp(a, levels, offsets[:, i]) for i in range(offsets.shape[1])])
        out[t.name] = np.clip(Y + b, box[:, 0], box[:, 1])
    return out


def _rms(x) -> float:
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean((x - x.mean()) ** 2)))


def band_coverage(Y, y, sd: float) -> dict:
    """The share of the record ``y`` (n,) inside the central 50 % and 90 % bands of
    the predictive mixture ``(1/m) sum_i N(Y_i(t), sd^2)`` (``Y``: (m, n) model draws):
    each sample's PIT, the mixture's CDF at the measured value, within 0.25 and 0.45
    of one half."""
    if not sd > 0:
        sd = 1e-12 * max(float(np.max(np.abs(y))), 1e-300)
    pit = ndtr((np.asarray(y, float)[None, :] - Y) / sd).mean(axis=0)
    return {"50": float(np.mean(np.abs(pit - 0.5) <= 0.25)), "90": float(np.mean(np.abs(pit - 0.5) <= 0.45))}


def _window_bands(Y, y2, sd, rng) -> dict:
    """The 5, 25, 50, 75 and 95 % quantiles of the predictive mixture (each model draw
    with :data:`ERROR_DRAWS` draws of its errors) and the record, on a window of
    :data:`FIGURE_SAMPLES` samples around the record's largest response."""
    n = len(y2)
    centre = int(np.argmax(np.sum(y2**2, axis=1)))
    start = int(np.clip(centre - FIGURE_SAMPLES // 2, 0, max(n - FIGURE_SAMPLES, 0)))
    cut = slice(start, start + FIGURE_SAMPLES)
    Yw = Y[:, cut]
    draws = (Yw[:, None] + sd * rng.standard_normal((len(Yw), ERROR_DRAWS) + Yw.shape[1:])).reshape(-1, *Yw.shape[1:])
    q = np.percentile(draws, [5, 25, 50, 75, 95], axis=0)
    return {"start": start, "q05": q[0], "q25": q[1], "median": q[2], "q75": q[3], "q95": q[4], "record": y2[cut]}


#: the points :func:`prediction_errors` predicts the validation tests at
PREDICTION_POINTS = ("map", "posterior_mean", "posterior_median")


def prediction_errors(res, pool) -> dict:
    """{validation test: {"map", "posterior_mean", "posterior_median"}}: the relative
    output error of the model at each point (:meth:`Problem.prediction_errors`), the mean
    and median taken in the sampler's coordinates."""
    problem = res.problem
    if not problem.validation:
        return {}
    points = dict(zip(PREDICTION_POINTS, (res.map.x, res.draws.mean(axis=0), np.median(res.draws, axis=0))))
    errs = evaluate_many(_PredictionErrors(problem, res.space), list(points.values()), pool, progress=False)
    return {name: {k: float(e[name]) for k, e in zip(points, errs)} for name in problem.validation}


def _surrogate_check(res, X, outs, ok) -> dict:
    """The bands of each stage's compared output, and the surrogate's metrics against
    the model's at the draws."""
    problem = res.problem
    pred, bands = {}, {}
    for st in problem.stages:
        Y = np.array([o[st] for o in outs])
        bands[st] = {
            "low": np.percentile(Y, 5, axis=0),
            "high": np.percentile(Y, 95, axis=0),
            "median": np.median(Y, axis=0),
            "reference": problem.output(st, problem.reference_components(st)),
        }
        e_model = np.array([o[Likelihood.key(st)] for o in outs])
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
