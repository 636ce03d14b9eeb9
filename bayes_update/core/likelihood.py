"""The likelihood of a model's parameters given its metrics e_lin and e_nlin.

Derivation (docs/likelihood.md has the long form)
-------------------------------------------------
Each metric compares Volterra components of the measured and the simulated
velocity projected on the same regressors: ``e = ||Phi (theta_ref -
theta_mod(x))|| / ||y_ref||``, where ``Phi`` holds the p regressors of the
stage (p = J1 = 2 for e_lin; the 59 order-2 and order-3 products for e_nlin).
At the true parameters the difference ``Phi (theta_ref - theta_mod)`` is
noise: the output noise projected on the regressors, and, larger here, the
response to the *input* noise, since the model is driven by the recorded
(noisy) force while the structure felt the true one.  If that difference is
Gaussian with variance ``s_n^2 ||y_ref||^2`` in each of ``nu`` effective
directions,

    e^2 / s_n^2 ~ chi^2_nu    and    log L(x) = -e(x)^2 / (2 s_n^2) + const,

so the metric (not its log, and not with a variance marginalised away) enters
as a squared distance.  Two facts decide this form on this problem:

* the noise scale cannot be read from the misfit at the optimum: for the
  linear stage p = 2 coefficients meet 2 parameters (P_eff, eta), so e_lin
  reaches ~1e-7 at its minimum (measured), and a likelihood with the noise
  variance marginalised (``-n_eff log e``) would put infinite density there;
* the regression residual underestimates it 17-fold (0.027 % against 0.46 %
  for e_lin at the truth of the default data set), because most of the
  metric's noise is the input-noise response, which lies inside the span of
  the regressors.

So ``s_n`` and ``nu`` come from a parametric bootstrap at the estimate
(:func:`estimate_likelihood`): the white noise levels of both channels are
read from their spectra above the excited band, the model at the estimate is
taken as truth, K replicates of the measurement (the recorded force plus
force noise drives the model, projected on the recorded force's regressors; the model's response
to the clean force plus velocity noise is the "measurement") give K residual
vectors; their mean square per direction of the span of the parameter
sensitivities (:mod:`bayes_update.core.span`) is ``s_n^2``.  ``nu`` (from
``mean(e^2) = nu s_n^2``, ``var(e^2) = 2 nu s_n^4``) is reported only: its
estimate from K values wanders by 2x between seeds.

Model error: the updating model is a discretisation (or a reduction); its
error at the estimate, ``e_model``, is measured against a refined model
(:meth:`bayes_update.core.problem.Problem.refined_model`: the model's
``refined()``; the beam's is a finer mesh) and added as ``s^2 = s_n^2 + e_model^2``.  The bias is
deterministic and mostly in one direction (a frequency error moves P_eff), so
it is budgeted as one standard deviation in *any* direction, not spread over
nu of them: a bias of that size then shifts any parameter by at most one
posterior sd.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from bayes_update.core.metrics import STAGE_ORDERS
from bayes_update.core.model_form import form_draws, periodogram
from bayes_update.core.problem import Problem
from bayes_update.core.replicates import ScalesRun, control_variate_rows, draw_replicates, lti_fit
from bayes_update.core.span import derivative_from, derivative_points, span_of
from surrogates.evaluation import evaluate_many


@dataclass(frozen=True)
class StageScale:
    """Noise and model-error scale of one metric (all dimensionless, relative)."""

    stage: str
    noise_mean_square: float  # mean of e^2 over the noise replicates at the estimate
    noise_dof: float  # nu: effective directions of the noise
    model_error: float  # e_model: model against its refined version at the estimate
    n_regressors: int
    n_replicates: int
    noise_levels: dict = field(default_factory=dict)  # channel -> {sd, unit, method, detail} the bootstrap added
    span_variance: float | None = None  # noise variance per direction in the span of the parameters' sensitivities
    span_rank: int | None = None
    model_error_unabsorbed: float | None = None  # the part of e_model no parameter change can take up
    model_error_source: str | None = None  # what e_model was measured against, or why it is zero
    #: the model-form error's variance per direction of the span (its draws at the mode,
    #: bayes_update.core.model_form), in the units of span_variance; 0 where not measured
    model_form_variance: float = 0.0
    #: {sensor: rms of the residual's excess over the noise at the mode / the record's rms}
    model_form_rms: dict | None = None
    model_form_source: str | None = None  # how the model-form error was measured, or why not

    @property
    def noise_sd(self) -> float:
        """s_n: the noise's sd per direction in the span of the parameter
        sensitivities when measured (``span_variance``), else mean(e^2) / nu."""
        if self.span_variance is not None:
            return math.sqrt(self.span_variance)
        return math.sqrt(self.noise_mean_square / self.noise_dof)

    @property
    def model_form_sd(self) -> float:
        """The model-form error's sd per direction of the span."""
        return math.sqrt(self.model_form_variance)

    @property
    def sd(self) -> float:
        """s = sqrt(s_n^2 + s_form^2 + e_model^2): the metric's scale in the likelihood."""
        return math.sqrt(self.noise_sd**2 + self.model_form_variance + self.model_error**2)

    def to_dict(self) -> dict:
        return {**asdict(self), "noise_sd": self.noise_sd, "model_form_sd": self.model_form_sd, "sd": self.sd}


