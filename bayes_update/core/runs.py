"""Model runs kept on disk, keyed by (model, force, theta): :class:`RunStore`.

Every model run of every command goes through :meth:`Problem.run
<bayes_update.core.problem.Problem.run>`; with a store attached
(``problem.run_store``) a run already made, by this command or an earlier one,
interrupted or finished, is read instead of made again, and a new one is written
as soon as it ends (atomically: a file is complete or absent, so an interrupted
command loses at most the runs in flight).  A run that raised ``ModelError`` is
kept too (it would raise again): its message is stored and raised on a hit.

The key of a run is what decides the model's response and nothing else:

* the model: its ``describe()`` (else its class and a hash of its pickled state:
  its constants), the hash of the source file that defines its class (a model file
  edited since gets new runs; for this package's own models, the beam, the hash of
  all their code and of the fe package) and this package's version.  The libraries a
  model of your own calls (e.g. OpenSeesPy) are not in the key: after upgrading one,
  use a new ``--cache`` folder, or ``--no-cache``;
* the force the model is driven by (its bytes) and the sampling rate: the data
  set's recorded force, or a noise replicate's;
* theta: every parameter's exact float64 value.

So the same data at another path, another command (``calibrate`` then ``sample``)
or a later rerun share runs, while new data, a changed model file or another
model never do.  Layout: ``root/<model>/<force>/<theta>.npz`` (the response and the
theta), ``<theta>.err`` for a failed run; each entry records the command that made
it (``source``), so that a command can tell the runs of another (:meth:`points`)
from its own.  Entries are written by worker processes directly, so ``root`` must
be reachable at the same path from every worker (a local pool always; a Dask
cluster on another machine: a shared filesystem, else runs are made again).
"""

from __future__ import annotations

import hashlib
import inspect
import json
import os
import pickle
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from bayes_update.core.steps import StepLog

__all__ = ["RunStore", "StoreSteps", "clear_runs", "default_root", "runs_usage", "store_in"]

#: the journal of runs written: a byte each
JOURNAL = "made.log"
#: the journal of runs read instead of made: a byte each
FOUND = "found.log"


def default_root() -> Path:
    """The user's cache folder: ``$BAYES_UPDATE_CACHE``, else ``$XDG_CACHE_HOME/bayes-update``
    (``~/.cache/bayes-update``), where numba keeps its compiled kernels too; the runs go
    into its ``runs`` folder (:func:`store_in`)."""
    env = os.environ.get("BAYES_UPDATE_CACHE")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "bayes-update"


def store_in(cache_dir, source: str) -> "RunStore":
    """The :class:`RunStore` of a cache folder (its ``runs`` folder)."""
    return RunStore(Path(cache_dir) / "runs", source)


def _entries(cache_dir):
    runs = Path(cache_dir) / "runs"
    return [p for p in runs.glob("*/*/*") if p.suffix in (".npz", ".err")] if runs.is_dir() else []


def runs_usage(cache_dir) -> dict:
    """What the run cache of ``cache_dir`` holds: ``{"folder", "runs", "bytes", "models",
    "oldest_days"}`` (``models``: the number of distinct model keys; ``oldest_days``: the
    age of the oldest run [days], None when empty)."""
    entries = _entries(cache_dir)
    stats = [p.stat() for p in entries]
    return {
        "folder": str(Path(cache_dir) / "runs"),
        "runs": len(entries),
        "bytes": sum(s.st_size for s in stats),
        "models": len({p.parent.parent.name for p in entries}),
        "oldest_days": (time.time() - min(s.st_mtime for s in stats)) / 86400.0 if stats else None,
    }


def clear_runs(cache_dir, older_than_days: float | None = None) -> tuple[int, int]:
    """Delete the kept runs of ``cache_dir`` (all, or those last written more than
    ``older_than_days`` days ago) and the folders left empty; numba's compiled kernels,
    beside them, are not touched.  Returns (runs deleted, bytes freed)."""
    if older_than_days is not None and not older_than_days >= 0:
        raise ValueError(f"older_than_days must be >= 0, got {older_than_days!r}")
    cut = None if older_than_days is None else time.time() - 86400.0 * older_than_days
    n = freed = 0
    for p in _entries(cache_dir):
        try:
            st = p.stat()
            if cut is None or st.st_mtime < cut:
                p.unlink()
                n, freed = n + 1, freed + st.st_size
        except OSError:
            continue
    runs = Path(cache_dir) / "runs"
    for d in sorted(runs.glob("*/*"), reverse=True) + sorted(runs.glob("*")):
        if d.is_dir() and not any(d.iterdir()):
            d.rmdir()
    if cut is None:
        for name in (JOURNAL, FOUND):
            (runs / name).unlink(missing_ok=True)
    return n, freed


