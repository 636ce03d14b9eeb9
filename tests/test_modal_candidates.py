"""A modal model's joint elements offered as candidate effects (``ModalModel(..., candidates=)``).

A candidate is integrated as a declared element is, its coefficient not among the parameters but
offered through ``candidate_effects()`` (one effect per element, null 0), read from theta when
there and 0 otherwise.  The workflow is run on the two-mass chain of tests/test_modal_calibrate.py
(a cubic spring at mass 1, where the force acts and acc1 measures): of a cubic spring, a friction
and a clearance at acc1, it must name the cubic spring alone.
"""

import time

import numpy as np
import pytest
from test_modal_calibrate import FS, K3, LEVELS, SENSORS, _record

from bayes_update.data.dataset import Dataset, Record
from bayes_update.models.modal import ModalModel, Nonlinearity

MODES = [(7.1, 0.02), (19.3, 0.015)]
COEFFS = [[0.9, 0.4], [0.3, -0.5]]
TWO = [("acc1", "acceleration"), ("acc2", "acceleration")]
ELEMS = [Nonlinearity("friction", at="acc1", v0=1e-3), Nonlinearity("k3", at="acc2"), Nonlinearity("c3", 2)]
PRIORS = {"friction_at_acc1": (0.0, 0.5), "k3_at_acc2": (-1e7, 1e7), "c3_2": (0.0, 40.0)}


def _force(n=2048, seed=3):
    return np.random.default_rng(seed).standard_normal(n)


def _model(nonlinear=(), candidates=(), bounds=PRIORS, **kw):
    kw = dict(updated=[1], nonlinear=nonlinear, candidates=candidates, bounds=bounds, driving_point="acc1", **kw)
    return ModalModel(MODES, COEFFS, TWO, **kw)


def test_a_candidate_at_its_null_is_the_element_declared_at_zero():
    """Bit-identical to the same element declared and set to 0 (the same RK4 steps: they are sized by
    the element's prior whether declared or candidate); not the linear model (which the exact
    discretisation advances), so that is not the comparison.  Under test (in theta), a candidate
    acts as the declared element at that value."""
    u, theta = _force(), {"f1": 7.2, "zeta1": 0.025}
    cand, declared = _model(candidates=ELEMS), _model(nonlinear=ELEMS)
    zeros = {e.name: 0.0 for e in ELEMS}
    y = cand.simulate(theta, u, 200.0)
    assert np.array_equal(y, declared.simulate({**theta, **zeros}, u, 200.0))
    assert np.array_equal(y, cand.simulate({**theta, **zeros}, u, 200.0))
    on = {"friction_at_acc1": 0.2, "k3_at_acc2": 4e6, "c3_2": 20.0}
    y_on = cand.simulate({**theta, **on}, u, 200.0)
    assert np.array_equal(y_on, declared.simulate({**theta, **on}, u, 200.0)) and not np.array_equal(y, y_on)
    # the candidates are not parameters, are described, and change the description
    assert [p.name for p in cand.parameters] == ["f1", "zeta1"]
    assert cand.describe()["candidates"] == {k: [lo, hi, e.unit] for e, (k, (lo, hi)) in zip(ELEMS, PRIORS.items())}
    assert cand.describe()["shapes"] == {"friction_at_acc1": {"v0": 1e-3}}
    plain = _model(bounds={})
    assert plain.candidate_effects() == {} and "candidates" not in plain.describe() and "shapes" not in plain.describe()
    assert cand.refined().candidate_effects() == cand.candidate_effects()


@pytest.fixture(scope="module")
def chain():
    tests = []
    for name, (role, level, seed) in LEVELS.items():
        t, u, y, _ = _record(level, seed)
        tests.append(Record(f"{name}.csv", "noise", name, role, t, u, y, sensors=SENSORS))
    return Dataset("two-mass chain, cubic spring at mass 1", FS, None, tests)


def _rms_motion(data, sensor=0):
    """rms velocity [m/s] and displacement [m] of the high test at ``sensor``: its acceleration
    integrated in the frequency domain (above 1 Hz; the force's band starts at 3 Hz)."""
    a = data.test("high").response[:, sensor]
    w = 2 * np.pi * np.fft.rfftfreq(a.size, 1 / FS)
    over = np.where(w > 2 * np.pi, 1 / (1j * np.where(w > 0, w, 1.0)), 0.0)  # 1 / (i w), 0 below 1 Hz
    V = np.fft.rfft(a - a.mean()) * over
    return float(np.std(np.fft.irfft(V, a.size))), float(np.std(np.fft.irfft(V * over, a.size)))