@dataclass(frozen=True)
class Likelihood:
    """``log L = -1/2 sum_stage (e_stage / s_stage)^2`` (see the module docstring).

    ``noise_residuals`` (stage -> ((K, n) array, (K,) weights), optional): the
    bootstrap's replicate residual vectors, relative to the reference's norm,
    and their weights in the noise's second moment ``sum_i w_i d_i d_i^T``
    (1/K each, or a control variate's, :func:`estimate_likelihood`);
    ``form_residuals`` the same of the model-form error's draws at the mode
    (:func:`errors_at_mode`).  :func:`bayes_update.core.adjustment.curvature_adjustment`
    needs both (:meth:`error_rows`); none of these is pickled (workers need only the scales)."""

    scales: dict  # stage -> StageScale
    noise_residuals: dict | None = field(default=None, compare=False, repr=False)
    #: stage -> :class:`~bayes_update.core.span.Sensitivity` at the point the scales were measured (the sensitivity
    #: span's runs), which a mode search from that point takes as its first Jacobian
    sensitivities: dict | None = field(default=None, compare=False, repr=False)
    #: stage -> the noise's periodogram in a replicate's time-domain residual, (n // 2 + 1,) or
    #: (n // 2 + 1, n_sensors): what the model-form error is measured beyond
    noise_spectra: dict | None = field(default=None, compare=False, repr=False)
    form_residuals: dict | None = field(default=None, compare=False, repr=False)

    def __getstate__(self):
        return {
            "scales": self.scales,
            "noise_residuals": None,
            "sensitivities": None,
            "noise_spectra": None,
            "form_residuals": None,
        }

    def error_rows(self, stage: str):
        """``(D, w)``: the noise replicates' rows and, where measured, the model-form
        draws' (weights 1/K each), one second moment ``sum_i w_i d_i d_i^T``; None
        without the noise replicates."""
        res = (self.noise_residuals or {}).get(stage)
        if res is None:
            return None
        D, w = res if isinstance(res, tuple) else (res, np.full(len(res), 1.0 / len(res)))
        form = (self.form_residuals or {}).get(stage)
        if form is None:
            return D, w
        return np.vstack([D, form[0]]), np.concatenate([w, form[1]])

    def __post_init__(self):
        for st, sc in self.scales.items():
            if st not in STAGE_ORDERS:
                raise ValueError(f"unknown stage {st!r}")
            if not (sc.sd > 0 and math.isfinite(sc.sd)):
                raise ValueError(f"stage {st}: the likelihood scale must be positive and finite, got {sc.sd}")

    @property
    def stages(self) -> tuple:
        return tuple(s for s in STAGE_ORDERS if s in self.scales)

    @staticmethod
    def key(stage: str) -> str:
        return "e_lin" if stage == "linear" else "e_nlin"

    def restricted(self, stages) -> "Likelihood":
        def part(d):
            return {s: d[s] for s in stages if s in d} if d else None

        return Likelihood(
            {s: self.scales[s] for s in stages},
            part(self.noise_residuals),
            noise_spectra=part(self.noise_spectra),
            form_residuals=part(self.form_residuals),
        )

    def unabsorbed(self) -> "Likelihood":
        """The same noise with only the unabsorbed part of the model error
        (orthogonal to the parameters' sensitivities): the misfit a model
        comparison should count as explained.  The posterior keeps the whole
        model error, so that its bias moves a parameter by at most one sd."""
        return Likelihood(
            {
                st: dataclasses.replace(sc, model_error=sc.model_error_unabsorbed)
                if sc.model_error_unabsorbed is not None
                else sc
                for st, sc in self.scales.items()
            },
            self.noise_residuals,
            self.sensitivities,
            self.noise_spectra,
            self.form_residuals,
        )

    def log_likelihood(self, metrics: dict) -> float:
        """From a dict with e_lin / e_nlin; a failed run (NaN) gives -inf."""
        total = 0.0
        for st, sc in self.scales.items():
            e = metrics[self.key(st)]
            if not np.isfinite(e):
                return -np.inf
            total += (e / sc.sd) ** 2
        return -0.5 * total

    # The surrogate emulates z = log(1 + e^2 / s^2): quadratic (smooth) near the
    # minimum, where e itself has a kink (|.| of a linear function) and log e a
    # -inf spike; logarithmic far from it, where e^2 spans decades.
    def to_z(self, stage: str, e):
        return np.log1p((np.asarray(e, float) / self.scales[stage].sd) ** 2)

    def from_z(self, stage: str, z):
        return self.scales[stage].sd * np.sqrt(np.expm1(np.maximum(np.asarray(z, float), 0.0)))

    @staticmethod
    def log_likelihood_from_z(z_by_stage: dict):
        """-1/2 sum (e/s)^2 written in z: -1/2 sum (exp(z) - 1)."""
        return -0.5 * sum(np.expm1(z) for z in z_by_stage.values())

    def to_dict(self) -> dict:
        return {st: sc.to_dict() for st, sc in self.scales.items()}


