"""The contract checked, before any heavy work and on every run.

:func:`check_contract` checks a model without running it (the members and
their types, a hook's name misspelt, pickling); :func:`check_response` reads
every response the way the framework does; :func:`check_run` and
:func:`check_model` (:func:`check_model_on` on a data set) add the one check
run.  Apart from the loader (:mod:`bayes_update.core.model_loader`): these
check what a model holds and returns, wherever it came from.
"""

from __future__ import annotations

import difflib
import pickle
from collections.abc import Mapping, Sequence

import numpy as np

from bayes_update.core.model_errors import ModelError, ModelSpecError, run_error, unwrapped
from bayes_update.core.parameters import ParameterSet

#: the optional members the framework calls when present (docs/models.md), each with how it is called
CALLABLE_HOOKS = {
    "refined": "refined() -> a finer model of the same physics",
    "candidate_effects": "candidate_effects() -> {effect: [Parameter(..., null=value), ...]}",
    "to_internal": "to_internal(theta) -> x",
    "from_internal": "from_internal(x) -> theta",
    "log_jacobian": "log_jacobian(x) -> float",
    "from_internal_many": "from_internal_many(X) -> {name: array}",
    "log_jacobian_many": "log_jacobian_many(X) -> array",
    "start": "start(dataset, executor, progress) -> (theta, model runs)",
    "extra_starts": "extra_starts(x) -> [x, ...]",
    "diagnose": "diagnose(dataset, theta, basis) -> dict",
    "signature": "signature(effect, diagnostics, gap)",
    "diagnostics_figure": "diagnostics_figure(diagnostics)",
    "check_dataset": "check_dataset(dataset)",
    "describe": "describe() -> dict",
}
#: the optional members the framework reads as values, each with what it must be
VALUE_HOOKS = {
    "default_metrics": "'full' or 'paper'",
    "remove_offsets": "True or False",
    "internal_names": "a list of names, one per internal coordinate",
    "internal_units": "a dict {internal coordinate: unit}",
    "response_kind": "a response kind such as 'velocity'",
    "response_unit": "a unit such as 'm/s'",
}
_REQUIRED = ("parameters", "simulate")
#: a member whose name is this close to the name of a hook the model lacks (difflib's ratio, case
#: ignored) is taken for that hook misspelt, which the framework would otherwise ignore without a
#: word: ``refine`` is 0.92 from ``refined``, ``candidate_effect`` 0.97 from ``candidate_effects``;
#: 0.85 leaves a helper such as ``restart`` (0.83 from ``start``) or ``refinement`` (0.71) alone
MISSPELT_RATIO = 0.85
#: where the contract is written down, for the messages
CONTRACT_DOC = "docs/models.md"


def _valid_value(name: str, value) -> bool:
    """Whether ``value`` is what :data:`VALUE_HOOKS` says the member ``name`` must be."""
    if name == "default_metrics":
        from bayes_update.core.metrics import METRIC_SETS

        return isinstance(value, str) and value in METRIC_SETS
    if name == "remove_offsets":
        return isinstance(value, (bool, np.bool_))
    if name == "internal_names":
        return (
            isinstance(value, Sequence) and not isinstance(value, str) and all(isinstance(v, str) and v for v in value)
        )
    if name == "internal_units":
        return isinstance(value, Mapping)
    return isinstance(value, str)


def _check_required(model, kind: str) -> None:
    for name in _REQUIRED:
        if hasattr(model, name):
            continue
        near = difflib.get_close_matches(name, _public_names(model), n=1, cutoff=0.6)
        hint = f" ({near[0]!r} is defined: is that it, misspelt?)" if near else ""
        if name == "parameters":
            raise ModelSpecError(
                f"{kind} has no 'parameters'{hint}: declare them, e.g. "
                "parameters = [bayes_update.Parameter('k', 1e3, 1e5, unit='N/m')]"
            )
        raise ModelSpecError(
            f"{kind} has no simulate(theta, force, fs) method{hint}: define it, returning the "
            f"response at the sensors, one value per force sample ({CONTRACT_DOC})"
        )
    if not callable(getattr(model, "simulate")):
        raise ModelSpecError(
            f"{kind}.simulate is a {type(model.simulate).__name__}, not a method: define "
            f"simulate(self, theta, force, fs) ({CONTRACT_DOC})"
        )


