"""The local sensitivity of a stage's compared output: its forward-difference
derivative in the internal coordinates and the span of its columns.

The likelihood's noise scale is measured per direction of that span
(:mod:`bayes_update.core.likelihood`), and the derivative, taken with the
steps of :func:`bayes_update.core.mode.find_mode`, is the first Jacobian of
a mode search from the same point (:func:`bayes_update.core.mode.known_point`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bayes_update.core.model import ModelSpecError
from bayes_update.core.problem import Problem
from surrogates.evaluation import evaluate_many

__all__ = ["Sensitivity", "StageOutput", "derivative_from", "derivative_points", "output_derivative", "span_of"]


@dataclass(frozen=True)
class Sensitivity:
    """A stage's output and its forward-difference derivative at one point."""

    x: np.ndarray  # the point (internal coordinates)
    output: np.ndarray  # the stage's compared output there, (n,)
    derivative: np.ndarray  # d output / d x, (n, d)
    steps: np.ndarray  # the finite-difference steps (internal coordinates): ``rel_step`` of the prior box


@dataclass
class StageOutput:
    """Picklable ``x (internal coordinates) -> the stage's compared output``."""

    problem: Problem
    stage: str
    space: object

    def __call__(self, x) -> np.ndarray:
        p = self.problem
        return p.output(self.stage, p.components(self.stage, p.simulate(self.space.to_parameters(x), self.stage)))


def output_derivative(
    problem: Problem, stage: str, params, space, rel_step: float = 1e-4, at=None, executor=None
) -> Sensitivity:
    """d(stage output)/dx at ``params`` by forward differences in the internal
    coordinates, steps ``rel_step`` of the prior box, backwards at the upper bound
    (the steps and rule of :func:`bayes_update.core.mode.find_mode` with
    ``1e-4`` steps, so a mode search from here can take it as its first
    Jacobian); ``at``: the model's response at ``params`` when already run.  d model runs."""
    x, h, steps, points = derivative_points(space, params, rel_step)
    y0 = problem.output(stage, problem.components(stage, problem.simulate(params, stage) if at is None else at))
    outs = evaluate_many(StageOutput(problem, stage, space), points, executor, progress=False)
    return derivative_from(x, h, steps, y0, outs)


def derivative_points(space, params, rel_step: float = 1e-4):
    """``(x, h, steps, points)`` of :func:`output_derivative`: the internal point, the
    steps' sizes, their signs applied (backwards at the upper bound) and the d points
    to run, for a caller that runs them with other work."""
    x = np.asarray(space.to_internal(params), float)
    box = space.box()
    h = rel_step * (box[:, 1] - box[:, 0])
    steps = np.where(x + h <= box[:, 1], h, -h)
    return x, h, steps, [x + step * e for step, e in zip(steps, np.eye(len(x)))]


def derivative_from(x, h, steps, y0, outputs) -> Sensitivity:
    """The :class:`Sensitivity` from the output at x and at :func:`derivative_points`' points."""
    cols = [(out - y0) / step for out, step in zip(outputs, steps)]
    return Sensitivity(x=np.asarray(x, float).copy(), output=y0, derivative=np.array(cols).T, steps=h)


def span_of(derivative, stage: str = "", tol: float = 1e-6) -> np.ndarray:
    """Orthonormal basis (n, r) of the span of a derivative's columns, r = its numerical rank."""
    U, S, _ = np.linalg.svd(np.asarray(derivative, float), full_matrices=False)
    r = int(np.sum(S > tol * S[0])) if S[0] > 0 else 0
    if r == 0:
        raise ModelSpecError(
            f"stage {stage}: the model's compared output does not move with any parameter here: "
            "check that simulate uses theta[name] of every declared parameter, and that each "
            "parameter's range and unit are those simulate expects"
        )
    return U[:, :r]
