"""The Iwan element of the modal model: n Jenkins sliders in parallel, each of stiffness kt / n,
their slips spread evenly to ``slip`` (s_i = slip i / n), so that a joint slips over a range of
levels (bayes_update.models.modal).  Each check against a closed form of the physics, not the code:

(a) a free decay without viscous damping, every slider slipping in each half cycle: from peak X1
    to peak X2 the mode loses (w^2 - kt)(X1^2 - X2^2) / 2 = sum_i (kt / n) s_i (X1 + X2 - 2 s_i),
    each slider's slip force times its travel (the Jenkins element's law, summed);
(b) a slow cycle of amplitude X: the loop's area, the work of the force over a cycle less the
    viscous damping's, is Masing's sum_i 4 (kt / n) s_i (X - s_i) over the sliders with s_i < X
    (the others stick and store, not dissipate): at an amplitude between the slips, some stuck;
(c) at a sensor's point it is the mode's own with kt and slip mapped (as a Jenkins element);
(d) its default prior is the Jenkins element's, and its name and constant are checked alike.
The constants here are used nowhere else in the repository.
"""

from __future__ import annotations

import numpy as np
import pytest

from bayes_update.models.modal import ModalModel, Nonlinearity
from bayes_update.models.modal.fit import element_bounds
from bayes_update.models.modal.spec import IWAN_SLIDERS

F1 = 6.7  # [Hz] the mode
W1 = 2 * np.pi * F1
KT = 0.27 * W1**2  # [1/s^2]: every slider slipping, the mode falls to 6.7 sqrt(0.73) = 5.7 Hz
SLIP = 1.3e-3  # [m]: the largest slip
SLIPS = SLIP * np.arange(1, IWAN_SLIDERS + 1) / IWAN_SLIDERS


def one_mode(zeta=1e-9, sensors=("displacement",), coefficients=((1.0,),), **element):
    element = Nonlinearity("iwan", 1, slip=SLIP) if not element else Nonlinearity("iwan", **element)
    return ModalModel(
        [(F1, zeta)],
        [list(c) for c in coefficients],
        sensors=list(sensors),
        updated=[],
        nonlinear=[element],
        bounds={element.name: (0.0, 2 * KT)},
    )


def test_a_free_decay_loses_each_sliders_slip_force_times_its_travel():
    """One mode without viscous damping, thrown by a pulse to about 12 times the largest slip:
    the half cycles whose travel X1 + X2 exceeds 3 times it (every slider slipping)."""
    fs, n = 4000.0, 16000
    u = np.zeros(n)
    u[1:9] = 12 * SLIP * W1 * fs / 8  # [m/s^2]: a velocity of about 12 slip w1 in 2 ms
    q = one_mode().simulate({"iwan_1": KT}, u, fs)
    i = np.flatnonzero((np.abs(q[1:-1]) >= np.abs(q[:-2])) & (np.abs(q[1:-1]) > np.abs(q[2:])))[1:] + 1
    a, b, c = q[i - 1], q[i], q[i + 1]
    peaks = np.abs(b - (a - c) ** 2 / (8 * (a - 2 * b + c)))  # each turning point by its parabola
    moving = peaks[1:] + peaks[:-1] > 3 * SLIP
    x1, x2 = peaks[:-1][moving], peaks[1:][moving]
    assert x1.size >= 20 and x1[0] > 10 * SLIP
    lost = (W1**2 - KT) * (x1**2 - x2**2) / 2
    slid = (KT / IWAN_SLIDERS) * np.sum(SLIPS[:, None] * (x1 + x2 - 2 * SLIPS[:, None]), axis=0)
    # measured: at most 1.0e-6 over 30 half cycles from 13.4 slips down (the parabola's error at
    # 600 samples a cycle, and RK4's); 3x that
    assert np.all(np.abs(lost / slid - 1) < 3e-6), lost / slid - 1


