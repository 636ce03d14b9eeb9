"""The one check before any long step: what a user can get wrong, found in seconds.

Every command that runs a model calls :func:`preflight` before its long steps
(the data inspection, the noise estimate, the basis fit, the start search):
``bayes-update calibrate``, ``sample`` and ``discrepancy``, and the Python
functions ``bayes_update.calibrate``, ``sample`` and ``find_discrepancy``
(through :func:`bayes_update.core.calibrate.problem_for`).  In order, the
cheapest first:

1. the model's contract without a run
   (:func:`bayes_update.core.model.check_contract`: parameters, the types of
   the optional members, hooks' names misspelt, pickling), and for the
   discrepancy workflow its ``candidate_effects()`` and the candidates asked for;
2. the data set's structure: a test with role ``linear`` and one with role
   ``nonlinear``, each name once (:func:`bayes_update.core.problem.require_roles`;
   each test's channels, lengths and sensors were checked when it was read),
   and the model's own ``check_dataset`` (the beam: its rig);
3. one model run at the middle of the prior (every candidate effect at its
   null) on the linear test's force, its response checked for shape, dtype
   and finiteness (:func:`bayes_update.core.model.check_run`).

The command line calls it itself before its first look at the data
(``OUT/inspection``) and then the Python function, whose own call finds the
same model, data set and prior already checked: a check that passed is kept
(:data:`_PASSED`, keyed by the model's pickled state, the data set's
fingerprint and the prior), so that no check, and above all not the model
run, is made twice.
"""

from __future__ import annotations

import hashlib
import pickle
from collections import OrderedDict
from dataclasses import dataclass, field

from bayes_update.core.effects import candidate_effects
from bayes_update.core.metrics import STAGES
from bayes_update.core.model import check_contract, check_force, check_run, model_label
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.problem import require_roles

__all__ = ["Checked", "preflight"]

#: checks that passed, newest last: key -> :class:`Checked` (a few: a session checks one model at a time)
_PASSED: OrderedDict = OrderedDict()
_KEEP = 8


@dataclass(frozen=True)
class Checked:
    """What :func:`preflight` found: the prior of the run and, for the
    discrepancy workflow, the model's candidate effects (checked)."""

    space: ParameterSet
    effects: dict = field(default_factory=dict)

    @property
    def nulls(self) -> dict:
        """{parameter: the value that switches its effect off} of every candidate effect."""
        return {p.name: p.null for ps in self.effects.values() for p in ps}


def _key(dataset, model, space, effects):
    """What identifies a check: the model's pickled state (a model changed since is
    checked again), the data set's fingerprint and the prior; None for a model
    that does not pickle (the check says so)."""
    try:
        state = pickle.dumps(model)
    except Exception:
        return None
    prior = None if space is None else repr(sorted(space.to_dict().items()))
    return hashlib.sha256(state).hexdigest(), dataset.fingerprint(), prior, effects


def preflight(
    dataset, model, space: ParameterSet | None = None, *, effects: bool = False, candidates=None, store=None
) -> Checked:
    """The checks of the module docstring, for ``model`` on ``dataset`` under the
    prior ``space`` (default: the model's declared parameters); ``effects``: the
    discrepancy workflow's (its candidate effects checked, and ``candidates``,
    the names asked for, among them; the run at their nulls).  Raises
    :class:`~bayes_update.core.model.ModelSpecError` (a
    :class:`~bayes_update.core.model.ModelRunError` for the run),
    :class:`~bayes_update.data.dataset.DatasetError` or ``ValueError``, each
    saying what to fix.  ``store``: the run cache (:class:`~bayes_update.core.runs.RunStore`) the
    check run is kept in and found in."""
    key = _key(dataset, model, space, effects)
    if key is not None and key in _PASSED:
        _PASSED.move_to_end(key)
        _require_candidates(model, _PASSED[key].effects, candidates)
        return _PASSED[key]
    prior = check_contract(model, space)
    checked = Checked(prior, candidate_effects(model, prior.names) if effects else {})
    _require_candidates(model, checked.effects, candidates)
    require_roles(dataset, STAGES)
    if callable(getattr(model, "check_dataset", None)):
        model.check_dataset(dataset)  # the model's own word on the data (the beam: its rig)
    # the middle of the prior as the internal coordinates give it, to the bit: the point the linear
    # screen runs first (calibrate.screen_linear), which then finds this run in the store
    middle = prior.to_parameters(prior.to_internal(prior.center()))
    check_run(
        model,
        prior,
        check_force(model, dataset),
        dataset.sampling_rate_hz,
        len(dataset.sensors),
        {**middle, **checked.nulls},
        store=store,
    )
    if key is not None:
        _PASSED[key] = checked
        while len(_PASSED) > _KEEP:
            _PASSED.popitem(last=False)
    return checked


def _require_candidates(model, effects: dict, candidates) -> None:
    """``candidates`` (effect names asked for; None: all) among the model's ``effects``."""
    unknown = [n for n in candidates or () if n not in effects]
    if unknown:
        raise ValueError(f"unknown candidate effect(s) {unknown}; {model_label(model)} offers {sorted(effects)}")
