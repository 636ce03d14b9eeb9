"""The loader of ``--model SPEC``: a model object, a built-in name, a file or a module.

:func:`load_model` turns a spec into a model; a file is imported as ``python
file.py`` would see it (:func:`_import_file`), so that worker processes and
numba's cache find it again.  Apart from the contract's checks
(:mod:`bayes_update.core.model_checks`): loading knows files and imports, not
what a model must hold.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import importlib.util
import inspect
import keyword
import os
import sys
import tempfile
from pathlib import Path

from bayes_update.core.model_errors import ModelSpecError

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
