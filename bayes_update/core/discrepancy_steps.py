"""The steps of the discrepancy workflow over one problem (:class:`DiscrepancyWorkflow`):
the baseline's fit and likelihood, the naming rounds (each candidate effect, then pairs
of them), and the fits, likelihoods and diagnostics that the re-update and the gap
reuse (steps 1-3 and 5 of :mod:`bayes_update.core.discrepancy`'s docstring).

Apart from :func:`~bayes_update.core.discrepancy.find_discrepancy`, which checks the
model, finds the start, orders these steps and reports the result, because this is
the naming itself: fits, Bayes factors and held-out comparisons on a built problem.
"""

from __future__ import annotations

import numpy as np

from bayes_update.core.adjustment import own_points
from bayes_update.core.effects import DECISIVE, ExtendedSpace
from bayes_update.core.fits import (
    Fit,
    best_extra_starts,
    effect_at_bound,
    effect_at_null,
    effect_excludes_null,
    effect_starts,
    failed_fit,
    fit_model,
    names_effect,
    names_pair,
)
from bayes_update.core.held_out import describe, held_out_comparison, held_out_runs
from bayes_update.core.likelihood import errors_at_mode, estimate_likelihood
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.steps import StepLog

__all__ = ["DiscrepancyWorkflow"]


class DiscrepancyWorkflow:
    """The steps of :func:`~bayes_update.core.discrepancy.find_discrepancy` over one problem
    (:mod:`bayes_update.core.discrepancy`'s docstring)."""

    def __init__(self, dataset, problem, base: ParameterSet, effects: dict, settings, pool, steps: StepLog, log):
        self.dataset, self.problem, self.base, self.effects = dataset, problem, base, effects
        self.settings, self.pool, self.steps, self.log = settings, pool, steps, log

    def likelihood(self, space, theta, seed, unabsorbed=True):
        lik = estimate_likelihood(
            self.problem, theta, n_replicates=self.settings.n_replicates, seed=seed, space=space, executor=self.pool
        )
        self.steps.add_runs(lik.n_model_runs)
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
                    **f.metrics,
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
                    **f.metrics,
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
            # the strongest candidate the naming rule accepts (rows are sorted by 2 ln B)
            single = next((r for r in rows if names_effect(r)), None)
            pick, picked = ([single["name"]], fits[single["name"]]) if single is not None else ([], None)
            if (
                best is not None
                and best is not single
                and best["two_ln_B"] is not None
                and best["two_ln_B"] > DECISIVE
                and not best["at_null"]
                and len(named) + 2 <= self.settings.max_effects
            ):
                # the strongest decisive but not named (on a bound, its interval reaching its null under
                # the form error the other effect's missing share leaves, or the held-out tests predicted
                # worse): it may be taking another effect's share as well; a named pair stands against a
                # weaker single candidate the rule accepts on its evidence
                pair_rows, pair_fits = self.pairs(current, best_base, best, rows, fits, lik)
                rounds[-1]["pairs"] = pair_rows
                good = [r for r in pair_rows if r["named"]]
                if good and (single is None or good[0]["two_ln_B"] > single["two_ln_B"]):
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