#: noise replicates whose time-domain residuals give the noise's spectrum (Likelihood.noise_spectra)
SPECTRUM_REPLICATES = 32
#: random-phase draws of the model-form error at the mode per stage (projections only, no model run)
FORM_DRAWS = 96


# --------------------------------------------------------------------- noise
def noise_scale_from_replicates(e2, max_dof: int) -> tuple[float, float]:
    """(mean of e^2, nu) from replicate values of e^2, assuming e^2 = s^2 chi^2_nu:
    mean = nu s^2 and var = 2 nu s^4 give nu = 2 mean^2 / var, clipped to
    [1, max_dof] (the metric cannot have more directions than regressors)."""
    e2 = np.asarray(e2, float)
    if e2.ndim != 1 or e2.size < 4 or not np.all(np.isfinite(e2)) or np.any(e2 < 0):
        raise ValueError("need at least 4 finite non-negative replicate values of e^2")
    mean = float(e2.mean())
    var = float(e2.var(ddof=1))
    nu = float(np.clip(2 * mean**2 / var, 1.0, max_dof)) if var > 0 else float(max_dof)
    return mean, nu


def estimate_likelihood(
    problem: Problem,
    params,
    *,
    refined=None,
    model_error: bool = True,
    n_replicates: int = 32,
    seed=0,
    stages=None,
    space=None,
    model_replicates: int | None = None,
    executor=None,
) -> Likelihood:
    """Measure the likelihood scales at the estimate ``params`` (module docstring).

    n_replicates : noise replicates per stage (K model runs each, unless
        ``model_replicates``); the relative sd of the estimated s_n is about
        1/sqrt(2 K nu).
    model_replicates : None (every replicate a model run), or k: the response to
        the force noise of the ``n_replicates`` replicates from a linear
        time-invariant estimate of the model's response (one model run), its
        error corrected by k replicates run on the model as well
        (:func:`bayes_update.core.replicates.control_variate_rows`): 2 + k model runs per stage instead of K.
    refined : the model the model error is measured against (default
        :meth:`Problem.refined_model`); ignored with ``model_error=False`` (e.g. when
        the data come from the updating model itself).
    executor : runs every model run of every stage in parallel, all at once (the same
        numbers as without: every random draw is made here, in the same order).
    """
    if int(n_replicates) != n_replicates or n_replicates < 4:
        raise ValueError(f"n_replicates must be an integer >= 4, got {n_replicates!r}")
    if model_replicates is not None and (int(model_replicates) != model_replicates or model_replicates < 4):
        raise ValueError(f"model_replicates must be None or an integer >= 4, got {model_replicates!r}")
    stages = problem.stages if stages is None else tuple(stages)
    ref_model, error_source = None, "off (model_error=False)"
    if model_error:
        ref_model = refined if refined is not None else problem.refined_model()
        error_source = f"{type(ref_model).__name__} (refined)" if refined is not None else problem.refinement_source()
    space = space if space is not None else problem.default_space()
    # every random draw first, stage by stage in a fixed order, then every model run of every
    # stage in one call to the executor (the workers never wait for a stage), then the sums
    plans, tasks = [], []
    for i, stage in enumerate(stages):
        plan = draw_replicates(
            problem,
            stage,
            int(n_replicates),
            model_replicates,
            np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,))),
        )
        plan["x"], plan["h"], plan["steps"], points = derivative_points(space, params)
        kinds = (
            [("force", plan["force"])]
            + [("force", f) for f in plan["forces"]]
            + [("output", x) for x in points]
            + ([("refined", plan["force"])] if ref_model is not None else [])
        )
        plan["slice"] = slice(len(tasks), len(tasks) + len(kinds))
        tasks += [(kind, stage, arg) for kind, arg in kinds]
        plans.append(plan)
    # the refined model's runs (the longest) first, so that none is left alone at the end
    order = sorted(range(len(tasks)), key=lambda j: tasks[j][0] != "refined")
    done = evaluate_many(
        ScalesRun(problem, params, space, ref_model), [tasks[j] for j in order], executor, batch_size=1, progress=False
    )
    results = [None] * len(tasks)
    for j, value in zip(order, done):
        results[j] = value
    scales, residuals, sensitivities, spectra = {}, {}, {}, {}
    for stage, plan in zip(stages, plans):
        res = results[plan["slice"]]
        v0, runs = res[0], res[1 : 1 + len(plan["forces"])]
        outs = res[1 + len(plan["forces"]) : 1 + len(plan["forces"]) + len(plan["x"])]
        ref_norm = np.linalg.norm(problem.output(stage, problem.reference_components(stage)))
        # the replicate's difference is projected on the recorded force's regressors, not on
        # its noisy force's: y_meas and v share v0, so the regressors' own change with the
        # force noise acts on their difference only, a second-order term (on the default data
        # set the metric's noise is the same to 3 digits either way: 0.0828 % against 0.0830 %
        # linear, 0.611 % against 0.611 % nonlinear), and no projector is built per replicate
        proj = problem.projector(stage)

        def row(noise, dv):
            return problem.output(stage, problem.components(stage, noise - dv, proj)) / ref_norm

        if plan["probe"] is not None:
            lti = lti_fit(plan["probe"], runs[0] - v0)
            D, w = control_variate_rows(row, lti, plan["cheap"], plan["pairs"], runs[1:], v0)
            changes = [lti(du) for du, _ in plan["cheap"][:SPECTRUM_REPLICATES]]
        else:  # every replicate a model run (none needed without force noise)
            runs = runs if plan["forces"] else [v0] * len(plan["cheap"])
            D = np.array([row(noise, v - v0) for (_, noise), v in zip(plan["cheap"], runs)])
            w = np.full(len(D), 1.0 / len(D))
            changes = [v - v0 for v in runs[:SPECTRUM_REPLICATES]]
        # the noise's spectrum in a replicate's time-domain residual (sensor noise and the response
        # to the force noise): what the model-form error at the mode is measured beyond
        spectra[stage] = np.mean([periodogram(noise - dv) for (_, noise), dv in zip(plan["cheap"], changes)], axis=0)
        e2 = np.sum(D**2, axis=1)
        n_reg = problem.n_regressors(stage)
        _, nu = noise_scale_from_replicates(e2[w > 0][: int(n_replicates)], n_reg)  # nu: reported only
        mean = float(w @ e2)
        y0 = problem.output(stage, problem.components(stage, v0))
        sens = derivative_from(plan["x"], plan["h"], plan["steps"], y0, outs)
        sensitivities[stage] = sens
        Q = span_of(sens.derivative, stage)
        span_var = float(w @ np.sum((D @ Q) ** 2, axis=1) / Q.shape[1])
        e_model = e_perp = 0.0
        if ref_model is not None:
            d = y0 - problem.output(stage, problem.components(stage, res[-1]))
            e_model = float(np.linalg.norm(d) / ref_norm)
            e_perp = float(np.linalg.norm(d - Q @ (Q.T @ d)) / ref_norm)
        residuals[stage] = (D, w)
        scales[stage] = StageScale(
            stage=stage,
            noise_mean_square=mean,
            noise_dof=nu,
            model_error=e_model,
            n_regressors=n_reg,
            n_replicates=int(n_replicates),
            noise_levels=_noise_levels(plan["estimates"], problem.sensors),
            span_variance=span_var,
            span_rank=int(Q.shape[1]),
            model_error_unabsorbed=e_perp,
            model_error_source=error_source,
        )
    return Likelihood(scales, residuals, sensitivities, spectra)


