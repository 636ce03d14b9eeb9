"""The likelihood's model errors measured again at the mode.

:func:`errors_at_mode` re-measures, at the mode, the discretisation error
against the refined model and the model-form error (what a test's residual
holds beyond the noise, as random-phase draws), keeping the noise terms of
:func:`~bayes_update.core.noise_bootstrap.estimate_likelihood`.  Apart from
that bootstrap: it runs after the mode search, from its residual and Jacobian.
The derivation: :mod:`bayes_update.core.likelihood`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from bayes_update.core.likelihood_scales import Likelihood
from bayes_update.core.model_form import form_draws
from bayes_update.core.problem import Problem
from surrogates.evaluation import evaluate_many

#: random-phase draws of the model-form error at the mode per stage (projections only, no model run)
FORM_DRAWS = 96


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
      against its refined version there, as :func:`~bayes_update.core.likelihood.estimate_likelihood`
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
