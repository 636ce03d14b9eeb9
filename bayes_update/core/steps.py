"""Wall time and model runs per named step of a pipeline: :class:`StepLog`.

Every command is a sequence of named steps (start, likelihood scales, mode,
design, ...).  What a user pays for each is its wall time and its model runs;
both are recorded here, one place, and land in ``run.json``.
"""

from __future__ import annotations

import time
from contextlib import contextmanager

__all__ = ["StepLog"]


class StepLog:
    """Records ``timing`` [s] and ``runs`` (model runs) per step name.

    >>> steps = StepLog()
    >>> with steps("start"):
    ...     steps.add_runs(12)        # inside a step: counted for it
    >>> steps.runs["start"]
    12
    """

    def __init__(self):
        self.timing: dict = {}
        self.runs: dict = {}
        self._current: list = []
        self._t0 = time.perf_counter()

    @contextmanager
    def __call__(self, name: str):
        self._current.append(name)
        self.runs.setdefault(name, 0)
        t0 = time.perf_counter()
        try:
            yield self
        finally:
            self.timing[name] = self.timing.get(name, 0.0) + time.perf_counter() - t0
            self._current.pop()

    def add_runs(self, n: int, name: str | None = None) -> None:
        """Count ``n`` model runs for ``name`` (default: the step being run)."""
        name = name or (self._current[-1] if self._current else "other")
        self.runs[name] = self.runs.get(name, 0) + int(n)

    def finish(self) -> None:
        """Close the record: ``total`` of both."""
        self.timing["total"] = time.perf_counter() - self._t0
        self.runs["total"] = int(sum(v for k, v in self.runs.items() if k != "total"))

    def line(self) -> str:
        """One line for a log: total time and runs, then each step's."""
        parts = ", ".join(
            f"{k} {self.timing.get(k, 0.0):.0f} s / {self.runs.get(k, 0)} runs" for k in self.timing if k != "total"
        )
        return f"{self.timing.get('total', 0.0):.0f} s and {self.runs.get('total', 0)} model runs" + (
            f" ({parts})" if parts else ""
        )

    def to_dict(self) -> dict:
        return {"timing_s": dict(self.timing), "n_model_runs": dict(self.runs)}