@dataclass
class _RunAt:
    """Picklable: ``model`` (None: the problem's) at ``params`` on a stage's test; None where
    it cannot run."""

    problem: Problem
    params: dict
    model: object
    stage: str

    def __call__(self):
        try:
            return self.problem.run(self.params, self.problem.tests[self.stage].force, model=self.model)
        except self.problem.failures:
            return None


def _call(task):
    return task()


def errors_at_mode(
    problem: Problem,
    likelihood: Likelihood,
    params,
    residual,
    jacobian,
    executor=None,
    seed=0,
    n_draws: int = FORM_DRAWS,
    own_points: dict | None = None,
) -> Likelihood:
    """``likelihood`` with its model errors measured at the mode ``params``; the noise terms stay.

    * The discretisation error (where the model has ``refined()``): the model
      against its refined version there, as :func:`estimate_likelihood`
      measures it at the start (a start may lie far from the mode).
    * The model-form error: what a test's residual holds beyond the noise at
      the test's own best point (``own_points``: {stage: params}, default the
      mode), as random-phase draws (:mod:`bayes_update.core.model_form`)
      projected like the noise replicates; its variance per direction of the span
      of the parameters' sensitivities is ``model_form_variance``.  Why the test's
      own point: at the joint mode a test's residual also holds the pull of the
      other test (a compromise the parameters could take up), which the tests'
      disagreement counts (:func:`bayes_update.core.adjustment.between_test_covariance`);
      what no parameter value takes up is the model-form error.  A model that is
      right leaves nothing beyond the noise and keeps its scales.

    Per stage a run of the model at the mode and one at the stage's own point
    (the better residual counts: a Gauss-Newton step along a direction the test
    barely pins may overshoot) and, where it has ``refined()``, one of the refined
    model at the mode (through ``executor``, all side by side); the model's compared output
    at the mode comes from the mode's
    scaled ``residual`` (no run) and the span from its ``jacobian`` (rows in
    ``problem.stages`` order).  With the model
    error switched off (``model_error=False``: data made by the updating model
    itself) the likelihood is returned as it is."""
    if all((sc.model_error_source or "").startswith("off") for sc in likelihood.scales.values()):
        return likelihood
    ref_model = problem.refined_model()
    own = own_points or {}
    stages = problem.stages
    # per stage the model at the mode and at the stage's own point (its better residual is taken:
    # a Gauss-Newton step along a direction the test barely pins may overshoot), and the refined model
    tasks = (
        [_RunAt(problem, params, None, st) for st in stages]
        + [_RunAt(problem, own[st], None, st) for st in stages if st in own]
        + ([_RunAt(problem, params, ref_model, st) for st in stages] if ref_model is not None else [])
    )
    runs = evaluate_many(_call, tasks, executor, batch_size=1, progress=False)
    at_mode, runs = runs[: len(stages)], runs[len(stages) :]
    at_own = {st: runs.pop(0) for st in stages if st in own}
    refined_runs = runs
    scales, forms, row = {}, {}, 0
    for i, stage in enumerate(stages):
        sc = likelihood.scales[stage]
        ref = problem.output(stage, problem.reference_components(stage))
        norm, n = np.linalg.norm(ref), ref.size
        r, J = np.asarray(residual[row : row + n], float), np.asarray(jacobian[row : row + n], float)
        row += n
        Q = _column_span(J)
        changes = {}
        if ref_model is not None:
            d = ref - r * norm * sc.sd - problem.output(stage, problem.components(stage, refined_runs[i]))
            changes.update(
                model_error=float(np.linalg.norm(d) / norm),
                model_error_unabsorbed=float(np.linalg.norm(d - Q @ (Q.T @ d)) / norm),
            )
        spectrum = (likelihood.noise_spectra or {}).get(stage)
        test = problem.tests[stage]
        where, resid = _best_residual(problem, test, at_mode[i], at_own.get(stage))
        if spectrum is None:
            changes["model_form_source"] = "not measured: the likelihood has no noise spectrum (given by hand)"
        elif resid is None:
            changes["model_form_source"] = "not measured: the model cannot run at the MAP"
        else:
            rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(100 + i,)))
            draws, excess = form_draws(resid, spectrum, n_draws, rng)
            D = np.array([problem.output(stage, problem.components(stage, dk)) / norm for dk in draws])
            forms[stage] = (D, np.full(len(D), 1.0 / len(D)))
            y = test.response.reshape(len(test.response), -1)
            rel = np.sqrt(np.mean(excess.reshape(len(excess), -1) ** 2, axis=0) / np.mean(y**2, axis=0))
            changes.update(
                model_form_variance=float(np.mean(np.sum((D @ Q) ** 2, axis=1)) / max(Q.shape[1], 1)),
                model_form_rms={name: float(v) for (name, _), v in zip(problem.sensors, rel)},
                model_form_source=f"the test's residual at {where} beyond the noise's spectrum "
                f"({n_draws} random-phase draws)",
            )
        scales[stage] = dataclasses.replace(sc, **changes)
    return Likelihood(
        scales, likelihood.noise_residuals, likelihood.sensitivities, likelihood.noise_spectra, forms or None
    )


