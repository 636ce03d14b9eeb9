"""Candidate effects of a model of the contract, and the rules that name one.

A model offers effects it may be missing through the optional member
``candidate_effects() -> {effect: [Parameter(..., null=value), ...]}``: each
effect's parameters carry the ``null`` value that switches the effect off, and
``simulate(theta, force, fs)`` accepts their names in ``theta``.  This module
reads that declaration (:func:`candidate_effects`), runs a model with every
effect not under test at its null (:class:`WithNulls`), and spans the
parameters of the baseline plus the added effects (:class:`ExtendedSpace`).

The naming rules of the discrepancy workflow
(:mod:`bayes_update.core.discrepancy`) live here too: :data:`DECISIVE`,
:data:`EXPLAINED_FACTOR`, :func:`misfit_allowance`, :func:`misfit_ratios` and
the evidence table.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from bayes_update.core.held_out import describe
from bayes_update.core.metrics import metric_key
from bayes_update.core.model import ModelSpecError
from bayes_update.core.parameters import Parameter, ParameterSet

__all__ = [
    "DECISIVE",
    "EXPLAINED_FACTOR",
    "ExtendedSpace",
    "WithNulls",
    "candidate_effects",
    "evidence_table",
    "misfit_allowance",
    "misfit_ratios",
]

#: 2 ln B above which the evidence is called decisive (Kass and Raftery 1995: > 6 "strong", > 10 "very strong")
DECISIVE = 6.0
#: The gap is closed when e_lin and e_nlin at the model's mode are each at most this
#: many times :func:`misfit_allowance` (noise and unabsorbed model error): reported
#: beside the named effects, not a condition for naming them (a model of a real
#: structure always leaves a gap).  Under noise alone e^2 / allowance^2 is about
#: chi^2_nu / nu: beyond 3^2 with probability 0.27 % for nu = 1, 1e-4 for nu = 2.
EXPLAINED_FACTOR = 3.0


def misfit_allowance(lik) -> dict:
    """{e_lin, e_nlin: the misfit noise and model error leave at a model's mode}:
    sqrt(mean e^2 over the noise replicates + e_model_unabsorbed^2).  The
    replicates' mean e^2 counts the noise in every direction of the stage's
    output (the parameters take up part of it at the mode, so this is an
    upper expectation); of the model error only the part no parameter change
    can take up remains at the mode."""
    out = {}
    for st, sc in lik.scales.items():
        me = sc.model_error_unabsorbed if sc.model_error_unabsorbed is not None else sc.model_error
        out[metric_key(st)] = math.sqrt(sc.noise_mean_square + me**2)
    return out


def misfit_ratios(fit, lik) -> dict:
    """{e_lin, e_nlin: the fit's misfit (``fit.metrics``) over :func:`misfit_allowance`}."""
    allow = misfit_allowance(lik)
    return {k: float(fit.metrics[k] / allow[k]) for k in allow}


def candidate_effects(model, base_names=()) -> dict:
    """``{effect: (Parameter, ...)}`` of ``model.candidate_effects()``, checked.

    Raises :class:`ModelSpecError` (saying what to add or fix) when the model
    has no ``candidate_effects``, a parameter is not a :class:`Parameter` or
    has no ``null``, or a name is used twice (also against ``base_names``)."""
    kind = type(model).__name__
    if not callable(getattr(model, "candidate_effects", None)):
        raise ModelSpecError(
            f"{kind} has no candidate_effects(): the discrepancy workflow needs it; add a method "
            "candidate_effects(self) -> {effect_name: [Parameter(..., null=value), ...]} whose parameters "
            "simulate(theta, force, fs) accepts (docs/models.md)"
        )
    effects = model.candidate_effects()
    if not isinstance(effects, Mapping) or not effects:
        raise ModelSpecError(
            f"{kind}.candidate_effects() must return a non-empty dict "
            f"{{effect_name: [Parameter, ...]}}, got {effects!r}"
        )
    seen = set(base_names)
    out = {}
    for name, params in effects.items():
        params = tuple(params) if not isinstance(params, Parameter) else (params,)
        if not isinstance(name, str) or not name or not params:
            raise ModelSpecError(f"{kind}.candidate_effects(): effect {name!r} needs a name and at least one Parameter")
        for p in params:
            if not isinstance(p, Parameter):
                raise ModelSpecError(f"{kind}.candidate_effects()[{name!r}]: {p!r} is not a bayes_update.Parameter")
            if p.null is None:
                raise ModelSpecError(
                    f"{kind}.candidate_effects()[{name!r}]: parameter {p.name!r} has no null value; give "
                    f"Parameter({p.name!r}, {p.low!r}, {p.high!r}, ..., null=<the value that switches the "
                    "effect off>)"
                )
            if p.name in seen:
                raise ModelSpecError(
                    f"{kind}.candidate_effects()[{name!r}]: parameter name {p.name!r} is "
                    "already used (by the model's parameters or another effect)"
                )
            seen.add(p.name)
        out[name] = params
    return out


class WithNulls:
    """A model that passes every candidate parameter not in ``theta`` at its
    null value: the baseline is the model with all effects off.  Every other
    member is the wrapped model's (its hooks, units, metric set), and
    ``refined()`` wraps the wrapped model's refined one."""

    wraps_model = True  # messages name the wrapped model (bayes_update.core.model.model_label)

    def __init__(self, model, nulls: Mapping):
        self.model, self.nulls = model, dict(nulls)

    def simulate(self, theta, force, fs):
        return self.model.simulate({**self.nulls, **theta}, force, fs)

    def __getattr__(self, name):
        model = self.__dict__.get("model")
        if model is None or name.startswith("__"):
            raise AttributeError(name)
        if name == "refined" and hasattr(model, "refined"):
            return lambda: WithNulls(model.refined(), self.nulls)
        return getattr(model, name)


class ExtendedSpace:
    """The baseline's :class:`ParameterSet` plus the added effects' parameters.

    Coordinates x = (the baseline's internal coordinates, then each added
    parameter's: its value, or its natural log when ``log``).  What the
    likelihood's bootstrap and the mode search need: ``box``,
    ``to_internal``, ``to_parameters``."""

    def __init__(self, base: ParameterSet, added=()):
        self.base = base
        self.added = tuple(added)
        self.effects = ParameterSet(self.added) if self.added else None
        self.names = base.names + tuple(p.name for p in self.added)
        self.n_base = len(base)

    def __len__(self) -> int:
        return len(self.names)

    def box(self) -> np.ndarray:
        return self.base.box() if self.effects is None else np.vstack([self.base.box(), self.effects.box()])

    def widths(self) -> np.ndarray:
        b = self.box()
        return b[:, 1] - b[:, 0]

    def to_internal(self, theta) -> np.ndarray:
        x = self.base.to_internal(theta)
        return x if self.effects is None else np.concatenate([x, self.effects.to_internal(theta)])

    def to_parameters(self, x) -> dict:
        x = np.asarray(x, float)
        theta = self.base.from_internal(x[: self.n_base])
        if self.effects is not None:
            theta.update(self.effects.from_internal(x[self.n_base :]))
        return theta

    from_internal = to_parameters

    def null_internal(self) -> np.ndarray:
        """The added parameters' null values in internal coordinates."""
        return self.effects.to_internal({p.name: p.null for p in self.added})

    def log_prior_density(self, x) -> float:
        """Normalised log prior density at internal point x: the baseline's
        (:meth:`ParameterSet.log_normalised_prior`) and a uniform density per
        added coordinate."""
        x = np.asarray(x, float)
        lp = self.base.log_normalised_prior(x[: self.n_base])
        return lp - float(np.sum(np.log(self.widths()[self.n_base :])))

    def values(self, x, cov) -> dict:
        """{added parameter: mode, sd, Laplace interval (mode +- 2 sd), null, unit} in
        the parameter's unit (the sd of a log-scale one is mode x its log's sd)."""
        sd = np.sqrt(np.diag(cov))
        out = {}
        for i, p in enumerate(self.added, start=self.n_base):
            lo, hi = x[i] - 2 * sd[i], x[i] + 2 * sd[i]
            if p.log:
                m = math.exp(x[i])
                out[p.name] = {
                    "mode": m,
                    "sd": m * float(sd[i]),
                    "interval": [math.exp(lo), math.exp(hi)],
                    "null": p.null,
                    "unit": p.unit,
                    "prior": [p.low, p.high],
                    "log": True,
                }
            else:
                out[p.name] = {
                    "mode": float(x[i]),
                    "sd": float(sd[i]),
                    "interval": [float(lo), float(hi)],
                    "null": p.null,
                    "unit": p.unit,
                    "prior": [p.low, p.high],
                }
        return out


def evidence_table(res) -> str:
    """Markdown table of every round's candidates and the decision (``res``: a
    discrepancy result with ``rounds``, ``named``, ``explains_gap``,
    ``misfit_ratio``, ``verdict`` and ``gap_sentence()``)."""
    lines = []
    for i, rnd in enumerate(res.rounds):
        base = " + ".join(["baseline"] + rnd["base"])
        lines += [
            f"Round {i + 1}: candidates added to {base}",
            "",
            "| candidate | 2 ln B | gain in log L | fitted effect parameters (mode +- Laplace sd) | excludes null "
            "| held-out error per test, before -> after (gain in sd of its noise) | note |",
            "|---|---|---|---|---|---|---|",
        ]
        for c in rnd["candidates"]:
            pars = ", ".join(f"{k} = {v['mode']:.4g} +- {v['sd']:.2g} {v['unit']}" for k, v in c["parameters"].items())
            held = c.get("held_out")
            lines.append(
                f"| {c['name']} | {_two_ln_b(c)} | {c['delta_log_likelihood']:.1f} | {pars} | "
                f"{'yes' if c['excludes_null'] else 'no'} | {describe(held)} | {_note(c)} |"
            )
        lines.append("")
        if rnd.get("pairs"):
            lines += [
                "The strongest candidate on a bound of its prior, fitted with each other decisive one:",
                "",
                "| pair | 2 ln B | partner alone | members (mode +- Laplace sd; where) | held-out error per test "
                "(gain in sd) | named |",
                "|---|---|---|---|---|---|",
            ]
            for c in rnd["pairs"]:
                members = "; ".join(
                    ", ".join(f"{k} = {v['mode']:.4g} +- {v['sd']:.2g} {v['unit']}" for k, v in m["parameters"].items())
                    + (" (at its null)" if m["at_null"] else " (on a bound)" if m["at_bound"] else "")
                    for m in c["members"].values()
                )
                held = c.get("held_out")
                lines.append(
                    f"| {' + '.join(c['names'])} | {c['two_ln_B']:.1f} | {c['partner_alone']:.1f} | "
                    f"{members} | {describe(held)} | "
                    f"{'yes' if c['named'] else 'no'} |"
                )
            lines.append("")
    if getattr(res, "detectability", None):
        lines += [
            "What these tests would name (linearised about the baseline, `bayes_update.core.detectability`):",
            "",
            "| candidate | detectable from |",
            "|---|---|",
        ]
        for e, d in res.detectability.items():
            lines.append(f"| {e} | {d['text']} |")
        lines.append("")
    lines.append(f"Named: **{', '.join(res.named) or 'none'}** (rule: {NAMING_RULE})")
    lines.append(f"Verdict: {res.verdict}. {res.gap_sentence()}")
    return "\n".join(lines)


#: the naming rule in words (the evidence table and discrepancy.json)
NAMING_RULE = (
    f"2 ln B > {DECISIVE:g} against the model without it, each at its own optimum and under the noise "
    "and the model-form error its own mode leaves; the effect's mode more than 2 Laplace sd from its null "
    "value, neither at its null nor on a bound of its prior, the fit not failed; and the held-out "
    "(validation) tests predicted better, by more than 3 sd of what their noise could give, and none of "
    "them worse by more than 3 sd of its own and 3 % of its error (nor one it cannot run); the strongest "
    "candidate the rule accepts is named, or a pair with the strongest candidate when that one is decisive "
    "but not accepted and the pair is decisive against each member alone and stronger"
)


def _two_ln_b(row) -> str:
    return "failed fit" if row.get("failed_fit") else f"{row['two_ln_B']:.1f}"


def _note(row) -> str:
    if row.get("failed_fit"):
        return "the fit ended below the model without it, twice: not evidence"
    if row.get("at_null"):
        return "fitted at its null value" + (
            " (the data pin it there: its Occam factor)" if row["two_ln_B"] < -DECISIVE else ""
        )
    if row.get("at_bound"):
        return "on a bound of its prior"
    held = row.get("held_out")
    if row["two_ln_B"] > DECISIVE and held is not None and not held["improves"]:
        worse = held.get("worse", [])
        return (
            "decisive, but the held-out tests are not predicted better"
            if not worse
            else f"decisive, but it predicts {', '.join(worse)} worse"
        )
    return ""


class NamingVerdict:
    """What a discrepancy result says about naming: a dataclass with ``named``,
    ``explains_gap``, ``misfit_ratio`` and ``gap_after`` inherits these."""

    @property
    def named_effect(self):
        return self.named[0] if self.named else None

    @property
    def verdict(self) -> str:
        """ "named", "no missing effect" (the baseline explains the data) or "no
        candidate explains the gap"."""
        if self.named:
            return "named"
        return "no missing effect" if self.explains_gap else "no candidate explains the gap"

    def gap_remaining(self) -> dict:
        """What the model (with the named effects) still leaves: e_lin and e_nlin over what
        noise and model error allow, and the held-out tests' error beyond their noise and
        over the noise's own."""
        g = self.gap_after
        out = {"misfit_ratio": dict(self.misfit_ratio), "closed": bool(self.explains_gap)}
        if g.get("held_out_relative_error") is not None:
            floor = g.get("held_out_noise_floor") or 0.0
            out.update(
                held_out_error_beyond_noise=g["held_out_error_beyond_noise"],
                held_out_relative_error=g["held_out_relative_error"],
                held_out_times_noise=g["held_out_relative_error"] / floor if floor > 0 else None,
            )
        if g.get("held_out_cannot_run"):
            out["held_out_cannot_run"] = list(g["held_out_cannot_run"])
        return out

    def gap_sentence(self) -> str:
        """One sentence: what is named, and the gap that remains, as numbers."""
        r = self.gap_remaining()
        ratios = ", ".join(f"{k} {v:.2g}x" for k, v in r["misfit_ratio"].items())
        held = ""
        if r.get("held_out_relative_error") is not None:
            times = r.get("held_out_times_noise")
            held = (
                f"; the held-out tests' error is {100 * r['held_out_relative_error']:.3g} %, "
                f"{100 * r['held_out_error_beyond_noise']:.3g} % beyond their noise"
                + (f" ({times:.2g} times the noise's)" if times is not None else "")
            )
        if r.get("held_out_cannot_run"):
            held += f"; it cannot run {', '.join(r['held_out_cannot_run'])} (diverges; not in these numbers)"
        what = "with " + (" + ".join(self.named) if self.named else "the baseline alone")
        if r["closed"]:
            return f"The gap is closed {what}: misfit {ratios} what noise and model error allow{held}."
        return (
            f"A gap remains {what}: misfit {ratios} what noise and model error allow{held}: "
            "something outside the catalogue (or outside the model's form)"
        )

    def decision_json(self) -> dict:
        return {
            "named": list(self.named),
            "named_effect": self.named_effect,
            "verdict": self.verdict,
            "explains_gap": bool(self.explains_gap),
            "misfit_ratio": self.misfit_ratio,
            "explained_factor": EXPLAINED_FACTOR,
            "gap_remaining": self.gap_remaining(),
            "gap_sentence": self.gap_sentence(),
            "decision_rule": NAMING_RULE,
        }
