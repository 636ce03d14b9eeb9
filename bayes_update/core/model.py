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
* ``diagnose(dataset, theta, basis) -> dict`` and ``signature_values(diagnostics,
  gap) -> {effect: value}``: model-specific diagnostics of the discrepancy
  workflow, with the number each effect's physics should shrink;
* ``describe() -> dict``: what identifies the model in a cache key and a report;
* ``check_dataset(dataset)``: raise ``ValueError`` (saying what to fix) for a
  data set the model cannot be compared with (the beam: another rig).
"""

from __future__ import annotations

import contextlib
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

__all__ = ["BUILTIN_MODELS", "Model", "ModelError", "ModelRunError", "ModelSpecError", "check_model", "check_model_on",
           "describe_theta", "load_model", "model_label", "run_error"]


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
RUN_REMEDY = ("where the model cannot run, raise bayes_update.ModelError (that point then gets no "
              "likelihood and the run goes on); never return NaN")


def model_label(model) -> str:
    """The class name of ``model`` (of the model inside the framework's wrappers:
    a class with ``wraps_model = True`` holds it as ``.model``)."""
    while getattr(type(model), "wraps_model", False):
        model = model.model
    return type(model).__name__


def _units_of(model) -> dict:
    units = {}
    try:
        for p in getattr(model, "parameters", ()) or ():
            units[p.name] = getattr(p, "unit", "")
        effects = getattr(model, "candidate_effects", None)
        for ps in (effects() if callable(effects) else {}).values():
            for p in ps:
                units.setdefault(p.name, getattr(p, "unit", ""))
    except Exception:      # only for a message: a model that cannot say gets its values without units
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
        raise ModelSpecError(f"--model {spec!r}: expected path/to/file.py:NAME or package.module:NAME"
                             + (f", or one of {sorted(BUILTIN_MODELS)}" if BUILTIN_MODELS else ""))
    module = _import(where, spec)
    if not hasattr(module, name):
        public = sorted(n for n in vars(module) if not n.startswith("_"))
        raise ModelSpecError(f"--model {spec!r}: {where} has no {name!r}; it defines {public[:20]}")
    obj = getattr(module, name)
    if inspect.isclass(obj) or (callable(obj) and not hasattr(obj, "simulate")):
        try:
            inspect.signature(obj).bind()
        except TypeError:
            raise ModelSpecError(f"--model {spec!r}: {name} needs arguments; give a class or factory that "
                                 "takes none (wrap yours in a function)") from None
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
        raise ModelSpecError(f"--model {spec!r}: cannot import module {where!r} ({exc}); "
                             "is it installed, or on PYTHONPATH?") from exc


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
            name = None                             # another module of that name is imported
        else:
            try:
                found = importlib.util.find_spec(name)
            except (ImportError, ValueError):
                found = None
            if found is not None and not _same_file(found.origin, path):
                name = None                         # the name would import another module
    synthetic = name is None
    if synthetic:
        name = f"_bayes_update_user_model_{stem if stem.isidentifier() else 'file'}_" \
               f"{hashlib.sha256(str(path).encode()).hexdigest()[:8]}"
        if name in sys.modules and _same_file(getattr(sys.modules[name], "__file__", None), path):
            return sys.modules[name]
    mod_spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(mod_spec)
    sys.modules[name] = module
    sys.path.insert(0, folder)                      # as `python file.py` has it, while it loads
    ok = False
    try:
        with _numba_cache_apart(name) if synthetic else contextlib.nullcontext():
            mod_spec.loader.exec_module(module)
        ok = True
    except Exception as exc:
        del sys.modules[name]
        raise ModelSpecError(f"--model {spec!r}: importing {path} failed: "
                             f"{type(exc).__name__}: {exc}") from exc
    finally:
        sys.path.remove(folder)                     # the copy inserted above
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


def check_model(model, force: np.ndarray, fs: float, n_sensors: int = 1, theta: Mapping | None = None
                ) -> ParameterSet:
    """Check ``model`` against the contract with one run, before any heavy work.

    Runs ``simulate`` once at ``theta`` (default: the middle of the prior) on
    ``force`` and checks the response's shape (n,) or (n, n_sensors) and that it
    is finite.  Returns the model's :class:`ParameterSet`.  Raises
    :class:`ModelSpecError` saying what is wrong and how to fix it.
    """
    kind = type(model).__name__
    if not hasattr(model, "parameters"):
        raise ModelSpecError(f"{kind} has no 'parameters': declare them, e.g. "
                             "parameters = [bayes_update.Parameter('k', 1e3, 1e5, unit='N/m')]")
    if not callable(getattr(model, "simulate", None)):
        raise ModelSpecError(f"{kind} has no simulate(theta, force, fs) method")
    try:
        space = ParameterSet(model.parameters, model)
    except (TypeError, ValueError) as exc:
        raise ModelSpecError(f"{kind}.parameters: {exc}") from exc
    try:
        pickle.dumps(model)
    except Exception as exc:
        raise ModelSpecError(f"{kind} cannot be pickled ({type(exc).__name__}: {exc}); model runs go to "
                             "worker processes: keep lambdas, open files and locks out of the model's "
                             "attributes, or define it at a module's top level") from exc
    force = np.asarray(force, float)
    theta = dict(theta) if theta is not None else space.center()
    try:
        y = np.asarray(model.simulate(theta, force, fs), float)
    except Exception as exc:
        raise ModelSpecError(f"{kind}.simulate failed at theta = {theta}: {type(exc).__name__}: {exc}") from exc
    shapes = [(len(force), n_sensors)] if n_sensors > 1 else [(len(force),), (len(force), 1)]
    if y.shape not in shapes:
        want = " or ".join(map(str, shapes))
        raise ModelSpecError(f"{kind}.simulate returned shape {y.shape} for a force of {len(force)} samples "
                             f"and {n_sensors} sensor(s); it must return {want}: one value per input sample"
                             + (", one column per sensor" if n_sensors > 1 else ""))
    if not np.all(np.isfinite(y)):
        raise ModelSpecError(f"{kind}.simulate returned {int(np.sum(~np.isfinite(y)))} non-finite value(s) at "
                             f"theta = {theta}; raise an exception where the model cannot run instead")
    return space


def check_model_on(model, dataset, theta: Mapping | None = None) -> ParameterSet:
    """:func:`check_model` on a data set: one run on the force of its linear test
    (else its first), at its sampling rate, against the number of sensors it
    declares."""
    lin = dataset.by_role("linear")
    force = (lin[0] if lin else dataset.tests[0]).force
    return check_model(model, force, dataset.sampling_rate_hz, n_sensors=len(dataset.sensors), theta=theta)
