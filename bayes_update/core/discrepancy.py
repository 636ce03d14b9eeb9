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
   held-out tests are predicted better beyond their noise, none of them worse; then a next round
   looks for a second effect (``max_effects``).  When the strongest candidate
   is decisive but not named (on a bound of its prior, or predicting the
   held-out tests worse), it may be taking another effect's share as well:
   it is fitted together with each other candidate, and a pair is named when
   it is decisive against each member alone and both members sit inside their
   priors, away from their nulls (:func:`~bayes_update.core.fits.names_pair`);
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

from bayes_update.core.adjustment import own_points
from bayes_update.core.calibrate import find_start, problem_for
from bayes_update.core.detectability import detectability
from bayes_update.core.effects import DECISIVE, EXPLAINED_FACTOR, ExtendedSpace, NamingVerdict, misfit_ratios
from bayes_update.core.fits import (
    Fit,
    best_extra_starts,
    effect_at_bound,
    effect_at_null,
    effect_excludes_null,
    effect_starts,
    failed_fit,
    fit_model,
    gap,
    names_effect,
    names_pair,
    noise_floor,
    signature_changes,
)
from bayes_update.core.held_out import describe, held_out_comparison, held_out_runs
from bayes_update.core.likelihood import errors_at_mode, estimate_likelihood, likelihood_runs
from bayes_update.core.logs import info
from bayes_update.core.parameters import ParameterSet
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


