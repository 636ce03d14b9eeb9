"""A GVT-like campaign through the modal model: calibrate on the low and high multisines,
predict the held-out middle level and both sweeps; the posterior honest about a model that
is wrong.

The records come from ``tests/gvt_rig.py`` (a wing in physical coordinates with a store on a
joint of friction and clearance, six modes in 2-12 Hz, two above; every mode softens with
level, the store's heave mode by 3-4.5 % with its damping rising 0.9 -> 4-5 %).  The model is
the one a user builds from the first look: ``ModalModel.from_dataset`` with one residual mode
above the band, the joint mode's frequency and damping updated and a friction in its
coordinate.  It is wrong in form (the other five modes are fixed at their low-level values
while the structure softens them; the joint is friction and clearance between two bodies,
not a friction in one mode): it misses the high level by a third of its rms.  The reference
is a direct output-error fit of the same model (``scipy.optimize.least_squares`` on the two
estimation records' time histories, each sensor over its declared noise).

Measured (seed 5): held-out error calibrate / direct fit 1.065 (the middle level), 1.049 and
1.000 (the sweeps); ``sample`` 304 runs, R-hat 1.006, the direct fit's values 0.9, 1.2 and
0.9 posterior sd from its means: the model-form error measured at the MAP (2.9 % and 0.6 %
of the two tests' outputs) widens the likelihood, where the model's own discretisation error
is nil.
"""

from __future__ import annotations

import gvt_rig
import numpy as np
import pytest
from scipy.optimize import least_squares

import bayes_update as bu
from bayes_update.models.modal import ModalModel, Nonlinearity

SEED = 5
ROLES = {
    "ms_low": "linear",
    "ms_mid": "validation",
    "ms_high": "nonlinear",
    "sweep_low": "validation",
    "sweep_high": "validation",
}
FRICTION_V0 = 0.01  # the friction's smoothing velocity in the mode's coordinate
BOUNDS = {"zeta2": (0.003, 0.08), "f2": (3.6, 4.1)}  # the joint mode's: 0.9 % at low level, 4.4 % at high
# the bar: calibrate's held-out error at most 1.25x the direct fit's (measured 1.000-1.065)
RATIO = 1.25


def _centred(a):
    return a - a.mean(axis=0)


def _model(data):
    return ModalModel.from_dataset(
        data,
        updated=[2],
        nonlinear=[Nonlinearity("friction", 2, v0=FRICTION_V0)],
        residual_modes=1,
        bounds=BOUNDS,
    )


def _error(model, theta, test, fs) -> float:
    """rms over the sensors of ||y - y_model|| / ||y|| (means removed)."""
    y = _centred(model.simulate(theta, _centred(test.force), fs))
    ref = _centred(test.response)
    return float(
        np.sqrt(np.mean([(np.linalg.norm(ref[:, j] - y[:, j]) / np.linalg.norm(ref[:, j])) ** 2 for j in range(3)]))
    )


def _direct_fit(data, model, starts) -> dict:
    fs = data.sampling_rate_hz
    noise = data.extra["truth"]["noise_sd"]
    sd = np.array([noise[s] for s, _ in data.sensors])
    tests = [t for t in data.tests if t.role in ("linear", "nonlinear")]
    names = [p.name for p in model.parameters]
    lo = np.array([p.low for p in model.parameters])
    hi = np.array([p.high for p in model.parameters])

    def residual(x):
        theta = dict(zip(names, x))
        return np.concatenate(
            [
                ((_centred(t.response) - _centred(model.simulate(theta, _centred(t.force), fs))) / sd).ravel()
                for t in tests
            ]
        )

    best = min((least_squares(residual, x0, bounds=(lo, hi), x_scale=hi - lo) for x0 in starts), key=lambda r: r.cost)
    return dict(zip(names, map(float, best.x)))


@pytest.fixture(scope="module")
def campaign():
    data = gvt_rig.make_campaign(seed=SEED, roles=ROLES)
    model = _model(data)
    cal = bu.calibrate(data, model, workers=2, progress=False, log=lambda *a: None)
    names = [p.name for p in model.parameters]
    box = np.array([[p.low, p.high] for p in model.parameters])
    direct = _direct_fit(data, model, [np.array([cal.theta[n] for n in names]), box.mean(axis=1)])
    return data, model, cal, direct


def test_calibrate_predicts_the_held_out_level_and_the_sweeps_like_a_direct_fit(campaign):
    data, model, cal, direct = campaign
    fs = data.sampling_rate_hz
    # the model is wrong in form, and calibrate says so
    assert any("test ms_high by" in w for w in cal.fit_warnings), cal.fit_warnings
    for name in ("ms_mid", "sweep_low", "sweep_high"):
        test = data.test(name)
        e_cal, e_direct = _error(model, cal.theta, test, fs), _error(model, direct, test, fs)
        print(f"\n{name}: calibrate {e_cal:.4f}, direct fit {e_direct:.4f} (ratio {e_cal / e_direct:.3f})")
        assert e_cal <= RATIO * e_direct, (name, e_cal, e_direct)


