"""The discrepancy workflow for any model of the contract: name the effect the
model misses, add it, re-update, show the gap shrink.

The model offers its candidates through ``candidate_effects()`` alone
(:mod:`bayes_update.core.effects`: parameters with a ``null`` value that
switches the effect off).  :func:`find_discrepancy` runs these steps:

1. **baseline**: start at ``start``, else where the model's own ``start``
   hook or the two-stage calibration puts it
   (:func:`bayes_update.core.calibrate.find_start`); the likelihood scales
   there (:func:`bayes_update.core.likelihood.estimate_likelihood`, with only
   the unabsorbed model error: a model comparison counts the rest as
   explained); the mode by least squares (:mod:`bayes_update.core.mode`) from
   the start and the two best of the model's ``extra_starts`` (if it offers
   them); the scales again at that mode (``reestimate_likelihood``) and the
   mode's Laplace evidence.  Every candidate parameter is passed at its null;
2. **naming rounds**: each effect's parameters are added (uniform prior on
   their bounds, log-uniform for ``log=True``); the extended mode is searched
   from the current mode with the effect's parameters at its null and at
   ``effect_start`` of the range on each side of it (where the range extends
   that way: from the null itself a symmetric effect has no gradient; the
   null start guarantees a fit no worse than the model without the effect);
   the model without it re-converged from that fit's base parameters with the
   same effort (so that what re-converging the base parameters gains is not
   credited to an effect); a fit that still ends below the model without it
   is run again from there, and reported as failed if it does once more
   (:func:`~bayes_update.core.fits.failed_fit`, never as a Bayes factor);
   Laplace log evidence and ``2 ln B`` of each at its own optimum, each model
   under the noise and the model-form error its own mode leaves
   (:mod:`bayes_update.core.comparison`: a misfit no candidate explains counts
   for none of them); each fit's prediction of the held-out
   tests (:mod:`bayes_update.core.held_out`).  Named when ``2 ln B >``
   :data:`~bayes_update.core.effects.DECISIVE`, the Laplace interval (mode +- 2
   sd) of one of its parameters excludes the null, the fit is neither at its
   null nor on a bound of its prior (both reported as such), and the
   held-out tests are predicted better beyond their noise, none of them worse (a test the
   model cannot run, a softening spring past its barrier, is worse); the strongest candidate
   so accepted is named, then a next round looks for a second effect (``max_effects``).
   When the strongest candidate is decisive but not named (on a bound of its prior, or
   predicting the held-out tests worse), it may be taking another effect's share as well:
   it is fitted together with each other candidate, and a pair is named when
   it is decisive against each member alone and both members sit inside their
   priors, away from their nulls (:func:`~bayes_update.core.fits.names_pair`), and its
   evidence beats the accepted single candidate's, if any;
3. **re-update**: the likelihood scales re-measured with the named effects in
   the model (its model-form error too), the extended mode and its Laplace posterior;
4. **the gap that remains**: e_lin and e_nlin over
   :func:`~bayes_update.core.effects.misfit_allowance`, and the held-out tests'
   error beyond their noise, reported as numbers
   (:meth:`~bayes_update.core.effects.NamingVerdict.gap_sentence`): "closed"
   within :data:`~bayes_update.core.effects.EXPLAINED_FACTOR`, else "a gap
   remains: something outside the catalogue"; not a condition for naming;
5. **gap** before and after: e_lin, e_nlin and, for each test with role
   ``validation``, the direct output error ||y - y_model|| / ||y|| and its
   part beyond the noise (:data:`~bayes_update.core.fits.GAP_LABELS`); where
   the model offers ``diagnose`` (the beam's harmonics, free decays and kernel
   orders), its diagnostics before and after and, through ``signature``,
   whether the number each named effect's physics should move shrank.

Values are reported in each parameter's unit, under its declared name.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bayes_update.core.calibrate import find_start, problem_for
from bayes_update.core.detectability import detectability
from bayes_update.core.discrepancy_steps import DiscrepancyWorkflow
from bayes_update.core.effects import EXPLAINED_FACTOR, NamingVerdict, misfit_ratios
from bayes_update.core.fits import Fit, gap, noise_floor, signature_changes
from bayes_update.core.logs import info
from bayes_update.core.preflight import preflight
from bayes_update.core.problem import Problem
from bayes_update.core.steps import StepLog
from surrogates.evaluation import executor_for

__all__ = ["DiscrepancyResult", "DiscrepancySettings", "Fit", "find_discrepancy"]


@dataclass(frozen=True)
class DiscrepancySettings:
    n_replicates: int = 24  # noise replicates for the likelihood scales
    max_iterations: int = 50  # least-squares iterations per start
    max_effects: int = 2  # effects named at most (greedy, one at a time)
    n_start: int = 64  # Sobol' points of the start search (when no start is given)
    effect_start: float = 0.1  # effect starts: null +- this fraction of the range
    extra_starts: bool = True  # the baseline also starts from the best of the model's extra_starts
    reestimate_likelihood: bool = True  # the scales again at the baseline's mode (not at the start)
    validation: bool = True  # the validation tests' output error before and after
    detectability: bool = True  # the smallest magnitude of each candidate these tests would name
    #: a search stops when an iteration gains less than this in log L, the Jacobian at its
    #: mode by forward differences (about 35 % fewer runs; 2 ln B moves by < 0.02); None:
    #: scipy's relative ftol 1e-6 and central differences at the mode
    cost_tolerance: float | None = None
    seed: int = 0

    @classmethod
    def quick(cls, **kw) -> "DiscrepancySettings":
        base = dict(
            n_replicates=8,
            max_iterations=30,
            extra_starts=False,
            reestimate_likelihood=False,
            cost_tolerance=0.01,
            detectability=False,
        )
        base.update(kw)
        return cls(**base)


@dataclass
class DiscrepancyResult(NamingVerdict):
    named: list  # effect names, in the order they were named
    rounds: list  # per round: {"base": [...], "candidates": [...]} (JSON-ready)
    baseline: Fit
    final: Fit
    likelihood: object  # of the baseline (unabsorbed model error)
    final_likelihood: object
    gap_before: dict
    gap_after: dict
    effects: dict  # the model's candidate_effects() considered, checked
    start: dict
    timing: dict
    n_model_runs: dict = field(default_factory=dict)
    explains_gap: bool = True
    misfit_ratio: dict = field(default_factory=dict)
    diagnostics_before: dict | None = field(default=None, repr=False)  # the model's diagnose(), if any
    diagnostics_after: dict | None = field(default=None, repr=False)
    signature: dict = field(default_factory=dict)
    problem: Problem | None = field(default=None, repr=False)  # for the figures
    #: effect -> the smallest magnitude these tests would name (bayes_update.core.detectability)
    detectability: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {
            **self.decision_json(),
            "candidate_effects": {
                e: {p.name: {"low": p.low, "high": p.high, "unit": p.unit, "log": p.log, "null": p.null} for p in ps}
                for e, ps in self.effects.items()
            },
            "candidates": self.rounds[0]["candidates"] if self.rounds else [],
            "rounds": self.rounds,
            "gap_before": self.gap_before,
            "gap_after": self.gap_after,
            "signature_check": self.signature,
            "start": self.start,
            "detectable_from": {e: d["detectable_from"] for e, d in self.detectability.items()},
            "detectability": self.detectability,
            "baseline_mode": self.baseline.to_json(self.effects),
            "final_mode": self.final.to_json(self.effects),
            "likelihood": self.likelihood.to_dict(),
            "final_likelihood": self.final_likelihood.to_dict(),
            "timing_s": self.timing,
            "n_model_runs": self.n_model_runs,
        }


def find_discrepancy(
    dataset,
    model,
    *,
    start=None,
    candidates=None,
    settings: DiscrepancySettings | None = None,
    metrics: str | None = None,
    space=None,
    executor=None,
    workers=None,
    progress: bool = False,
    log=info,
) -> DiscrepancyResult:
    """The workflow of the module docstring for ``model`` (any model of the contract
    with ``candidate_effects()``) on ``dataset`` (tests with roles ``linear``,
    ``nonlinear`` and optionally ``validation``), never told what is hidden.

    Parameters
    ----------
    start : {name: value} of the model's parameters (default: the model's own
        ``start`` hook, else the two-stage calibration).
    candidates : effect names to consider (default: all the model offers).
    metrics : the metric set (default: the model's ``default_metrics``, else
        ``full``; :mod:`bayes_update.core.problem`).
    space : the prior of the model's parameters (default: the declared ones).
    """
    settings = settings or DiscrepancySettings()
    steps = StepLog()
    with steps("check_and_screen"):
        # the check before any long step: the contract, the effects, the data set's roles, one run at
        # the nulls (problem_for below finds it done)
        checked = preflight(dataset, model, space, effects=True, candidates=candidates)
    base, effects = checked.space, checked.effects
    names = list(effects) if candidates is None else list(candidates)
    with executor_for(executor, workers) as pool:
        with steps("check_and_screen"):
            problem = problem_for(dataset, model, space, metrics, executor=pool, effects=True)
            steps.add_runs(1 + problem.n_screen_runs)
        flow = DiscrepancyWorkflow(dataset, problem, base, effects, settings, pool, steps, log)
        with steps("start"):
            if start is None:
                seed = int(np.random.SeedSequence(settings.seed).spawn(1)[0].generate_state(1)[0])
                start, n = find_start(
                    dataset,
                    problem,
                    base,
                    n_points=settings.n_start,
                    seed=seed,
                    executor=pool,
                    progress=progress,
                    log=log,
                )
                steps.add_runs(n)
            else:
                base.check(start, "start")
            start = {n: float(start[n]) for n in base.names}
        with steps("baseline"):
            baseline, lik = flow.baseline(start)
        log("baseline: " + ", ".join(f"{k} {100 * v:.3f} %" for k, v in baseline.metrics.items()))
        detectable = {}
        if settings.detectability:
            with steps("detectability"):
                detectable, n = detectability(problem, base, baseline, lik, {e: effects[e] for e in names}, pool)
                steps.add_runs(n)
            log("detectable from: " + "; ".join(f"{e} {d['text']}" for e, d in detectable.items()))
        with steps("naming"):
            current, baseline, rounds, named = flow.name_effects(baseline, lik, names)
        with steps("re_update"):
            final, final_lik = baseline, lik
            if named:
                final_lik = flow.likelihood(current.space, current.theta, settings.seed + 1, unabsorbed=False)
                final = flow.fit(current.names, final_lik, [current.mode.x])
                final_lik = flow.honest(final, final_lik, settings.seed + 1, unabsorbed=False)
                final = flow.fit(current.names, final_lik, [final.mode.x])
        # is the gap closed? (reported, not a condition for naming: a real structure always leaves one)
        # the naming fit on comparison scales, against what noise and the unabsorbed model error leave
        misfit = misfit_ratios(current if named else baseline, lik)
        explains = all(r <= EXPLAINED_FACTOR for r in misfit.values())
        with steps("gap"):
            floors = {t.name: noise_floor(problem, t) for t in problem.validation.values()}
            gap_before = gap(baseline, problem, floors)
            gap_after = gap(final, problem, floors) if named else gap_before
            steps.add_runs(len(problem.validation) * (1 + bool(named)))
            d0 = flow.diagnose(baseline.theta)
            d1 = flow.diagnose(final.theta) if named else d0
            steps.add_runs(len(dataset.tests) * ((d0 is not None) + (d0 is not None and bool(named))))
            signature = signature_changes(problem.model, named, d0, d1, gap_before, gap_after)
    steps.finish()
    log("discrepancy: " + steps.line())
    res = DiscrepancyResult(
        named=named,
        rounds=rounds,
        baseline=baseline,
        final=final,
        likelihood=lik,
        final_likelihood=final_lik,
        gap_before=gap_before,
        gap_after=gap_after,
        effects={e: effects[e] for e in names},
        start=start,
        timing=steps.timing,
        n_model_runs=steps.runs,
        explains_gap=explains,
        misfit_ratio=misfit,
        diagnostics_before=d0,
        diagnostics_after=d1,
        signature=signature,
        problem=problem,
        detectability=detectable,
    )
    log(res.gap_sentence())
    return res