# ---------------------------------------------------------------- the workflow
class _Workflow:
    """The steps of :func:`find_discrepancy` over one problem (module docstring)."""

    def __init__(self, dataset, problem, base: ParameterSet, effects: dict, settings, pool, steps: StepLog, log):
        self.dataset, self.problem, self.base, self.effects = dataset, problem, base, effects
        self.settings, self.pool, self.steps, self.log = settings, pool, steps, log

    def likelihood(self, space, theta, seed, unabsorbed=True):
        lik = estimate_likelihood(
            self.problem, theta, n_replicates=self.settings.n_replicates, seed=seed, space=space, executor=self.pool
        )
        self.steps.add_runs(likelihood_runs(self.problem, self.settings.n_replicates, space))
        return lik.unabsorbed() if unabsorbed else lik

    def honest(self, fit: Fit, lik, seed, unabsorbed=True):
        """``lik`` with the model errors measured at ``fit``'s mode: the discretisation's and
        the model-form error (:func:`~bayes_update.core.likelihood.errors_at_mode`), so that no
        model's misfit beyond the noise counts as evidence for an effect: what the baseline
        leaves that no candidate explains widens every model's likelihood alike."""
        problem = self.problem
        sizes = [problem.output(st, problem.reference_components(st)).size for st in problem.stages]
        own = own_points(fit.mode.jacobian, fit.mode.residual, sizes, fit.mode.x, fit.space.box())
        new = errors_at_mode(
            problem,
            lik,
            fit.theta,
            fit.mode.residual,
            fit.mode.jacobian,
            executor=self.pool,
            seed=seed,
            own_points={st: fit.space.to_parameters(x) for st, x in zip(problem.stages, own)},
        )
        if new is not lik:
            self.steps.add_runs(len(problem.stages) * (2 + (problem.refined_model() is not None)))
        return new.unabsorbed() if unabsorbed else new

    def fit(self, added, lik, starts, iterations=None) -> Fit:
        space = ExtendedSpace(self.base, [p for e in added for p in self.effects[e]])
        f = fit_model(self.problem, space, added, lik, starts, self.settings, self.pool, iterations)
        self.steps.add_runs((f.mode.n_evaluations + 1) * len(self.problem.stages))  # + its score's run
        return f

    def baseline(self, start) -> tuple[Fit, object]:
        s = self.settings
        b = self.base.box()
        x0 = np.clip(self.base.to_internal(start), b[:, 0], b[:, 1])
        space0 = ExtendedSpace(self.base)
        lik = self.likelihood(space0, self.base.to_parameters(x0), s.seed)
        starts = [x0]
        if s.extra_starts:
            extra, n = best_extra_starts(self.problem, space0, lik, x0, self.pool)
            starts += extra
            self.steps.add_runs(n)
        fit = self.fit([], lik, starts)
        if s.reestimate_likelihood:  # the scales at the baseline's mode, not at the start
            lik = self.likelihood(space0, fit.theta, s.seed)
            fit = self.fit([], lik, [fit.mode.x])
        lik = self.honest(fit, lik, s.seed)
        fit = self.fit([], lik, [fit.mode.x])
        self.log(
            "baseline's likelihood: "
            + "; ".join(
                f"{st} noise {100 * sc.noise_sd:.3f} %, model form {100 * sc.model_form_sd:.3f} %, model error "
                f"{100 * sc.model_error:.3f} % per direction"
                for st, sc in lik.scales.items()
            )
        )
        return fit, lik

    def round(self, current: Fit, remaining, lik) -> tuple[Fit, list, dict]:
        """Each remaining effect added to ``current`` and fitted; the model without it
        re-converged from each extended fit's own base parameters (with the same
        effort) so that the Bayes factor compares both models at their optima: what
        re-converging the base parameters gains is not credited to an effect.
        Returns (the best model without the effects, the evidence rows, the fits)."""
        fits, base_fits = {}, [current]
        box = current.space.box()
        width = box[:, 1] - box[:, 0]
        n = len(current.mode.x)
        for e in remaining:
            k = len(self.effects[e])
            trial = ExtendedSpace(self.base, list(current.space.added) + list(self.effects[e]))
            # the effect at its null is one of the starts: the model with the effect contains the
            # model without it, so its fit can end no worse than where the baseline is
            starts = [
                np.concatenate([current.mode.x, v])
                for v in effect_starts(trial, k, self.settings.effect_start) + [trial.null_internal()[-k:]]
            ]
            f = fits[e] = self.fit(current.names + [e], lik, starts)
            if np.any(np.abs(f.mode.x[:n] - current.mode.x) > 1e-3 * width):
                base_fits.append(self.fit(current.names, lik, [f.mode.x[:n]]))
        best_base = min(base_fits, key=lambda fit: fit.mode.cost)
        if best_base is not current:
            self.log(
                f"  the model without the candidates re-converged from a candidate's base parameters: "
                f"-log L {current.mode.cost:.1f} -> {best_base.mode.cost:.1f} (the comparisons use it)"
            )
        for e, f in fits.items():
            if failed_fit(f, best_base):
                # a nested fit that ended below the model without it has not found its optimum: once more
                # from that model's mode with the effect at its null, with twice the iterations
                k = len(self.effects[e])
                fits[e] = self.fit(
                    current.names + [e],
                    lik,
                    [np.concatenate([best_base.mode.x, f.space.null_internal()[-k:]]), f.mode.x],
                    iterations=2 * self.settings.max_iterations,
                )
        held = self.held_out([best_base] + list(fits.values()))
        rows = []
        for (e, f), h in zip(fits.items(), held[1:]):
            k = len(self.effects[e])
            failed = failed_fit(f, best_base)
            two_ln_b = None if failed else 2.0 * (f.log_evidence - best_base.log_evidence)
            values = f.space.values(f.mode.x, f.covariance)
            values = {p.name: values[p.name] for p in self.effects[e]}
            rows.append(
                {
                    "name": e,
                    "two_ln_B": two_ln_b,
                    "failed_fit": failed,
                    "delta_log_likelihood": float(best_base.mode.cost - f.mode.cost),
                    "n_parameters": k,
                    "parameters": values,
                    "excludes_null": effect_excludes_null(f, k),
                    "at_null": effect_at_null(f, k),
                    "at_bound": effect_at_bound(f, k),
                    "e_lin": f.metrics["e_lin"],
                    "e_nlin": f.metrics["e_nlin"],
                    "held_out": held_out_comparison(self.problem, held[0], h),
                }
            )
            flag = (
                " (at its null value)"
                if rows[-1]["at_null"]
                else " (on a bound of its prior)"
                if rows[-1]["at_bound"]
                else ""
            )
            self.log(
                f"  {e}: "
                + ("FAILED FIT (ends below the model without it)" if failed else f"2 ln B = {two_ln_b:.1f}{flag}")
                + ", "
                + ", ".join(f"{n} = {v['mode']:.4g} +- {v['sd']:.2g} {v['unit']}" for n, v in values.items())
                + ("" if rows[-1]["held_out"] is None else f"; held-out {describe(rows[-1]['held_out'])}")
            )
        rows.sort(key=lambda r: -np.inf if r["two_ln_B"] is None else -r["two_ln_B"])
        return best_base, rows, fits

    def held_out(self, fits) -> list:
        """Each fit's responses on the validation tests (one run per test and fit)."""
        self.steps.add_runs(len(self.problem.validation) * len(fits))
        return held_out_runs(self.problem, [f.theta for f in fits], self.pool)

    def pairs(self, current: Fit, best_base: Fit, first: dict, rows: list, fits: dict, lik) -> tuple[list, dict]:
        """``first`` (a decisive candidate not named: on a bound of its prior, or
        predicting the held-out tests worse) fitted together with
        each other candidate whose own fit did not fail: an effect on a bound may be
        taking another's share as well (a damper asked to carry a bow too).  The
        partner need not be decisive alone: scored under the model-form error that
        ``first``'s missing share leaves, a real second effect can look like nothing
        (the bow of a beam that also has a damper: 2 ln B -7 alone, named in the
        pair); the pair must then beat both members alone
        (:func:`~bayes_update.core.fits.names_pair`).  The pair starts from the
        partner's own fit with ``first`` near its null, and from ``first``'s fit with
        the partner near its null.  Returns (the pair rows, and their fits by
        (first, partner))."""
        e1, n = first["name"], len(current.mode.x)
        k1 = len(self.effects[e1])
        out, pair_fits = [], {}
        for row in rows:
            e2 = row["name"]
            if e2 == e1 or row["two_ln_B"] is None:
                continue
            k2 = len(self.effects[e2])
            trial = ExtendedSpace(
                self.base, list(current.space.added) + list(self.effects[e1]) + list(self.effects[e2])
            )
            x2 = fits[e2].mode.x
            starts = [
                np.concatenate([x2[:n], v, x2[n:]])
                for v in effect_starts(
                    ExtendedSpace(self.base, list(current.space.added) + list(self.effects[e1])),
                    k1,
                    self.settings.effect_start,
                )
            ]
            starts.append(np.concatenate([x2[:n], fits[e1].mode.x[n:], x2[n:]]))
            starts.append(np.concatenate([x2[:n], fits[e1].space.null_internal()[-k1:], x2[n:]]))  # = the partner's fit
            starts += [
                np.concatenate([fits[e1].mode.x, v]) for v in effect_starts(trial, k2, self.settings.effect_start)
            ]
            f = pair_fits[(e1, e2)] = self.fit(current.names + [e1, e2], lik, starts)
            values = f.space.values(f.mode.x, f.covariance)
            members = {
                e: {
                    "excludes_null": effect_excludes_null(f, k, end),
                    "at_null": effect_at_null(f, k, end),
                    "at_bound": effect_at_bound(f, k, end),
                    "parameters": {p.name: values[p.name] for p in self.effects[e]},
                }
                for e, k, end in ((e1, k1, n + k1), (e2, k2, None))
            }
            before, after = self.held_out([best_base, f])
            out.append(
                {
                    "names": [e1, e2],
                    "two_ln_B": 2.0 * (f.log_evidence - best_base.log_evidence),
                    "partner_alone": row["two_ln_B"],
                    "members": members,
                    "e_lin": f.metrics["e_lin"],
                    "e_nlin": f.metrics["e_nlin"],
                    "held_out": held_out_comparison(self.problem, before, after),
                }
            )
            out[-1]["named"] = names_pair(out[-1], row["two_ln_B"], first["two_ln_B"])
            flags = "; ".join(
                f"{e} " + ("at its null" if m["at_null"] else "on a bound" if m["at_bound"] else "inside its prior")
                for e, m in members.items()
            )
            self.log(f"  {e1} + {e2}: 2 ln B = {out[-1]['two_ln_B']:.1f} ({e2} alone {row['two_ln_B']:.1f}); {flags}")
        out.sort(key=lambda r: -r["two_ln_B"])
        return out, pair_fits

    def name_effects(self, baseline: Fit, lik, names) -> tuple[Fit, Fit, list, list]:
        """Rounds of naming; returns (the model with the named effects, the baseline
        as re-converged in the first round, the rounds, the named effects)."""
        current, rounds, named, remaining = baseline, [], [], list(names)
        while len(named) < self.settings.max_effects and remaining:
            best_base, rows, fits = self.round(current, remaining, lik)
            if not rounds:
                baseline = best_base
            current = best_base
            rounds.append({"base": list(current.names), "candidates": rows})
            best = rows[0] if rows else None
            pick, picked = [], None
            if best is not None and names_effect(best):
                pick, picked = [best["name"]], fits[best["name"]]
            elif (
                best is not None
                and best["two_ln_B"] is not None
                and best["two_ln_B"] > DECISIVE
                and not best["at_null"]
                and len(named) + 2 <= self.settings.max_effects
            ):
                # decisive but not named (on a bound, its interval reaching its null under the form error
                # the other effect's missing share leaves, or the held-out tests predicted worse): it may be
                # taking another effect's share as well
                pair_rows, pair_fits = self.pairs(current, best_base, best, rows, fits, lik)
                rounds[-1]["pairs"] = pair_rows
                good = [r for r in pair_rows if r["named"]]
                if good:
                    pick, picked = good[0]["names"], pair_fits[tuple(good[0]["names"])]
            if not pick:
                break
            named += pick
            for e in pick:
                remaining.remove(e)
            current = picked
            if len(named) < self.settings.max_effects and remaining:
                # polish the named fit (it started from the baseline's mode): the next round must
                # not name a second effect for what this one's unfinished fit left over
                current = self.fit(current.names, lik, [current.mode.x])
            self.log(f"named: {' + '.join(pick)}")
        return current, baseline, rounds, named

    def diagnose(self, theta) -> dict | None:
        diagnose = getattr(self.problem.model, "diagnose", None)
        return diagnose(self.dataset, theta, self.problem.basis) if callable(diagnose) else None


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
        flow = _Workflow(dataset, problem, base, effects, settings, pool, steps, log)
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
        log(f"baseline: e_lin {100 * baseline.metrics['e_lin']:.3f} %, e_nlin {100 * baseline.metrics['e_nlin']:.3f} %")
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
