"""The roles of a data set's tests as the metrics need them: :func:`require_roles`.

Any number of tests per estimation role of :data:`~bayes_update.core.metrics.STAGES`
(each one a stage of its own: a campaign's levels and signals), and the ones a
command needs.  Apart from :class:`~bayes_update.core.problem.Problem` because the
preflight check (:mod:`bayes_update.core.preflight`) asks it of a data set before any
problem is built.
"""

from __future__ import annotations

from bayes_update.data.dataset import DatasetError

__all__ = ["require_roles"]


def require_roles(dataset, needed=("linear",)) -> None:
    """The data set's roles as the metrics need them: a test with each role in
    ``needed`` (the linear test always: the basis's poles come from the first one),
    and test names that tell the stages apart.  Raises :class:`DatasetError`
    naming the tests and what to set in dataset.json."""
    source = dataset.source or dataset.name
    names = [t.name for t in dataset.tests]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise DatasetError(f"{source}: tests {twice} appear more than once; each test needs a name of its own")
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
