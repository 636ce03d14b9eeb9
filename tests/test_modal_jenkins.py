"""The Jenkins element of the modal model (a spring kt in series with a slider that slips at a
stretch ``slip``; bayes_update.models.modal): each check against something independent of its
code.  (a) scipy's DOP853 on the modal equations with the slider's stick and slip phases switched
by events (no play operator, no RK4), in a mode and among coupled modes; (b) the closed forms of
its limits: below the slip the mode is the linear one, with a vanishing slip the linear mode of
stiffness w^2 - kt; (c) a conservation law: in a free decay without viscous damping each half
cycle loses kt slip times the slider's travel, from peak X1 to peak X2 (w^2 - kt)(X1^2 - X2^2) / 2
= kt slip (X1 + X2 - 2 slip); (d) the same joint at a sensor's point and in the mode.  The
constants here are used nowhere else in the repository.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, signal

from bayes_update.models.modal import ModalModel, Nonlinearity
from bayes_update.models.modal.fit import element_bounds

# two modes [Hz, -], a velocity and a displacement sensor, the Jenkins element in mode 1; a
# low-passed force [N rms] whose linear response in mode 1 has the rms q 4.1e-3 m (peak 1.4e-2 m)
FS, N = 500.0, 1500
MODES = [(9.3, 0.021), (27.4, 0.016)]
C = [[0.83, 0.41], [0.37, -0.62]]
SENSORS = ["velocity", "displacement"]
W1 = 2 * np.pi * MODES[0][0]
KT = 0.31 * W1**2  # [1/s^2]: fully slipped, mode 1 falls to 9.3 sqrt(0.69) = 7.7 Hz
SLIP = 9.0e-4  # [m]: 0.22 times the rms of mode 1's linear response


def rel_rms(y, ref):
    return np.sqrt(np.mean((y - ref) ** 2, axis=0) / np.mean(ref**2, axis=0))


def force(rms=7.5, seed=63):
    sos = signal.butter(4, 35.0, fs=FS, output="sos")
    u = signal.sosfilt(sos, np.random.default_rng(seed).standard_normal(N))
    return rms * u / np.std(u)


def event_reference(u, kt, slip):
    """The two sensors by DOP853 (rtol 1e-11) on the modal equations, mode 1 carrying
    -kt z: stuck (z fixed) until the stretch q1 - z reaches +-slip, then slipping (z = q1 -+ slip)
    until q1' changes sign; each switch found by solve_ivp's events, the force linear on each
    sample interval."""
    w = 2 * np.pi * np.array([f for f, _ in MODES])
    zeta = np.array([z for _, z in MODES])
    y = np.zeros(4)  # q1, q2, q1', q2'
    phase = ("stuck", 0.0)  # ("stuck", z) or ("slip", sign of the stretch)
    out = np.zeros((u.size, 4))

    def slider(state, ph):
        return ph[1] if ph[0] == "stuck" else state[0] - ph[1] * slip

    def rhs_of(i, ph):
        def rhs(t, s):
            f = u[i] + (u[i + 1] - u[i]) * (t * FS - i)
            a = f - 2 * zeta * w * s[2:] - w**2 * s[:2]
            a[0] += kt * slider(s, ph)
            return np.concatenate([s[2:], a])

        return rhs

    for i in range(u.size - 1):
        t, t1 = i / FS, (i + 1) / FS
        while True:
            if phase[0] == "stuck":
                z0 = phase[1]
                up = lambda t, s, z0=z0: s[0] - z0 - slip  # noqa: E731
                down = lambda t, s, z0=z0: s[0] - z0 + slip  # noqa: E731
                up.terminal, up.direction, down.terminal, down.direction = True, 1, True, -1
                events = [up, down]
            else:
                turn = lambda t, s: s[2]  # noqa: E731
                turn.terminal, turn.direction = True, -phase[1]
                events = [turn]
            sol = integrate.solve_ivp(
                rhs_of(i, phase), (t, t1), y, "DOP853", rtol=1e-11, atol=1e-15, events=events, max_step=1 / FS / 8
            )
            y = sol.y[:, -1]
            if sol.status != 1:
                break
            t = sol.t[-1]
            if phase[0] == "stuck":
                phase = ("slip", 1.0 if y[0] - phase[1] > 0 else -1.0)
            else:
                phase = ("stuck", y[0] - phase[1] * slip)
        out[i + 1] = y
    Cm = np.array(C)
    return np.column_stack([out[:, 2:] @ Cm[:, 0], out[:, :2] @ Cm[:, 1]])


def model(element=None, substeps=4, beside=(), modes=MODES):
    element = element or Nonlinearity("jenkins", 1, slip=SLIP)
    return ModalModel(
        modes,
        C,
        sensors=SENSORS,
        updated=[],
        nonlinear=[element, *beside],
        bounds={element.name: (0.0, 2 * KT), **{e.name: (-1e6, 1e6) for e in beside}},
        substeps=substeps,
        driving_point="sensor1" if beside else None,
    )


# ---------------------------------------------------------------------------------------------
# (a) against the event-switched DOP853
def test_a_mode_jenkins_matches_the_event_switched_reference():
    u = force()
    ref = event_reference(u, KT, SLIP)
    # the element matters: without it the response differs by 1.0-1.1 times its rms
    assert np.all(rel_rms(event_reference(u, 0.0, SLIP), ref) > 0.3)
    errors, m = [], model(substeps=1)
    for _ in range(6):
        errors.append(rel_rms(m.simulate({"jenkins_1": KT}, u, FS), ref))
        m = m.refined()
    errors = np.array(errors)
    # the default four substeps: measured 3.3e-5 and 3.3e-5; 3x the larger
    assert np.all(errors[2] < 1e-4), errors
    # a reversal inside a step costs O(dt^2) there: the least-squares order over 1 to 32 substeps,
    # measured 1.94 and 1.94 (each doubling 3.7-4.6x); RK4's 4 is lost
    order = np.polyfit(np.arange(6), -np.log2(errors), 1)[0]
    assert np.all((order > 1.6) & (order < 2.4)), order


def test_a_mode_jenkins_among_coupled_modes_matches_the_reference():
    """The same element while a joint (at its null) couples the modes: the mode's Jenkins goes into
    the coupled RK4 as a point of that mode alone, its slider kept by the coupled loop."""
    u = force()
    ref = event_reference(u, KT, SLIP)
    m = model(beside=[Nonlinearity("k3", at="sensor2")])
    err = rel_rms(m.simulate({"jenkins_1": KT, "k3_at_sensor2": 0.0}, u, FS), ref)
    # measured 3.5e-5 and 3.4e-5, as alone; 3x the larger
    assert np.all(err < 1e-4), err


# ---------------------------------------------------------------------------------------------
# (b) the closed forms of its limits
def linear(modes):
    return ModalModel(modes, C, sensors=SENSORS)


def nominal(modes):
    return {f"{q}{k + 1}": v for k, mode in enumerate(modes) for q, v in zip(("f", "zeta"), mode)}


def test_b_below_its_slip_the_mode_is_the_linear_one():
    u = force(rms=0.3)  # mode 1's linear response: its peak 5.7e-4 m, below the slip
    y = model().simulate({"jenkins_1": KT}, u, FS)
    exact = linear(MODES).simulate(nominal(MODES), u, FS)
    # RK4's error on the linear modes (the exact steps against RK4 at four substeps): measured 1.2e-7
    # and 1.1e-7; 3x the larger
    assert np.all(rel_rms(y, exact) < 3.6e-7), rel_rms(y, exact)


def test_b_with_a_vanishing_slip_the_mode_loses_kt():
    """slip 1e-9 m, 1e-6 of the response: the slider follows x, the mode's stiffness is w^2 - kt
    (its frequency 9.3 sqrt(0.69) Hz; the damping 2 zeta w unchanged, so zeta w / w')."""
    u = force()
    y = model(Nonlinearity("jenkins", 1, slip=1e-9)).simulate({"jenkins_1": KT}, u, FS)
    w_slipped = np.sqrt(W1**2 - KT)
    soft = [(w_slipped / (2 * np.pi), MODES[0][1] * W1 / w_slipped), MODES[1]]
    exact = linear(soft).simulate(nominal(soft), u, FS)
    # measured 5.6e-7 and 5.6e-7 (RK4's error, and the slip's 1e-6); 3x
    assert np.all(rel_rms(y, exact) < 1.7e-6), rel_rms(y, exact)


# ---------------------------------------------------------------------------------------------
# (c) a conservation law: the energy a free decay loses is the slider's
def test_c_a_free_decay_loses_kt_slip_times_the_sliders_travel():
    """One mode without viscous damping, thrown by a pulse to 14 slips: from each turning point
    to the next the mode's elastic energy falls by kt slip times the slider's travel."""
    fs, n = 4000.0, 12000
    one = ModalModel(
        [(MODES[0][0], 1e-9)],
        [[1.0]],
        sensors=["displacement"],
        updated=[],
        nonlinear=[Nonlinearity("jenkins", 1, slip=SLIP)],
        bounds={"jenkins_1": (0.0, 2 * KT)},
    )
    u = np.zeros(n)
    u[1:9] = 14 * SLIP * W1 * fs / 8  # [m/s^2]: a velocity of about 14 slip w1 in 2 ms
    q = one.simulate({"jenkins_1": KT}, u, fs)
    # the turning points after the pulse, each by the parabola through its three samples
    i = np.flatnonzero((np.abs(q[1:-1]) >= np.abs(q[:-2])) & (np.abs(q[1:-1]) > np.abs(q[2:])))[1:] + 1
    a, b, c = q[i - 1], q[i], q[i + 1]
    signed = b - (a - c) ** 2 / (8 * (a - 2 * b + c))
    peaks = np.abs(signed)
    # the half cycles in which the slider moved a slip or more (X1 + X2 - 2 slip, its travel, from
    # 30 slips down; below, the travel is the difference of nearly equal numbers: the peaks near
    # +-slip approach it geometrically)
    moving = peaks[1:] + peaks[:-1] > 3 * SLIP
    x1, x2 = peaks[:-1][moving], peaks[1:][moving]
    assert x1.size >= 15 and x1[0] > 15 * SLIP
    lost = (W1**2 - KT) * (x1**2 - x2**2) / 2
    slid = KT * SLIP * (x1 + x2 - 2 * SLIP)
    # measured: at most 3.7e-6 (the parabola's error at 430 samples a cycle, and RK4's); 2.7x that
    assert np.all(np.abs(lost / slid - 1) < 1e-5), lost / slid - 1
    # once stuck (the stretch inside the slip) the mode is linear and undamped about the slider's
    # rest: its turning points repeat
    assert np.all(np.abs(signed[-4:-2] - signed[-2:]) < 1e-6 * peaks[-1]), signed[-4:]


# ---------------------------------------------------------------------------------------------
# (d) a joint at a sensor's point is the mode's element with its constants mapped
def test_d_a_jenkins_at_a_point_is_the_modes_with_kt_and_slip_mapped():
    """One mode seen 0.64 at the driving point d1 and 0.8 at d2: a Jenkins at d2's point, x = 0.8 q,
    its force 0.8 / 0.64 in the mode's equation, is the mode's own with slip / 0.8 and
    kt 0.8^2 / 0.64 (the coupled loop against the single mode's)."""
    cd, c2, slip_p, kt_p = 0.64, 0.8, 7e-4, 0.2 * W1**2
    sensors = [("d1", "displacement"), ("d2", "displacement")]
    at_point = ModalModel(
        [MODES[0]],
        [[cd, c2]],
        sensors=sensors,
        updated=[],
        driving_point="d1",
        nonlinear=[Nonlinearity("jenkins", at="d2", slip=slip_p)],
        bounds={"jenkins_at_d2": (0.0, KT)},
    )
    in_mode = ModalModel(
        [MODES[0]],
        [[cd, c2]],
        sensors=sensors,
        updated=[],
        nonlinear=[Nonlinearity("jenkins", 1, slip=slip_p / c2)],
        bounds={"jenkins_1": (0.0, KT)},
    )
    u = force()
    y_point = at_point.simulate({"jenkins_at_d2": kt_p}, u, FS)
    y_mode = in_mode.simulate({"jenkins_1": kt_p * c2**2 / cd}, u, FS)
    assert (
        rel_rms(y_mode, linear_one(cd, c2, sensors).simulate({"f1": MODES[0][0], "zeta1": MODES[0][1]}, u, FS)).min()
        > 0.1
    )
    assert np.all(rel_rms(y_point, y_mode) < 1e-10), rel_rms(y_point, y_mode)


def linear_one(cd, c2, sensors):
    return ModalModel([MODES[0]], [[cd, c2]], sensors=sensors)


# ---------------------------------------------------------------------------------------------
# (e) its prior and its constant
def test_e_its_default_prior_is_half_the_static_stiffness_of_its_place():
    (kt,) = element_bounds((Nonlinearity("jenkins", 1, slip=SLIP),), np.array(MODES), [force()], FS).values()
    assert kt == (0.0, pytest.approx(0.5 * W1**2, rel=1e-12))


@pytest.mark.parametrize(
    "element, words",
    [
        (Nonlinearity("jenkins", 1), r"jenkins at mode 1 needs slip \[m\] > 0, its spring's stretch"),
        (Nonlinearity("jenkins", 1, slip=-1e-4), r"has slip = -0.0001"),
        (Nonlinearity("jenkins", 1, slip=1e-4, gap=1e-4), r"jenkins at mode 1 takes no gap="),
        (Nonlinearity("clearance", 1, gap=1e-4, slip=1e-4), r"clearance at mode 1 takes no slip="),
    ],
)
def test_e_a_bad_slip_is_refused_by_name(element, words):
    with pytest.raises(ValueError, match=words):
        ModalModel(MODES, C, sensors=SENSORS, nonlinear=[element], bounds={element.name: (0.0, KT)})


# ---------------------------------------------------------------------------------------------
# (f) the scale of a slip: the rms of the linear coordinates, against scipy's lsim
def test_f_coordinate_rms_is_the_linear_responses_by_lsim():
    """Each mode's q by scipy.signal.lsim (the transfer function 1 / (s^2 + 2 zeta w s + w^2), the
    force linear between samples, as the model's), each sensor's point sum_m c_mj q_m."""
    from bayes_update.models.modal.fit import coordinate_rms

    u = force(rms=2.0, seed=64) + 0.7  # the mean is removed first
    t = np.arange(N) / FS
    q = []
    for f, zeta in MODES:
        w = 2 * np.pi * f
        q.append(signal.lsim(([1.0], [1.0, 2 * zeta * w, w**2]), u - u.mean(), t)[1])
    q = np.column_stack(q)
    sensors = [("v", "velocity"), ("d", "displacement")]
    got = coordinate_rms(np.array(MODES), np.array(C), sensors, u, FS, between=[("v", "d")])
    c = np.array(C)
    want = {1: q[:, 0].std(), 2: q[:, 1].std(), "v": (q @ c[:, 0]).std(), "d": (q @ c[:, 1]).std()}
    want["v-d"] = (q @ (c[:, 0] - c[:, 1])).std()  # the relative displacement of the two points
    assert got.keys() == want.keys()
    # both exact for a force linear between samples (lsim: the matrix exponential of the augmented
    # system; the model: the closed-form first-order hold): measured 2e-15 at most
    assert all(abs(got[k] / want[k] - 1) < 1e-12 for k in want), {k: got[k] / want[k] - 1 for k in want}