def _public_names(model) -> list:
    return [n for n in dir(model) if not n.startswith("_")]


def _check_hooks(model, kind: str) -> None:
    """Each optional member present is of its type, and no member is a hook's name misspelt."""
    present = set(dir(model))
    for name, how in CALLABLE_HOOKS.items():
        value = getattr(model, name, None)
        if name in present and not callable(value):
            raise ModelSpecError(
                f"{kind}.{name} is {value!r} ({type(value).__name__}), not a method: the framework calls "
                f"{how} when the model has it ({CONTRACT_DOC}, optional members); define it as a method, or "
                "delete it when the model has none"
            )
    for name, what in VALUE_HOOKS.items():
        if name in present and not _valid_value(name, getattr(model, name)):
            raise ModelSpecError(
                f"{kind}.{name} is {getattr(model, name)!r}; it must be {what} ({CONTRACT_DOC}, optional members)"
            )
    known = (*_REQUIRED, *CALLABLE_HOOKS, *VALUE_HOOKS)
    absent = [h for h in known if h not in present]
    for name in _public_names(model):
        near = difflib.get_close_matches(name.lower(), absent, n=1, cutoff=MISSPELT_RATIO)
        if near and name not in known:
            raise ModelSpecError(
                f"{kind}.{name} is not a member the framework knows, and {kind} has no {near[0]!r}: if "
                f"{name!r} is meant as the optional {near[0]!r}, rename it (else it is ignored); if it is a "
                f"member of your own, start its name with an underscore ({CONTRACT_DOC}, optional members)"
            )


def check_contract(model, space: ParameterSet | None = None) -> ParameterSet:
    """Check ``model`` against the contract without running it.

    ``parameters`` well formed, ``simulate`` a method, every optional member
    of its type (``refined = None`` is refused: a hook is a method or absent),
    no member a hook's name misspelt (``refine``: it would be ignored without a
    word), and the model pickles (its runs go to worker processes).  A model
    inside the framework's wrappers (:func:`unwrapped`) is checked as the user
    wrote it.  Returns ``space`` (the prior of the run, when given), else the
    model's declared :class:`ParameterSet`.  Raises :class:`ModelSpecError`
    saying what is wrong and how to fix it.
    """
    user = unwrapped(model)
    kind = type(user).__name__
    _check_required(user, kind)
    _check_hooks(user, kind)
    try:
        declared = ParameterSet(user.parameters, user)
    except (TypeError, ValueError) as exc:
        raise ModelSpecError(
            f"{kind}.parameters: {exc}; declare a list of bayes_update.Parameter(name, low, "
            f"high, unit=..., log=...) ({CONTRACT_DOC})"
        ) from exc
    try:
        pickle.dumps(model)
    except Exception as exc:
        raise ModelSpecError(
            f"{kind} cannot be pickled ({type(exc).__name__}: {exc}); model runs go to "
            "worker processes: keep lambdas, open files and locks out of the model's "
            "attributes, or define it at a module's top level"
        ) from exc
    return declared if space is None else space