def _best_residual(problem, test, at_mode, at_own):
    """(where, the record's residual) of the better of the model's runs at the mode and
    at the test's own point (by rms; None where a run failed)."""
    best = None
    for where, run in (("the MAP", at_mode), ("its own best point", at_own)):
        if run is None:
            continue
        r = test.response - problem.compared_response(run)
        if best is None or np.sum(r**2) < np.sum(best[1] ** 2):
            best = (where, r)
    return best if best is not None else (None, None)


def _column_span(J) -> np.ndarray:
    """An orthonormal basis of the columns of J (singular values above 1e-6 of the largest)."""
    U, S, _ = np.linalg.svd(J, full_matrices=False)
    return U[:, : int(np.sum(S > 1e-6 * S[0]))] if S.size and S[0] > 0 else U[:, :0]


def _noise_levels(estimates: dict, sensors) -> dict:
    """{channel: {"sd", "unit", "method", "detail"}} of the noise the bootstrap adds
    (the force's counted as 0 where it is unknown)."""
    from bayes_update.data.dataset import RESPONSE_UNITS

    units = {"force": "N", **{name: RESPONSE_UNITS[kind] for name, kind in sensors}}
    return {ch: {**estimates[ch].to_dict(), "unit": units[ch]} for ch in ["force"] + [n for n, _ in sensors]}


def likelihood_runs(
    problem: Problem,
    n_replicates: int,
    space=None,
    model_error: bool = True,
    stages=None,
    model_replicates: int | None = None,
) -> int:
    """Model runs :func:`estimate_likelihood` takes: per stage one at the
    estimate, ``n_replicates`` (or the LTI probe and ``model_replicates``; none
    without force noise), d for the sensitivity span and one of the refined
    model (when there is one)."""
    stages = problem.stages if stages is None else tuple(stages)
    d = len(space if space is not None else problem.default_space())
    refined = model_error and problem.refined_model() is not None
    total = 0
    for st in stages:
        est = problem.noise[problem.tests[st].name]["force"]
        if not est.sd:
            replicates = 0
        else:
            replicates = int(n_replicates) if model_replicates is None else 1 + int(model_replicates)
        total += 1 + replicates + d + int(refined)
    return total
