"""The roles of a data set's tests as the metrics need them: :func:`require_roles`.

One test per role of :data:`~bayes_update.core.metrics.STAGES` at most, and the
ones a command needs.  Apart from :class:`~bayes_update.core.problem.Problem`
because the preflight check (:mod:`bayes_update.core.preflight`) asks it of a
data set before any problem is built.
"""

from __future__ import annotations

from bayes_update.core.metrics import STAGES
from bayes_update.data.dataset import DatasetError

__all__ = ["require_roles"]


def require_roles(dataset, needed=("linear",)) -> None:
    """The data set's roles as the metrics need them: one test with each role of
    :data:`STAGES` at most (e_lin and e_nlin compare one test each, and the
    code supports no more), and one with each role in ``needed`` (the linear
    test always: the basis's poles come from it).  Raises :class:`DatasetError`
    naming the tests and what to set in dataset.json."""
    source = dataset.source or dataset.name
    for role in STAGES:
        found = dataset.by_role(role)
        if len(found) > 1:
            raise DatasetError(
                f"{source}: {len(found)} tests have role {role!r} ({[t.name for t in found]}); the "
                f"metrics need exactly one: give the others role 'validation' (predicted and "
                "reported, never fitted) in dataset.json"
            )
    what = {
        "linear": "the low-level test that e_lin and the Kautz basis's poles come from",
        "nonlinear": "the high-level test that e_nlin comes from, which calibrate, sample and discrepancy "
        "need as well as the linear one",
    }
    for role in dict.fromkeys(("linear", *needed)):
        if not dataset.by_role(role):
            raise DatasetError(
                f"{source}: no test has role {role!r} ({what[role]}); set it in dataset.json "
                f"(roles now: {[(t.name, t.role) for t in dataset.tests]})"
            )
