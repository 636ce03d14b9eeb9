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
"""

from __future__ import annotations

import contextlib
import difflib
import hashlib
import importlib
import importlib.util
import inspect
import keyword
import os
import pickle
import sys
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from bayes_update.core.parameters import Parameter, ParameterSet

__all__ = [
    "BUILTIN_MODELS",
    "CALLABLE_HOOKS",
    "VALUE_HOOKS",
    "Model",
    "ModelError",
    "ModelRunError",
    "ModelSpecError",
    "check_contract",
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


# built-in names of --model: "module:NAME" specs, filled in as models ship
BUILTIN_MODELS: dict[str, str] = {}


def load_model(spec):
    """A model from ``spec``: a model object (returned as is), a built-in name
    (:data:`BUILTIN_MODELS`), ``path/to/file.py:NAME`` or ``package.module:NAME``,
    where NAME is a class or a zero-argument factory."""
    if not isinstance(spec, str):
        return spec
    if spec in BUILTIN_MODELS:
        spec = BUILTIN_MODELS[spec]
    where, sep, name = spec.rpartition(":")
    if not sep or not where or not name:
        raise ModelSpecError(
            f"--model {spec!r}: expected path/to/file.py:NAME or package.module:NAME"
            + (f", or one of {sorted(BUILTIN_MODELS)}" if BUILTIN_MODELS else "")
        )
    module = _import(where, spec)
    if not hasattr(module, name):
        public = sorted(n for n in vars(module) if not n.startswith("_"))
        raise ModelSpecError(f"--model {spec!r}: {where} has no {name!r}; it defines {public[:20]}")
    obj = getattr(module, name)
    if inspect.isclass(obj) or (callable(obj) and not hasattr(obj, "simulate")):
        try:
            inspect.signature(obj).bind()
        except TypeError:
            raise ModelSpecError(
                f"--model {spec!r}: {name} needs arguments; give a class or factory that "
                "takes none (wrap yours in a function)"
            ) from None
        except ValueError:
            pass  # no signature to inspect (a builtin): just call it
        obj = obj()
    return obj


def _import(where: str, spec: str):
    if where.endswith(".py") or "/" in where or "\\" in where:
        path = Path(where).expanduser()
        if not path.is_file():
            raise ModelSpecError(f"--model {spec!r}: no such file {path}")
        return _import_file(path.resolve(), spec)
    try:
        return importlib.import_module(where)
    except ImportError as exc:
        raise ModelSpecError(
            f"--model {spec!r}: cannot import module {where!r} ({exc}); is it installed, or on PYTHONPATH?"
        ) from exc


def _same_file(a, b) -> bool:
    try:
        return a is not None and b is not None and os.path.samefile(a, b)
    except OSError:
        return False


def _import_file(path: Path, spec: str):
    """The module of the file ``path``, loaded as ``python path`` would see it: its
    folder on ``sys.path`` while it loads (so that it imports the modules beside
    it), under its own name (its stem) when that name is free or already is this
    file, so that worker processes (fork or spawn) import it by that name and
    numba's cache (``cache=True``, keyed by the file) holds code that reloads
    under a real, importable name.  The folder stays on ``sys.path`` afterwards,
    at its end (a spawned worker inherits it; the framework's own imports are not
    shadowed).  Only when the stem names another module (``json.py``) or is not an
    identifier is the file loaded under a synthetic name, and then its numba
    functions cache in a folder of their own (:func:`_numba_cache_apart`)."""
    folder = str(path.parent)
    stem = path.stem
    name = stem if stem.isidentifier() and not keyword.iskeyword(stem) else None
    if name is not None:
        loaded = sys.modules.get(name)
        if loaded is not None:
            if _same_file(getattr(loaded, "__file__", None), path):
                return loaded
            name = None  # another module of that name is imported
        else:
            try:
                found = importlib.util.find_spec(name)
            except (ImportError, ValueError):
                found = None
            if found is not None and not _same_file(found.origin, path):
                name = None  # the name would import another module
    synthetic = name is None
    if synthetic:
        name = (
            f"_bayes_update_user_model_{stem if stem.isidentifier() else 'file'}_"
            f"{hashlib.sha256(str(path).encode()).hexdigest()[:8]}"
        )
        if name in sys.modules and _same_file(getattr(sys.modules[name], "__file__", None), path):
            return sys.modules[name]
    mod_spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(mod_spec)
    sys.modules[name] = module
    sys.path.insert(0, folder)  # as `python file.py` has it, while it loads
    ok = False
    try:
        with _numba_cache_apart(name) if synthetic else contextlib.nullcontext():
            mod_spec.loader.exec_module(module)
        ok = True
    except Exception as exc:
        del sys.modules[name]
        raise ModelSpecError(f"--model {spec!r}: importing {path} failed: {type(exc).__name__}: {exc}") from exc
    finally:
        sys.path.remove(folder)  # the copy inserted above
        if ok and folder not in sys.path:
            sys.path.append(folder)
    return module


@contextlib.contextmanager
def _numba_cache_apart(module_name: str):
    """While a file loads under a synthetic module name: numba's cache (keyed by
    the file, not the module name) goes to a folder of that name in the temporary
    directory, so that the user's own cache folder never holds entries that
    reload only under a name nothing can import."""
    if "numba" not in sys.modules and importlib.util.find_spec("numba") is None:
        yield
        return
    from numba.core import config

    old = config.CACHE_DIR
    config.CACHE_DIR = os.path.join(tempfile.gettempdir(), "bayes_update_numba_cache", module_name)
    try:
        yield
    finally:
        config.CACHE_DIR = old


# ------------------------------------------------------------ the contract, checked
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