def test_the_posterior_of_a_wrong_model_covers_the_direct_fit(campaign):
    data, model, _, direct = campaign
    post = bu.sample(data, model, bu.PosteriorSettings(seed=0), workers=2, progress=False, log=lambda *a: None)
    d = post.diagnostics
    print(f"\nsample: {post.n_model_runs['total']} runs, R-hat {d['max_r_hat']:.4f}")
    assert d["max_r_hat"] < 1.01 and min(d["min_ess_bulk"], d["min_ess_tail"]) >= 400, d
    for p in model.parameters:
        x = post.idata.posterior[p.name].values.ravel()
        shift = (direct[p.name] - x.mean()) / x.std()
        print(f"{p.name}: {x.mean():.5g} +- {x.std():.2g}; the direct fit {direct[p.name]:.5g} ({shift:+.2f} sd)")
        assert abs(shift) < 3.0, (p.name, shift)
    # the width comes from the model-form error measured at the MAP, not from the noise
    scales = post.likelihood.scales
    assert all(sc.model_form_sd > 10 * sc.noise_sd for sc in scales.values()), scales


def _joint_scale(data) -> float:
    """The joint mode's coordinate [m]: the geometric mean of its rms in the linear response to
    the lowest and the highest estimation level (``ModalModel.coordinate_rms``), where its
    frequency and damping move: the slip of a Jenkins element and the gap of a clearance."""
    rms = ModalModel.from_dataset(data, updated=[2], residual_modes=1, bounds=BOUNDS).coordinate_rms(data)
    return float(np.sqrt(rms["ms_low"][2] * rms["ms_high"][2]))


def test_discrepancy_names_the_joints_micro_slip_and_the_held_out_error_drops():
    """The linear model (the joint mode's frequency and damping updated) and five candidates in
    that mode's coordinate: a cubic spring, a cubic damper, a smooth Coulomb friction, a clearance
    and a Jenkins element (stick, then slip).  The rig's joint is four smoothed Jenkins elements
    and a preloaded clearance between the wing and the store: a micro-slip, whose damping rises
    and frequency falls with level.  Measured (seed 5; the slip and gap 8.2e-3 m): Jenkins 2 ln B
    112 (the others -10 to 0), kt 87 +- 37 1/s^2, named alone; re-updated with it, the held-out
    middle level 14.5 -> 8.9 %, the low sweep 17.6 -> 10.1 %, the high sweep 42.1 -> 42.5 %; 3162
    runs, 45 s.  Seeds 7 and 9: named alone, the naming round's fit 16.7 -> 12.0 % and 12.2 -> 7.3 %
    (middle), 18.2 -> 10.2 % and 16.4 -> 9.9 % (low sweep)."""
    data = gvt_rig.make_campaign(seed=SEED, roles=ROLES)
    scale = _joint_scale(data)
    candidates = [
        Nonlinearity("k3", 2),
        Nonlinearity("c3", 2),
        Nonlinearity("friction", 2, v0=FRICTION_V0),
        Nonlinearity("clearance", 2, gap=scale),
        Nonlinearity("jenkins", 2, slip=scale),
    ]
    linear = ModalModel.from_dataset(data, updated=[2], candidates=candidates, residual_modes=1, bounds=BOUNDS)
    res = bu.find_discrepancy(data, linear, workers=2, progress=False, log=lambda *a: None)
    print(f"\nnamed {res.named}; {res.n_model_runs['total']} runs; {res.gap_sentence()}")
    for row in res.rounds[0]["candidates"]:
        print(f"  {row['name']}: 2 ln B = {row['two_ln_B']:.1f}")
    assert res.named == ["jenkins_2"], res.named
    before, after = res.gap_before["held_out_tests"], res.gap_after["held_out_tests"]
    for name in ("ms_mid", "sweep_low", "sweep_high"):
        print(f"  {name}: {before[name]['relative_error']:.4f} -> {after[name]['relative_error']:.4f}")
    # measured 0.61 and 0.57 of the error before (seeds 7 and 9, the naming round's fit: 0.72, 0.56;
    # 0.59, 0.60)
    assert after["ms_mid"]["relative_error"] < 0.8 * before["ms_mid"]["relative_error"]
    assert after["sweep_low"]["relative_error"] < 0.8 * before["sweep_low"]["relative_error"]
    # its signature: the joint mode's frequency and damping in every test, model against measured
    # (median over the tests of their difference in % and percentage points), measured 6.00 -> 1.12
    sig = res.signature["jenkins_2"]
    assert sig["signature"] == "mode 2" and sig["after"] < 0.4 * sig["before"], sig
    # the high sweep drives the other modes too, whose softening no element in mode 2 gives: a gap remains
    assert not res.explains_gap and "A gap remains with jenkins_2" in res.gap_sentence()
    # and the harmonics say so too: on the lines above the band the high multisine holds -26.2 dB
    # of the output at mid, the named model -67.4 dB (-inf before: linear); the Jenkins element
    # gives the joint mode's level dependence, not the joint's distortion (the rig's four slips and
    # preloaded clearance act between two points, the element in one mode's coordinate)
    high = res.diagnostics_after["distortion"]["ms_high.csv"]["mid"]["any"]
    assert high["measured_detected"] and high["model_db"] < high["measured_db"] - 20, high
    # and the summary says which: the multisine's lines and the high sweep's even harmonics (the
    # preloaded clearance acts on one side; a Jenkins element in a mode is symmetric: none)
    left = {(r["test"], r["sensor"], r["class"]) for r in res.diagnostics_after["harmonics_left"]}
    assert {("ms_high.csv", "mid", "any"), ("sweep_high.csv", "mid", "even")} <= left, left
    from bayes_update.reports.discrepancy import format_result

    assert "harmonics left: sweep_high.csv mid even" in format_result(res)
    fig = linear.diagnostics_figure(res.diagnostics_after)  # the discrepancy report's figure
    shown = sum(bool(m["freq_hz"]) for m in res.diagnostics_after["measured"])  # not the residual mode
    assert shown == 6 and len(fig.axes) == 2 * shown + 1 and fig.axes[-1].get_ylabel().startswith("distortion")
