"""Evaluate a function on many parameter points through any executor.

``evaluate_many(func, points, executor)`` works with any
``concurrent.futures.Executor``: the default local process pool, a thread
pool, or a Dask ``Client.get_executor()``.  Points are sent in small batches
(one pickled copy of ``func`` per batch, not per point) and the results come
back in the order of ``points``, with a progress bar.
"""

from __future__ import annotations

import os
import signal
from concurrent.futures import Executor, ProcessPoolExecutor, as_completed
from contextlib import contextmanager

from tqdm.auto import tqdm

__all__ = ["default_executor", "evaluate_many", "executor_for"]


def _init_worker() -> None:
    # Ctrl-C in a terminal reaches the whole process group: the parent handles
    # it (cancels what is queued, says how to resume); a worker finishes its
    # batch quietly instead of printing a traceback of its own
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # one BLAS thread per worker process: the workers already use every core
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


class _ProcessPool(ProcessPoolExecutor):
    """A process pool whose shutdown drops the tasks not yet started, so an
    interrupted run stops after the running batches instead of after all."""

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = True) -> None:
        super().shutdown(wait=wait, cancel_futures=cancel_futures)


def default_executor(max_workers: int | None = None) -> ProcessPoolExecutor:
    """A local process pool over all cores (``max_workers`` to override),
    one BLAS thread per worker; workers ignore SIGINT (the parent handles it)."""
    n = max_workers or os.cpu_count() or 1
    if n < 1:
        raise ValueError(f"max_workers must be positive, got {max_workers}")
    return _ProcessPool(max_workers=n, initializer=_init_worker)


@contextmanager
def executor_for(executor: Executor | None = None, workers: int | None = None):
    """``executor`` when one is given, else a :func:`default_executor` of ``workers`` (all
    cores by default) owned by the ``with`` block and shut down when it ends, else None
    (``workers=1``: every run in this process)."""
    if executor is not None or (workers or 2) <= 1:
        yield executor
        return
    pool = default_executor(workers)
    try:
        yield pool
    finally:
        pool.shutdown()


def _run_batch(func, batch):
    return [func(p) for p in batch]


def evaluate_many(
    func,
    points,
    executor: Executor | None = None,
    batch_size: int | None = None,
    progress: bool = True,
    desc: str = "model runs",
) -> list:
    """``[func(p) for p in points]``, computed through ``executor``.

    Parameters
    ----------
    func : picklable callable of one point (e.g. ``functools.partial`` of
        a model evaluation).
    points : sequence of points.
    executor : any ``concurrent.futures.Executor``; ``None`` runs serially in
        this process (no pickling; the simplest for debugging).
    batch_size : points per task (default: about 4 tasks per worker, at most 16
        points per task so the progress bar moves).
    """
    points = list(points)
    if not points:
        return []
    if executor is None:
        return [func(p) for p in tqdm(points, desc=desc, unit="run", disable=None if progress else True)]
    if not isinstance(executor, Executor):
        raise TypeError(f"executor must be a concurrent.futures.Executor, got {type(executor).__name__}")
    if batch_size is None:
        workers = getattr(executor, "_max_workers", None) or os.cpu_count() or 1
        batch_size = max(1, min(16, len(points) // (4 * workers)))
    batches = [points[i : i + batch_size] for i in range(0, len(points), batch_size)]
    futures = {executor.submit(_run_batch, func, b): i for i, b in enumerate(batches)}
    results = [None] * len(batches)
    try:
        with tqdm(total=len(points), desc=desc, unit="run", disable=None if progress else True) as bar:
            for fut in as_completed(futures):
                i = futures[fut]
                results[i] = fut.result()
                bar.update(len(batches[i]))
    except BaseException:
        # an error or Ctrl-C: do not leave the rest queued on the caller's executor
        for fut in futures:
            fut.cancel()
        raise
    return [r for batch in results for r in batch]
