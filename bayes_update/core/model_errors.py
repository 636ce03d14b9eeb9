"""The errors of a model and the words their messages name it with.

:class:`ModelError` (where a model cannot run), :class:`ModelSpecError` (a
spec or model the framework cannot use), :class:`ModelRunError` (a run that
breaks the contract), and :func:`model_label`, :func:`describe_theta`,
:func:`run_error` that every such message is written with.  They sit apart
from the loader (:mod:`bayes_update.core.model_loader`) and the checks
(:mod:`bayes_update.core.model_checks`), which both raise them; the contract
itself and the public entry are :mod:`bayes_update.core.model`.
"""

from __future__ import annotations

from collections.abc import Mapping


class ModelError(RuntimeError):
    """Raised by a model's ``simulate`` where it cannot run (the parameters lie
    where the model diverges, buckles, ...).  The framework gives such a point
    NaN metrics and goes on; any other exception stops the run."""


class ModelSpecError(ValueError):
    """A ``--model`` spec or a model object that the framework cannot use; the
    message says what to fix."""


class ModelRunError(ModelSpecError):
    """A model run that breaks the contract after the check run: ``simulate``
    raised an exception other than :class:`ModelError` (a bug), or returned
    non-finite values or the wrong shape.  It stops the run; the message names
    the model, the theta (each parameter with its unit) and what to do.  It
    carries the message alone, so that it pickles from a worker process."""


#: what to do where a model cannot run (the end of every :class:`ModelRunError`)
RUN_REMEDY = (
    "where the model cannot run, raise bayes_update.ModelError (that point then gets no "
    "likelihood and the run goes on); never return NaN"
)


def unwrapped(model):
    """The user's model inside the framework's wrappers (a class with
    ``wraps_model = True`` holds it as ``.model``)."""
    while getattr(type(model), "wraps_model", False):
        model = model.model
    return model


def model_label(model) -> str:
    """The class name of ``model`` (of the model inside the framework's wrappers)."""
    return type(unwrapped(model)).__name__


def _units_of(model) -> dict:
    units = {}
    try:
        for p in getattr(model, "parameters", ()) or ():
            units[p.name] = getattr(p, "unit", "")
        effects = getattr(model, "candidate_effects", None)
        for ps in (effects() if callable(effects) else {}).values():
            for p in ps:
                units.setdefault(p.name, getattr(p, "unit", ""))
    except Exception:  # only for a message: a model that cannot say gets its values without units
        pass
    return units


def describe_theta(model, theta) -> str:
    """``fn = 33.4 Hz, zeta = 0.0271``: each parameter of ``theta`` with its unit
    (declared in the model's ``parameters`` or ``candidate_effects()``)."""
    if not isinstance(theta, Mapping):
        return repr(theta)
    units = _units_of(model)
    parts = []
    for name, value in theta.items():
        try:
            text = f"{float(value):.6g}"
        except (TypeError, ValueError):
            text = repr(value)
        unit = units.get(name, "")
        parts.append(f"{name} = {text} {unit}" if unit else f"{name} = {text}")
    return "{" + ", ".join(parts) + "}"


def run_error(model, theta, what: str, remedy: str = RUN_REMEDY) -> ModelRunError:
    """A :class:`ModelRunError` saying ``<Model>.simulate <what> at theta = {...}: <remedy>``, in one line."""
    text = f"{model_label(model)}.simulate {what} at theta = {describe_theta(model, theta)}: {remedy}"
    return ModelRunError(" ".join(text.split()))
