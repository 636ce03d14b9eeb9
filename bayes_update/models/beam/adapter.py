"""The beam as a model of the framework: what the generic core gets for an
``fe.BeamModel`` or ``fe.ModalROM`` (:data:`bayes_update.core.model.ADAPTERS`).

The beam keeps today's behaviour: the metrics on the paper's set
(:class:`UpdatingProblem`), the (eta, c, P_eff, k_s) coordinates of
:class:`ParameterSpace` with its prior box (docs/design.md#parameters-units-and-the-prior-box), the rig from the
data set's ``rig`` block, paper units in reports, the paper's grids as the
start of ``sample`` and the effects catalogue of
:mod:`bayes_update.models.beam.missing_effect`.
"""
from __future__ import annotations

from bayes_update.models.beam.problem import UpdatingProblem
from bayes_update.models.beam.rig import rig_of
from bayes_update.models.beam.space import ParameterSpace


def problem_and_space(dataset, model, space=None, metrics=None):
    """(:class:`UpdatingProblem`, :class:`ParameterSpace`) of a beam model on ``dataset``."""
    return UpdatingProblem(dataset, model, metrics=metrics), space if space is not None else ParameterSpace(
        rig_of(dataset))