def _sha(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def model_key(model) -> str | None:
    """The model's part of a run's key (module docstring); None when it cannot be
    described (its state does not pickle): its runs are then not kept."""
    from bayes_update import __version__

    try:
        if callable(getattr(model, "describe", None)):
            what = json.dumps(model.describe(), sort_keys=True, default=str)
        else:
            what = type(model).__qualname__ + ":" + _sha(pickle.dumps(model))
        try:
            source = _sha(Path(inspect.getsourcefile(type(model))).read_bytes())
        except (TypeError, OSError):
            source = "unknown"
        if type(model).__module__.startswith("bayes_update.models."):
            source += _own_code()
    except Exception:
        return None
    return _sha(f"{what}|{source}|{__version__}".encode())[:20]


_OWN_CODE: list = []


def _own_code() -> str:
    """A hash of the code behind this package's own models (bayes_update/models and the fe
    package they run): a checkout whose solver changed without a new version gets new runs,
    not the old code's.  Computed once a process; fe is found, not imported (the core may
    not import it)."""
    if not _OWN_CODE:
        import importlib.util

        import bayes_update

        roots = [Path(bayes_update.__file__).parent / "models"]
        spec = importlib.util.find_spec("fe")
        if spec is not None and spec.submodule_search_locations:
            roots += [Path(p) for p in spec.submodule_search_locations]
        h = hashlib.sha256()
        for root in roots:
            for path in sorted(root.rglob("*.py")):
                h.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
        _OWN_CODE.append(h.hexdigest())
    return _OWN_CODE[0]


def force_key(force, fs: float) -> str:
    force = np.ascontiguousarray(force, dtype=np.float64) + 0.0  # -0.0 is 0.0
    return _sha(force.tobytes() + np.float64(fs).tobytes())[:20]


def theta_key(theta) -> str:
    items = sorted((str(k), float(v).hex()) for k, v in dict(theta).items())
    return _sha(json.dumps(items).encode())[:24]


class RunStore:
    """Runs under ``root`` (module docstring); ``source`` names the command writing."""

    def __init__(self, root, source: str = "sample"):
        self.root = Path(root)
        self.source = str(source)
        self._models: dict = {}  # id(model) -> (model, key): a model object is described once

    def __getstate__(self):
        return {"root": self.root, "source": self.source, "_models": {}}

    def _model_key(self, model):
        hit = self._models.get(id(model))
        if hit is None or hit[0] is not model:
            hit = (model, model_key(model))
            self._models[id(model)] = hit
        return hit[1]

    def _path(self, model, force, fs, theta) -> Path | None:
        key = self._model_key(model)
        if key is None:
            return None
        return self.root / key / force_key(force, fs) / theta_key(theta)

    def get(self, model, force, fs, theta):
        """The stored response (an array), a ``ModelError`` to raise, or None."""
        from bayes_update.core.model import ModelError

        path = self._path(model, force, fs, theta)
        if path is None:
            return None
        try:
            with np.load(path.with_suffix(".npz")) as f:
                out = np.array(f["response"])
        except (OSError, KeyError, ValueError):
            try:
                out = ModelError(json.loads(path.with_suffix(".err").read_text())["message"])
            except (OSError, KeyError, ValueError):
                return None
        self._journal(FOUND)
        return out

    def _journal(self, name: str) -> None:
        # one byte a run (appends of a byte are atomic between processes): :meth:`made` and
        # :meth:`found` count the runs, whichever process made or read them
        try:
            with open(self.root / name, "ab") as f:
                f.write(b".")
        except OSError:
            pass

    def put(self, model, force, fs, theta, response=None, error: str | None = None) -> None:
        """Keep a run: its ``response``, or the ``error`` message of a ModelError."""
        path = self._path(model, force, fs, theta)
        if path is None:
            return
        path.parent.mkdir(parents=True, exist_ok=True)
        names = sorted(dict(theta))
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
        try:
            if error is None:
                with open(tmp, "wb") as f:
                    np.savez(
                        f,
                        response=np.asarray(response, float),
                        names=np.array(names),
                        values=np.array([float(theta[k]) for k in names]),
                        source=np.array(self.source),
                    )
                os.replace(tmp, path.with_suffix(".npz"))
            else:
                tmp.write_text(
                    json.dumps(
                        {"message": str(error), "theta": {k: float(theta[k]) for k in names}, "source": self.source}
                    )
                )
                os.replace(tmp, path.with_suffix(".err"))
            self._journal(JOURNAL)
        except OSError:
            # a full disk or a read-only cache costs a run next time, never this one
            if tmp.exists():
                tmp.unlink()

    def made(self) -> int:
        """Runs written under ``root`` so far (its journal's length): the difference over a
        step is the runs the step made."""
        return self._length(JOURNAL)

    def found(self) -> int:
        """Runs read under ``root`` so far instead of made (a failure read counts too): the
        difference over a step is the runs the step found kept."""
        return self._length(FOUND)

    def _length(self, name: str) -> int:
        try:
            return os.path.getsize(self.root / name)
        except OSError:
            return 0

    def points(self, model, forces: list, fs: float, exclude_source: str | None = None) -> list:
        """``[(theta, [response per force])]``: every theta at which the model ran on all of
        ``forces`` (without a failure), leaving out runs made by ``exclude_source``; in the
        order of the entries' names (a fixed order for a fixed store)."""
        key = self._model_key(model)
        if key is None:
            return []
        dirs = [self.root / key / force_key(f, fs) for f in forces]
        if not all(d.is_dir() for d in dirs):
            return []
        common = sorted(set.intersection(*({p.stem for p in d.glob("*.npz")} for d in dirs)))
        out = []
        for name in common:
            try:
                parts = []
                for d in dirs:
                    with np.load(d / f"{name}.npz") as f:
                        parts.append({k: np.array(f[k]) for k in ("response", "names", "values", "source")})
            except (OSError, ValueError, KeyError):
                continue
            if exclude_source is not None and any(str(p["source"]) == exclude_source for p in parts):
                continue
            theta = dict(zip(parts[0]["names"].tolist(), parts[0]["values"].tolist()))
            out.append((theta, [p["response"] for p in parts]))
        return out


class StoreSteps(StepLog):
    """A :class:`~bayes_update.core.steps.StepLog` that also counts, per step, the runs the
    step found in the store instead of making them: ``reused`` (the store's journal of reads;
    a run that does not go through the store is counted by the step as before, never here)."""

    def __init__(self, store: RunStore):
        super().__init__()
        self.store, self.reused = store, {}

    @contextmanager
    def __call__(self, name: str):
        found = self.store.found()
        with StepLog.__call__(self, name):
            yield self
        n = self.store.found() - found
        if n > 0:
            self.reused[name] = self.reused.get(name, 0) + n