@pytest.mark.parametrize("amplitude", [0.6 * SLIP, 2.5 * SLIP])
def test_b_a_slow_cycle_dissipates_masings_sum(amplitude):
    """Driven far below the mode (0.4 Hz, its amplitude raised over the first cycle), the
    displacement follows the force: over the third cycle the force's work less the viscous
    damping's (2 zeta w q'^2, from the velocity sensor) is the loop's area (the inertia's work is
    nil over a closed cycle), against sum_i 4 (kt / n) s_i (X - s_i) over the sliders that slip,
    X the cycle's half range.  At 0.6 slip two of the four sliders slip, at 2.5 slip all."""
    fs, f, cycles, zeta = 2000.0, 0.4, 3, 0.02
    t = np.arange(int(cycles * fs / f) + 1) / fs
    ramp = np.where(t < 1 / f, np.sin(np.pi * t * f / 2) ** 2, 1.0)
    # the force that would hold a linear spring of w^2 - kt/2 at the amplitude: about there
    u = (W1**2 - 0.5 * KT) * amplitude * np.sin(2 * np.pi * f * t) * ramp
    model = one_mode(zeta=zeta, sensors=("displacement", "velocity"), coefficients=((1.0, 1.0),))
    y = model.simulate({"iwan_1": KT}, u, fs)
    q, v, last = y[:, 0], y[:, 1], t >= (cycles - 1) / f
    X = (q[last].max() - q[last].min()) / 2
    work = np.trapezoid(u[last], q[last]) - np.trapezoid(2 * zeta * W1 * v[last] ** 2, t[last])
    s = SLIPS[SLIPS < X]
    masing = 4 * (KT / IWAN_SLIDERS) * np.sum(s * (X - s))
    assert 0 < s.size < IWAN_SLIDERS if amplitude < SLIP else s.size == IWAN_SLIDERS
    # measured: 9e-5 and 2.4e-4 (the cycle closes to 0.09 % and 0.05 % of X: what the stick-slip
    # switches leave ringing); 3x that
    assert work == pytest.approx(masing, rel=7e-4), (work, masing)


def test_c_at_a_point_it_is_the_modes_with_kt_and_slip_mapped():
    """One mode seen 0.5 at the driving point d1 and 0.7 at d2: an Iwan element at d2's point,
    x = 0.7 q and its force 0.7 / 0.5 in the mode's equation, is the mode's own with slip / 0.7
    and kt 0.7^2 / 0.5 (the coupled rows of its sliders at a point and in the mode alike)."""
    cd, c2, kt_p = 0.5, 0.7, 0.15 * W1**2
    sensors = [("d1", "displacement"), ("d2", "displacement")]
    at_point = ModalModel(
        [(F1, 0.02)],
        [[cd, c2]],
        sensors=sensors,
        updated=[],
        driving_point="d1",
        nonlinear=[Nonlinearity("iwan", at="d2", slip=SLIP)],
        bounds={"iwan_at_d2": (0.0, KT)},
    )
    in_mode = ModalModel(
        [(F1, 0.02)],
        [[cd, c2]],
        sensors=sensors,
        updated=[],
        nonlinear=[Nonlinearity("iwan", 1, slip=SLIP / c2)],
        bounds={"iwan_1": (0.0, KT)},
    )
    fs = 500.0
    u = 4.0 * np.sin(2 * np.pi * 5.9 * np.arange(3000) / fs) * np.linspace(0, 1, 3000)
    y_point = at_point.simulate({"iwan_at_d2": kt_p}, u, fs)
    y_mode = in_mode.simulate({"iwan_1": kt_p * c2**2 / cd}, u, fs)
    linear = ModalModel([(F1, 0.02)], [[cd, c2]], sensors=sensors).simulate({"f1": F1, "zeta1": 0.02}, u, fs)
    assert np.min(np.std(y_mode - linear, axis=0) / np.std(linear, axis=0)) > 0.1  # the sliders slip
    np.testing.assert_allclose(y_point, y_mode, rtol=0, atol=1e-10 * np.abs(y_mode).max())


def test_d_its_prior_and_its_constant_are_the_jenkins_elements():
    modes, u = np.array([(F1, 0.02)]), np.sin(np.arange(2000) * 0.05)
    (kt,) = element_bounds((Nonlinearity("iwan", 1, slip=SLIP),), modes, [u], 400.0).values()
    (kj,) = element_bounds((Nonlinearity("jenkins", 1, slip=SLIP),), modes, [u], 400.0).values()
    assert kt == kj == (0.0, pytest.approx(0.5 * W1**2, rel=1e-12))
    with pytest.raises(ValueError, match=r"iwan at mode 1 needs slip \[m\] > 0, the largest of its sliders"):
        one_mode(mode=1)
