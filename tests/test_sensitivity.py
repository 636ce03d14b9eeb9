"""Sobol' indices (bayes_update.core.sensitivity) against a known answer: the Ishigami function.

``sobol_indices`` takes an updating problem (anything with ``evaluate(params)
-> {"e_lin": ..., "e_nlin": ...}``) and a prior box; it runs a Sobol' design
through the problem, fits a GP of log e and applies SALib's Saltelli estimator
to the GP mean.  Here the "problem" returns e_lin = exp(f) with f the Ishigami
function of the first three parameters mapped onto [-pi, pi]^3, so the indices
of log e_lin are Ishigami's, and k_s is inert:

    f = sin x1 + a sin^2 x2 + b x3^4 sin x1,   a = 7, b = 0.1
    S1 = 0.3139, 0.4424, 0, 0        ST = 0.5576, 0.4424, 0.2437, 0
    (Ishigami and Homma 1990; Saltelli et al., Global Sensitivity Analysis, 2008)

The error measured here includes the GP's (256 design points; its held-out
median error on e is 28 %) and the estimator's (4096 base samples).
"""

import math

import numpy as np
import pytest

from bayes_update.core.parameters import Parameter, ParameterSet
from bayes_update.core.sensitivity import sobol_indices

A, B = 7.0, 0.1
V = A**2 / 8 + B * math.pi**4 / 5 + B**2 * math.pi**8 / 18 + 0.5
V1 = 0.5 * (1 + B * math.pi**4 / 5) ** 2
V2 = A**2 / 8
V13 = B**2 * math.pi**8 * (1 / 18 - 1 / 50)
S1_EXACT = {"eta": V1 / V, "c": V2 / V, "F": 0.0, "k_s": 0.0}
ST_EXACT = {"eta": (V1 + V13) / V, "c": V2 / V, "F": V13 / V, "k_s": 0.0}


class IshigamiProblem:
    """e_lin = exp(Ishigami(x)); e_nlin is NaN, so only e_lin is analysed (half the GP fits)."""

    stages = ("linear", "nonlinear")

    def __init__(self, space: ParameterSet):
        self.bounds = np.column_stack([space.low, space.high])

    def evaluate(self, params):
        u = np.array([params[n] for n in ("eta", "c", "F", "k_s")])
        x = -math.pi + 2 * math.pi * (u - self.bounds[:, 0]) / (self.bounds[:, 1] - self.bounds[:, 0])
        f = math.sin(x[0]) + A * math.sin(x[1]) ** 2 + B * x[2] ** 4 * math.sin(x[0])
        return {"e_lin": math.exp(f), "e_nlin": float("nan"), "error": None}


def test_textbook_values():
    assert [round(S1_EXACT[k], 4) for k in ("eta", "c")] == [0.3139, 0.4424]
    assert [round(ST_EXACT[k], 4) for k in ("eta", "c", "F")] == [0.5576, 0.4424, 0.2437]


def test_sobol_indices_of_the_ishigami_function():
    """Measured (seed 3): S1 0.3163 / 0.4500 / 0.0005 / 0.0000, ST 0.5496 /
    0.4574 / 0.2347 / 0.0000: largest errors 0.0076 (S1) and 0.015 (ST).
    Tolerances 0.02 and 0.03 (2.6x and 2x); the inert k_s 1e-3 (measured < 1e-4).
    About 8 s on one core."""
    from threadpoolctl import threadpool_limits

    space = ParameterSet(
        [
            Parameter("eta", 1.0, 6.0, "MPa s"),
            Parameter("c", 0.0, 30.0, "N s/mm"),
            Parameter("F", 60.0, 95.0, "N"),
            Parameter("k_s", 0.0, 600.0, "N/mm"),
        ]
    )
    with threadpool_limits(1):  # a 256-point GP: BLAS threads only add contention
        out = sobol_indices(
            IshigamiProblem(space), space, n_design=256, n_sobol=4096, pool=None, seed=3, progress=False
        )
    assert "e_nlin" not in out
    got = out["e_lin"]
    for name in ("eta", "c", "F"):
        assert got["S1"][name] == pytest.approx(S1_EXACT[name], abs=0.02), ("S1", name, got["S1"])
        assert got["ST"][name] == pytest.approx(ST_EXACT[name], abs=0.03), ("ST", name, got["ST"])
    assert abs(got["S1"]["k_s"]) < 1e-3 and abs(got["ST"]["k_s"]) < 1e-3
    # x3 acts only through its interaction with x1: S1 ~ 0 while ST is not
    assert got["ST"]["F"] - got["S1"]["F"] > 0.2
