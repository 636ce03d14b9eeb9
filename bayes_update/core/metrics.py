"""The metric sets: which part of each test's Volterra expansion a metric compares.

Each estimation test is summarised by its Volterra expansion; which part of
it a metric compares is a declared *metric set* (:data:`METRIC_SETS`):

``paper`` (the beam study's default; the paper's eq. 20-22)
    e_lin  = ||y1_ref - y1_mod|| / ||y1_ref||    on the test with role ``linear``;
    e_nlin = ||y23_ref - y23_mod|| / ||y23_ref|| on the test with role
    ``nonlinear``, y23 = y2 + y3.
``full`` (the default for any other model)
    the same on the linear test; on the nonlinear test the whole projection
    y1 + y2 + y3.  Why: y1 of the high-level test carries what a gain or an
    amplitude-dependent linear term changes, and the paper's set throws it
    away (on a measured Duffing record the paper's set predicted held-out
    data with 1.4-1.7x the error of a direct output-error fit, the full
    projection with 1.01x).  Where one scalar objective combines the tests
    (:mod:`bayes_update.core.calibrate`), each test is weighted by its
    measured noise (:meth:`Problem.noise_sd`), not by its energy.
"""

from __future__ import annotations

import numpy as np

import volterra

__all__ = [
    "METRIC_SETS",
    "STAGES",
    "STAGE_ORDERS",
    "metric_key",
    "n_compared_regressors",
    "relative_error",
    "stage_name",
    "stage_output",
    "stage_role",
]


#: The roles of the estimation tests; each test of a role is a *stage* (one metric, one
#: likelihood scale).  The first test of a role is the stage of the role's name (the paper's
#: two-test form: ``linear`` and ``nonlinear``); every further one, ``role:test name``
#: (:func:`stage_name`; a campaign's medium level beside its high one, a sweep beside a
#: multisine).
STAGES = ("linear", "nonlinear")
#: Kernel orders fitted on each role's tests.
STAGE_ORDERS = {"linear": (1,), "nonlinear": (1, 2, 3)}
#: Kernel orders each metric set compares, per role (module docstring).
METRIC_SETS = {"paper": {"linear": (1,), "nonlinear": (2, 3)}, "full": {"linear": (1,), "nonlinear": (1, 2, 3)}}
#: the metric of each role's first test (the paper's names)
_KEYS = {"linear": "e_lin", "nonlinear": "e_nlin"}


def stage_name(role: str, test_name: str, first: bool) -> str:
    """The stage of a test with ``role``: the role itself for the role's first test,
    ``"role:test name"`` for every other."""
    if role not in STAGE_ORDERS:
        raise ValueError(f"role must be one of {STAGES}, got {role!r}")
    return role if first else f"{role}:{test_name}"


def stage_role(stage: str) -> str:
    """The role of a stage (``"nonlinear:ms_mid"`` -> ``"nonlinear"``)."""
    role = stage.split(":", 1)[0]
    if role not in STAGE_ORDERS:
        raise ValueError(f"stage must be one of {STAGES} or 'role:test name', got {stage!r}")
    return role


def metric_key(stage: str) -> str:
    """The metric's name of a stage: ``e_lin``, ``e_nlin``, or ``e_nlin:test name``
    for a further test of the role."""
    role = stage_role(stage)
    return _KEYS[role] + stage[len(role) :]


def relative_error(reference, model) -> float:
    """||reference - model|| / ||reference|| (dimensionless)."""
    reference = np.asarray(reference, float)
    norm = np.linalg.norm(reference)
    if not norm > 0:
        raise ValueError("the reference signal is identically zero")
    return float(np.linalg.norm(reference - np.asarray(model, float)) / norm)


def stage_output(stage: str, comps: dict, metrics: str = "paper") -> np.ndarray:
    """The output a stage's metric compares under the metric set ``metrics``:
    y1 on the linear test; y2 + y3 (``paper``) or y1 + y2 + y3 (``full``) on
    the nonlinear test."""
    return sum(comps[n] for n in METRIC_SETS[metrics][stage_role(stage)])


def n_compared_regressors(basis: volterra.KautzBasis, stage: str, metrics: str = "paper") -> int:
    """Regressors behind a stage's metric: sum over its compared orders k of
    C(dim_k + k - 1, k) (the symmetric kernel's coefficients; dim_k, the
    order's functions, counts every mode and the feed-through)."""
    return sum(basis.n_terms(k) for k in METRIC_SETS[metrics][stage_role(stage)])