def _candidates(data):
    v_rms, x_rms = _rms_motion(data)
    return [
        Nonlinearity("k3", at="acc1"),
        Nonlinearity("friction", at="acc1", v0=0.05 * v_rms),
        Nonlinearity("clearance", at="acc1", gap=1.5 * x_rms),
    ]


def test_candidate_effects_list_the_candidates_with_the_default_priors(chain):
    cands = _candidates(chain)
    model = ModalModel.from_dataset(chain, updated=[1, 2], candidates=cands, driving_point="acc1")
    declared = ModalModel.from_dataset(chain, updated=[1, 2], nonlinear=cands, driving_point="acc1")
    effects = model.candidate_effects()
    assert list(effects) == ["k3_at_acc1", "friction_at_acc1", "clearance_at_acc1"]
    assert [p.name for p in model.parameters] == ["f1", "zeta1", "f2", "zeta2"]
    priors = {p.name: p for p in declared.parameters}
    for name, ps in effects.items():
        (p,) = ps
        assert (
            p.name == name
            and p.null == 0.0
            and (p.low, p.high, p.unit)
            == (
                priors[name].low,
                priors[name].high,
                priors[name].unit,
            )
        )
    # from_dataset's bounds override a candidate's prior as an element's
    top = ModalModel.from_dataset(
        chain, updated=[1], candidates=cands[:1], driving_point="acc1", bounds={"k3_at_acc1": (-1.0, 2.0)}
    )
    assert (top.candidate_effects()["k3_at_acc1"][0].low, top.candidate_effects()["k3_at_acc1"][0].high) == (-1, 2)


def test_the_workflow_names_the_cubic_spring_at_the_driving_point(chain):
    from bayes_update.core.discrepancy import DiscrepancySettings, find_discrepancy

    model = ModalModel.from_dataset(chain, updated=[1, 2], candidates=_candidates(chain), driving_point="acc1")
    t0 = time.perf_counter()
    res = find_discrepancy(chain, model, settings=DiscrepancySettings(), workers=2, log=lambda *a: None)
    seconds = time.perf_counter() - t0
    rows = {r["name"]: (round(float(r["two_ln_B"]), 1), r["excludes_null"]) for r in res.rounds[0]["candidates"]}
    k3 = res.final.theta["k3_at_acc1"] * 1.0  # [N/m^3]: per the unit input's 1 kg (test_modal_calibrate)
    print(f"\nnamed {res.named} ({res.verdict}), k3 {k3:.4g} N/m^3; round 1 (2 ln B, excludes null) {rows}")
    print(f"model runs {res.n_model_runs}, {seconds:.1f} s")
    assert set(rows) == {"k3_at_acc1", "friction_at_acc1", "clearance_at_acc1"}
    assert res.named == ["k3_at_acc1"] and res.verdict == "named", rows
    assert res.gap_after["e_nlin"] < 0.5 * res.gap_before["e_nlin"], (res.gap_before, res.gap_after)
    assert abs(k3 / K3 - 1) < 0.1, k3  # measured 3.649e7, 1.4 % under the chain's 3.7e7


def test_candidates_that_cannot_be_are_refused():
    with pytest.raises(ValueError, match=r"candidates: \['k3_at_acc2'\] already a declared parameter"):
        _model(nonlinear=ELEMS[1:2], candidates=ELEMS[1:2])
    with pytest.raises(ValueError, match="candidates: k3_at_acc2 sits at a sensor's point, but no driving point"):
        ModalModel(MODES, COEFFS, TWO, updated=[1], candidates=ELEMS[1:2], bounds=PRIORS)
    with pytest.raises(ValueError, match=r"candidates: friction at sensor 'acc1' needs v0"):
        _model(candidates=[Nonlinearity("friction", at="acc1")])
    with pytest.raises(ValueError, match=r"bounds\['c3_2'\] is missing"):
        _model(candidates=ELEMS[2:], bounds={})
