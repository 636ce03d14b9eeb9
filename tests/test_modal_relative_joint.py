"""An element between two sensors' points in the modal model (a joint that holds one body on
another: bayes_update.models.modal.joints), against scipy's DOP853 on a three-mass chain in
physical coordinates whose shapes come from scipy.linalg.eigh, the element's force acting +g on
mass 3 and -g on mass 2 on their relative displacement; and its default prior, whose stiffness is
the chain's static stiffness between those two points.  The constants here are used nowhere else
in the repository.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, linalg, signal

from bayes_update.models.modal import ModalModel, Nonlinearity
from bayes_update.models.modal.fit import ELEMENT_SHARE, coordinate_rms, element_bounds

# masses [kg], springs ground-1, 1-2, 2-3 [N/m], C = alpha M + beta K; the force on mass 1
MASS, SPRINGS, ALPHA, BETA = (1.2, 0.8, 0.5), (24000.0, 16000.0, 9000.0), 1.7, 3.0e-5
SENSORS = (("d1", "displacement", 0), ("a2", "acceleration", 1), ("v3", "velocity", 2))
FS, N = 1200.0, 1200


def chain():
    k1, k2, k3 = SPRINGS
    K = np.array([[k1 + k2, -k2, 0.0], [-k2, k2 + k3, -k3], [0.0, -k3, k3]])
    M = np.diag(MASS)
    lam, phi = linalg.eigh(K, M)
    w = np.sqrt(lam)
    modes = [(wm / (2 * np.pi), ALPHA / (2 * wm) + BETA * wm / 2) for wm in w]
    return M, K, ALPHA * M + BETA * K, modes, phi


def force():
    u = signal.sosfilt(signal.butter(4, 90.0, fs=FS, output="sos"), np.random.default_rng(83).standard_normal(N))
    return 9.0 * u / np.std(u)


def reference(u, g):
    """Each sensor's output by DOP853 (rtol 1e-10) on M x'' + C x' + K x = e_1 u - (e_3 - e_2)
    g(x_3 - x_2), the force linear on each sample interval."""
    M, K, C, _, _ = chain()
    Minv = np.linalg.inv(M)
    b = np.array([0.0, -1.0, 1.0])

    def accel(x, v, f):
        return Minv @ (np.array([f, 0.0, 0.0]) - K @ x - C @ v - b * g(x[2] - x[1]))

    X = np.zeros((N, 6))
    for i in range(N - 1):

        def rhs(t, s, i=i):
            return np.concatenate([s[3:], accel(s[:3], s[3:], u[i] + (u[i + 1] - u[i]) * (t * FS - i))])

        X[i + 1] = integrate.solve_ivp(
            rhs, (i / FS, (i + 1) / FS), X[i], "DOP853", rtol=1e-10, atol=1e-14, max_step=1 / FS / 16
        ).y[:, -1]
    A = np.array([accel(s[:3], s[3:], f) for s, f in zip(X, u)])
    kinds = {"displacement": X[:, :3], "velocity": X[:, 3:], "acceleration": A}
    return np.column_stack([kinds[kind][:, j] for _, kind, j in SENSORS])


def model(element, bound):
    _, _, _, modes, phi = chain()
    return ModalModel(
        modes,
        np.array([[phi[j, m] * phi[0, m] for _, _, j in SENSORS] for m in range(3)]),
        sensors=[s[:2] for s in SENSORS],
        updated=[],
        nonlinear=[element],
        bounds={element.name: bound},
        driving_point="d1",
    )


def rel_rms(y, ref):
    return np.sqrt(np.mean((y - ref) ** 2, axis=0) / np.mean(ref**2, axis=0))


CASES = {
    # a cubic spring [N/m^3]: at the rms relative displacement of the linear response (1.1e-4 m)
    # its force is 0.3 of the 2-3 spring's, its stiffness at the peaks some 4x that spring's
    "k3": (Nonlinearity("k3", at="v3", to="a2"), 7.0e10, lambda d: 7.0e10 * d**3),
    # a clearance [N/m] beyond a gap [m] of 0.6 times that rms
    "clearance": (
        Nonlinearity("clearance", at="v3", to="a2", gap=6.6e-5),
        2.0e4,
        lambda d: 2.0e4 * (max(d - 6.6e-5, 0.0) + min(d + 6.6e-5, 0.0)),
    ),
}


@pytest.mark.parametrize("kind", sorted(CASES))
def test_an_element_between_two_points_matches_dop853_on_the_chain(kind):
    element, value, g = CASES[kind]
    u = force()
    ref = reference(u, g)
    # the element matters: without it the response differs by 0.99-1.7 times its rms
    assert np.all(rel_rms(reference(u, lambda d: 0.0), ref) > 0.5)
    m, errors = model(element, (0.0, 2 * value)), []
    for _ in range(3):
        errors.append(rel_rms(m.simulate({element.name: value}, u, FS), ref))
        m = m.refined()
    errors = np.array(errors)
    if kind == "k3":
        # the default four substeps: measured 1.0e-5, 2.1e-4, 8.1e-5 (the spring's stiffness at the
        # peaks, not in the step's sizing); 3x the largest
        assert np.all(errors[0] < 6.3e-4), errors
        # RK4's order 4: each halved step divides the error by 16.4-17.0 (measured)
        ratios = errors[:-1] / errors[1:]
        assert np.all((ratios > 13) & (ratios < 20)), ratios
    else:
        # the kink's O(dt^2) at each crossing: measured 1.5e-5, 1.6e-4, 5.3e-5 at four substeps,
        # 1.8-2.3x less at eight; 3x the largest, and it falls
        assert np.all(errors[0] < 4.8e-4), errors
        assert np.all(errors[2] < errors[0] / 3), errors


def test_its_name_its_place_and_its_prior():
    """The default prior of a cubic spring between points 3 and 2: a quarter of the chain's static
    stiffness between them over the rms relative displacement squared, the stiffness from the modes'
    flexibility sum_m (phi_3m - phi_2m)^2 / w_m^2, checked against K's own inverse,
    1 / ((e3 - e2)^T K^-1 (e3 - e2))."""
    from bayes_update.models.modal.dynamics import mode_responses

    e = Nonlinearity("k3", at="v3", to="a2")
    assert e.name == "k3_between_v3_a2" and e.point == "v3-a2" and e.where == "sensors 'v3' and 'a2'"
    m = model(e, (-1.0, 1.0))
    _, K, _, modes, _ = chain()
    u = force()
    low, top = element_bounds((e,), np.array(modes), [u], FS, m.coefficients, m.sensors, 0)[e.name]
    b = np.array([0.0, -1.0, 1.0])
    stiffness = 1.0 / (b @ np.linalg.solve(K, b))
    r = mode_responses(u - u.mean(), FS, np.array(modes)[:, 0], np.array(modes)[:, 1])[:, :, 0]
    x = r @ (m.coefficients[:, 2] - m.coefficients[:, 1])
    assert low == -top and top == pytest.approx(ELEMENT_SHARE * stiffness / np.mean(x**2), rel=1e-9)


def test_bad_pairs_are_refused_by_name():
    with pytest.raises(ValueError, match="between sensor 'a2' and itself"):
        model(Nonlinearity("k3", at="a2", to="a2"), (-1.0, 1.0))
    with pytest.raises(ValueError, match="at sensor 'tip', which does not exist"):
        model(Nonlinearity("k3", at="a2", to="tip"), (-1.0, 1.0))
    with pytest.raises(ValueError, match="to='a2' needs at="):
        model(Nonlinearity("k3", 1, to="a2"), (-1.0, 1.0))
    m = model(Nonlinearity("k3", at="v3", to="a2"), (-1.0, 1.0))
    for pair in (("a2", "a2"), ("a2", "tip"), ("a2",)):
        with pytest.raises(ValueError, match=r"between: .* must name two different sensors of \['d1', 'a2', 'v3'\]"):
            coordinate_rms(m.modes, m.coefficients, m.sensors, force(), FS, between=[pair])
