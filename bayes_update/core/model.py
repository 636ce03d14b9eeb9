"""The model contract, the loader of ``--model SPEC``, and the check run before any heavy work.

A model is any picklable object with

* ``parameters``: a sequence of :class:`bayes_update.Parameter`;
* ``simulate(theta, force, fs) -> response``: ``theta`` maps every parameter
  name to a value in its unit, ``force`` is the sampled input (n,) at ``fs``
  [Hz], the response has shape (n,) or (n, n_sensors).  Outside what it can
  run, it raises an exception (never returns NaN).

Optional members, each used when present (docs/models.md says what happens
when absent):

* ``refined()``: a finer model of the same physics (the model-error term);
* ``candidate_effects()``: effects the model may miss (the discrepancy workflow);
* ``to_internal`` / ``from_internal`` / ``log_jacobian`` (and
  ``internal_names``, ``internal_units``): a reparameterisation the
  inference samples in (:class:`~bayes_update.core.parameters.ParameterSet`);
* ``default_metrics``: the metric set when none is asked for (``"full"``);
* ``response_kind``, ``response_unit``: what the sensors measure, when the
  data set does not say;
* ``start(dataset, executor, progress) -> (theta, model runs)``: the model's
  own start search (default: :mod:`bayes_update.core.calibrate`);
* ``extra_starts(x) -> [x, ...]``: more internal points the mode search
  starts from;
* ``diagnose(dataset, theta, basis) -> dict``, ``signature(effect, diagnostics,
  gap)`` and ``diagnostics_figure(diagnostics)``: model-specific diagnostics of
  the discrepancy workflow, the number each effect's physics should shrink,
  and their figure;
* ``describe() -> dict``: what identifies the model in a cache key and a report;
* ``check_dataset(dataset)``: raise ``ValueError`` (saying what to fix) for a
  data set the model cannot be compared with (the beam: another rig).

:func:`check_contract` checks all of this without running the model (a
member of the wrong type, a name one letter off a hook's, a model that does
not pickle); :func:`check_model` adds one run, whose response goes through
the same :func:`check_response` as every later run.

The code lives apart by job: :mod:`bayes_update.core.model_errors` (the errors
and the words of their messages), :mod:`bayes_update.core.model_loader` (the
loader) and :mod:`bayes_update.core.model_checks` (the checks).  This module
states the contract (:class:`Model`) and is the one entry every importer uses.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Protocol, runtime_checkable

import numpy as np

from bayes_update.core.model_checks import (
    CALLABLE_HOOKS,
    VALUE_HOOKS,
    check_contract,
    check_force,
    check_model,
    check_model_on,
    check_response,
    check_run,
)
from bayes_update.core.model_errors import (
    ModelError,
    ModelRunError,
    ModelSpecError,
    describe_theta,
    model_label,
    run_error,
    unwrapped,
)
from bayes_update.core.model_loader import BUILTIN_MODELS, load_model
from bayes_update.core.parameters import Parameter

__all__ = [
    "BUILTIN_MODELS",
    "CALLABLE_HOOKS",
    "VALUE_HOOKS",
    "Model",
    "ModelError",
    "ModelRunError",
    "ModelSpecError",
    "check_contract",
    "check_force",
    "check_model",
    "check_model_on",
    "check_response",
    "check_run",
    "describe_theta",
    "load_model",
    "model_label",
    "run_error",
    "unwrapped",
]


@runtime_checkable
class Model(Protocol):
    """What the framework needs of a model (see the module docstring)."""

    parameters: Sequence[Parameter]

    def simulate(self, theta: Mapping[str, float], force: np.ndarray, fs: float) -> np.ndarray: ...
