"""A disk cache of model evaluations, so that an interrupted DOE resumes.

An evaluation is keyed by the point (its exact float64 values) and by a
configuration dictionary: everything besides the point that decides the
result (model settings, data set, metric options, code version...).  The
cache is a directory holding one netCDF file per configuration, named by the
configuration's hash and carrying the configuration itself as JSON, so a
different configuration can never see another's results, and the files are
self-describing (``xarray.open_dataset`` reads them).

Results are dicts of floats, plus optionally an ``"error"`` string (None when
the run succeeded): what a model evaluation (e.g. the metrics of ``bayes_update``)
returns.  A failed run that *returned* (NaN metrics and a message) is cached
like any other, as it fails again the same way; a run that *raised* is not
cached, and stops :func:`cached_evaluate` after saving the chunks before it.
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from .evaluation import evaluate_many

__all__ = ["EvaluationCache", "cached_evaluate", "config_hash"]

_RESERVED = ("x", "error")


def _jsonable(obj):
    # only types whose JSON form is unambiguous and stable: an arbitrary
    # object's str() may hold a memory address and change the hash every run
    if isinstance(obj, Mapping):
        bad = [k for k in obj if not isinstance(k, str)]
        if bad:
            raise TypeError(f"config keys must be strings, got {bad[:3]!r}")
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return [_jsonable(v) for v in obj.tolist()]
    if isinstance(obj, np.generic):
        return _jsonable(obj.item())
    if obj is None or isinstance(obj, (str, bool, int, float)):
        return obj
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    raise TypeError(
        f"config values must be JSON-like (dict, list, str, number, bool, None, numpy "
        f"scalar or array, path); got {type(obj).__name__}: convert it first"
    )


def _canonical(config: Mapping) -> str:
    if not isinstance(config, Mapping):
        raise TypeError(f"config must be a dict, got {type(config).__name__}")
    return json.dumps(_jsonable(config), sort_keys=True, separators=(",", ":"), ensure_ascii=True)


def config_hash(config: Mapping) -> str:
    """sha256 (hex) of the configuration's canonical JSON (sorted keys, no
    spaces).  Stable across runs and machines; note that ``1`` and ``1.0``
    differ (a conservative miss, never a wrong hit)."""
    return hashlib.sha256(_canonical(config).encode()).hexdigest()


def _key(x: np.ndarray) -> bytes:
    # + 0.0 turns -0.0 into 0.0, which are the same point
    return (np.ascontiguousarray(x, dtype=np.float64) + 0.0).tobytes()


def _engine() -> str:
    try:
        import h5netcdf  # noqa: F401

        return "h5netcdf"
    except ImportError:  # netCDF3 through scipy: always there
        return "scipy"


class EvaluationCache:
    """Evaluations of one configuration, stored under directory ``path``.

    Parameters
    ----------
    path : directory (created if needed); the file of this configuration is
        ``path / f"{config_hash(config)[:16]}.nc"``.
    config : dict of what decides the results besides the point (JSON-like
        values; see :func:`config_hash`).

    One process should write a given configuration at a time; each write
    merges with what is on disk and replaces the file atomically, so a crash
    never leaves a half-written file.

    Attributes
    ----------
    hash : the configuration's sha256.
    file : the netCDF file.
    """

    def __init__(self, path, config: Mapping):
        self.config_json = _canonical(config)
        self.config = json.loads(self.config_json)
        self.hash = config_hash(config)
        self.dir = Path(path)
        if self.dir.exists() and not self.dir.is_dir():
            raise ValueError(f"cache path {self.dir} exists and is not a directory")
        self.file = self.dir / f"{self.hash[:16]}.nc"
        self._entries: dict[bytes, dict] = {}
        self._points: dict[bytes, np.ndarray] = {}
        self.keys: tuple | None = None  # metric names, in order
        self.has_error: bool = False
        self.n_inputs: int | None = None
        self._read()
        self.n_loaded = len(self._entries)  # evaluations found on disk: runs a resumed job saves

    def __repr__(self) -> str:
        return f"EvaluationCache({str(self.dir)!r}, config hash {self.hash[:16]}, {len(self)} entries)"

    def __len__(self) -> int:
        return len(self._entries)

    # -- disk ---------------------------------------------------------------
    def _read(self):
        if not self.file.exists():
            return
        import xarray as xr

        with xr.open_dataset(self.file, engine=_engine()) as ds:
            ds = ds.load()
        if ds.attrs.get("config") != self.config_json:
            raise ValueError(
                f"{self.file} holds another configuration (hash prefix collision or a "
                f"renamed file): {ds.attrs.get('config')!r:.200}"
            )
        keys = tuple(json.loads(ds.attrs["result_keys"]))
        has_error = bool(int(ds.attrs["has_error"]))
        self._check_schema(keys, has_error)
        X = np.asarray(ds["x"].values, dtype=np.float64)
        self.n_inputs = X.shape[1]
        cols = {k: np.asarray(ds[k].values, dtype=np.float64) for k in keys}
        errs = [str(e) for e in ds["error"].values] if has_error else None
        for i, x in enumerate(X):
            res = {k: float(cols[k][i]) for k in keys}
            if has_error:
                res["error"] = errs[i] or None
            k = _key(x)
            self._entries.setdefault(k, res)
            self._points.setdefault(k, x.copy())

    def _write(self):
        import xarray as xr

        self._read()  # merge what another run may have added meanwhile
        keys = list(self._entries)
        X = np.array([self._points[k] for k in keys]).reshape(len(keys), self.n_inputs)
        data = {"x": (("entry", "input"), X)}
        for name in self.keys:
            data[name] = ("entry", np.array([self._entries[k][name] for k in keys], dtype=np.float64))
        if self.has_error:
            data["error"] = ("entry", np.array([self._entries[k]["error"] or "" for k in keys], dtype=object))
        ds = xr.Dataset(
            data,
            attrs={
                "title": "model evaluations cached by surrogates.cache",
                "config": self.config_json,
                "config_hash": self.hash,
                "result_keys": json.dumps(list(self.keys)),
                "has_error": int(self.has_error),
            },
        )
        enc = {"x": {"_FillValue": None}}
        if self.has_error:
            enc["error"] = {"dtype": str} if _engine() == "h5netcdf" else {}
        self.dir.mkdir(parents=True, exist_ok=True)
        tmp = self.file.with_name(f".{self.file.name}.{os.getpid()}.tmp")
        try:
            ds.to_netcdf(tmp, engine=_engine(), encoding=enc)
            os.replace(tmp, self.file)  # atomic: readers see the old or the new file
        finally:
            if tmp.exists():
                tmp.unlink()

    # -- entries ------------------------------------------------------------
    def _check_schema(self, keys, has_error):
        if self.keys is None:
            self.keys, self.has_error = tuple(keys), bool(has_error)
        elif (set(keys), bool(has_error)) != (set(self.keys), self.has_error):
            raise ValueError(
                f"results for one configuration must all have the same keys: cache has "
                f"{list(self.keys) + (['error'] if self.has_error else [])}, got "
                f"{list(keys) + (['error'] if has_error else [])}; put what decides the "
                "keys (e.g. the stages) into the config"
            )

    def _points_array(self, points) -> np.ndarray:
        X = np.asarray(points, dtype=np.float64)
        if X.ndim != 2:
            raise ValueError(f"points must have shape (n, d), got {X.shape}")
        if self.n_inputs is not None and X.shape[1] != self.n_inputs:
            raise ValueError(f"points have {X.shape[1]} coordinates, this cache's have {self.n_inputs}")
        if not np.all(np.isfinite(X)):
            raise ValueError("points must be finite")
        return X

    @staticmethod
    def _normalize(res) -> dict:
        if not isinstance(res, Mapping):
            raise TypeError(f"a result must be a dict of floats (plus 'error'), got {type(res).__name__}")
        out = {}
        for k, v in res.items():
            if not isinstance(k, str) or not k:
                raise TypeError(f"result keys must be non-empty strings, got {k!r}")
            if k == "error":
                if v is not None and not isinstance(v, str):
                    raise TypeError(f"'error' must be a string or None, got {type(v).__name__}")
                out[k] = v or None
            elif k in _RESERVED:
                raise ValueError(f"result key {k!r} is reserved by the cache")
            elif v is None:
                out[k] = math.nan
            elif isinstance(v, numbers.Real):
                out[k] = float(v)
            else:
                raise TypeError(f"result {k!r} must be a real number or None, got {type(v).__name__}")
        return out

    def get(self, x) -> dict | None:
        """The cached result at point ``x`` (d,), a new dict, or None."""
        res = self._entries.get(_key(np.asarray(x, dtype=np.float64)))
        return None if res is None else dict(res)

    def __contains__(self, x) -> bool:
        return _key(np.asarray(x, dtype=np.float64)) in self._entries

    def add(self, points, results) -> None:
        """Store ``results`` (list of dicts) at ``points`` (n, d) and write the file.

        A point already cached keeps its first result.
        """
        X = self._points_array(points)
        results = [self._normalize(r) for r in results]
        if len(results) != len(X):
            raise ValueError(f"{len(X)} points but {len(results)} results")
        if not results:
            return
        schemas = {(frozenset(r) - {"error"}, "error" in r) for r in results}
        if len(schemas) > 1:
            raise ValueError(f"results of one call have different keys: {[sorted(k) for k, _ in schemas]}")
        self._check_schema([k for k in results[0] if k != "error"], "error" in results[0])
        self.n_inputs = X.shape[1]
        for x, r in zip(X, results):
            k = _key(x)
            if k not in self._entries:
                self._entries[k], self._points[k] = r, x.copy() + 0.0
        self._write()

    def missing(self, points) -> np.ndarray:
        """Indices (into ``points``) of the points to evaluate: not cached,
        and each distinct point once (its first occurrence)."""
        X = self._points_array(points)
        seen, idx = set(self._entries), []
        for i, x in enumerate(X):
            k = _key(x)
            if k not in seen:
                seen.add(k)
                idx.append(i)
        return np.asarray(idx, dtype=int)

    def points(self) -> np.ndarray:
        """All cached points (n, d), in insertion order."""
        return np.array(list(self._points.values())).reshape(len(self), self.n_inputs or 0)

    def to_dataset(self):
        """The cached evaluations as an ``xarray.Dataset`` (dims entry, input)."""
        import xarray as xr

        if not self.file.exists():
            return xr.Dataset(attrs={"config": self.config_json, "config_hash": self.hash})
        with xr.open_dataset(self.file, engine=_engine()) as ds:
            return ds.load()


def cached_evaluate(
    func,
    points,
    cache: EvaluationCache,
    executor=None,
    *,
    batch_size: int | None = None,
    chunk_size: int | None = None,
    progress: bool = True,
    desc: str = "model runs",
) -> list:
    """``[func(x) for x in points]``, running only the points ``cache`` lacks.

    Parameters
    ----------
    func : picklable callable of one point (1-D float array) returning a
        dict of floats, plus optionally ``"error"`` (str or None).
    points : (n, d) points.
    cache : :class:`EvaluationCache` of the configuration ``func`` computes.
    executor : any ``concurrent.futures.Executor`` (None: serial), used
        through :func:`surrogates.evaluation.evaluate_many`.
    batch_size : points per task, passed to ``evaluate_many``.
    chunk_size : points evaluated between two writes of the cache (default
        8 per worker: the pool stays busy, and a crash loses at most one
        chunk; set it for a Dask cluster, whose size is not known here).

    Returns
    -------
    list of n result dicts in the order of ``points`` (duplicates share one
    run).  An exception raised by ``func`` propagates once the chunks
    finished before it are saved; calling again resumes from there.
    """
    if len(points) == 0:
        return []
    X = cache._points_array(points)
    todo = cache.missing(X)
    if chunk_size is None:
        workers = 1 if executor is None else (getattr(executor, "_max_workers", None) or os.cpu_count() or 1)
        chunk_size = 8 * workers
    if isinstance(chunk_size, bool) or int(chunk_size) != chunk_size or chunk_size < 1:
        raise ValueError(f"chunk_size must be a positive integer, got {chunk_size!r}")
    chunk_size = int(chunk_size)
    with tqdm(total=len(todo), desc=desc, unit="run", disable=None if progress and len(todo) else True) as bar:
        for i in range(0, len(todo), chunk_size):
            chunk = X[todo[i : i + chunk_size]]
            res = evaluate_many(func, [x.copy() for x in chunk], executor, batch_size=batch_size, progress=False)
            cache.add(chunk, res)
            bar.update(len(chunk))
    return [cache.get(x) for x in X]