def check_response(model, theta, y, n: int, n_sensors: int) -> np.ndarray:
    """A response of ``model.simulate`` at ``theta`` as the framework reads it:
    float, (n,) for one sensor or (n, n_sensors) for several (a single
    column comes back as (n,)), every value finite.  Otherwise a
    :class:`ModelRunError` naming the model, theta and the remedy.  Every run
    goes through it: the check run before any long step and every later one."""
    try:
        arr = np.asarray(y)
        if arr.dtype.kind == "O":  # numbers as Python objects: fine when they are numbers
            arr = arr.astype(float)
    except (TypeError, ValueError) as exc:
        raise run_error(
            model,
            theta,
            f"returned a {type(y).__name__} that is not an array of numbers ({exc})",
            "return a numpy array of the response, one value per input sample",
        ) from None
    if arr.dtype.kind not in "fiu":
        # a complex response would lose its imaginary part to a cast without a word
        raise run_error(
            model,
            theta,
            f"returned an array of dtype {arr.dtype} ({type(y).__name__})",
            "return real numbers (a float array): the response the sensors measure, one value per input sample",
        )
    y = arr.astype(float, copy=False)
    shapes = [(n, n_sensors)] if n_sensors > 1 else [(n,), (n, 1)]
    if y.shape not in shapes:
        raise run_error(
            model,
            theta,
            f"returned shape {y.shape} for a force of {n} samples and {n_sensors} sensor(s)",
            f"it must return {' or '.join(map(str, shapes))} at every theta: one value "
            "per input sample"
            + (", one column per sensor" if n_sensors > 1 else "")
            + "; where the model cannot run, raise bayes_update.ModelError",
        )
    bad = int(np.count_nonzero(~np.isfinite(y)))
    if bad:
        raise run_error(model, theta, f"returned {bad} non-finite (NaN/inf) value(s) of {y.size}")
    return y[:, 0] if y.ndim == 2 and y.shape[1] == 1 else y


def check_run(
    model,
    space: ParameterSet,
    force: np.ndarray,
    fs: float,
    n_sensors: int = 1,
    theta: Mapping | None = None,
    store=None,
) -> np.ndarray:
    """One run of ``model`` at ``theta`` (default: the middle of ``space``, the
    prior) on ``force`` at ``fs`` [Hz], its response checked
    (:func:`check_response`).  A :class:`ModelError` there is an error too: the
    middle of the prior must be a point where the model runs."""
    force = np.asarray(force, float)
    theta = dict(theta) if theta is not None else space.center()
    try:
        y = model.simulate(theta, force, fs)
    except ModelError as exc:
        raise run_error(
            model,
            theta,
            f"raised ModelError ({exc}) in the check run",
            "the check runs the model at the middle of its prior, which must be a point where "
            "it runs: narrow the prior (the Parameter bounds, or --prior NAME=LO:HI) to where "
            "the model runs",
        ) from exc
    except Exception as exc:  # a bug of the model: its message, in one line
        raise run_error(
            model,
            theta,
            f"raised {type(exc).__name__}: {exc}",
            "fix the model there (the check runs it at the middle of its prior on the linear "
            "test's force before any long step)",
        ) from exc
    y = check_response(model, theta, y, len(force), n_sensors)
    if store is not None:
        store.put(model, force, fs, theta, response=y)
    return y


def check_model(
    model,
    force: np.ndarray,
    fs: float,
    n_sensors: int = 1,
    theta: Mapping | None = None,
    space: ParameterSet | None = None,
) -> ParameterSet:
    """Check ``model`` against the contract with one run, before any heavy work:
    :func:`check_contract`, then :func:`check_run` at ``theta`` (default: the
    middle of ``space``, else of the declared prior) on ``force``.  Returns the
    prior (``space``, else the model's declared :class:`ParameterSet`).
    Raises :class:`ModelSpecError` (a :class:`ModelRunError` for the run)
    saying what is wrong and how to fix it.
    """
    space = check_contract(model, space)
    check_run(model, space, force, fs, n_sensors, theta)
    return space


def check_force(model, dataset) -> np.ndarray:
    """The force the check run uses: the data set's linear test's (else its
    first test's), as every later run sees it (its mean removed as a sensor
    offset unless the model's ``remove_offsets`` is False, as
    :class:`~bayes_update.core.problem.Problem` does)."""
    lin = dataset.by_role("linear")
    force = np.array((lin[0] if lin else dataset.tests[0]).force, float)
    return force - force.mean() if getattr(model, "remove_offsets", True) else force


def check_model_on(model, dataset, theta: Mapping | None = None, space: ParameterSet | None = None) -> ParameterSet:
    """:func:`check_model` on a data set: one run on :func:`check_force`, at its
    sampling rate, against the number of sensors it declares."""
    return check_model(
        model,
        check_force(model, dataset),
        dataset.sampling_rate_hz,
        n_sensors=len(dataset.sensors),
        theta=theta,
        space=space,
    )
