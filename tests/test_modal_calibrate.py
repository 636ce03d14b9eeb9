"""The modal model of the first look, calibrated on a structure of another form (issue 44's first
slice): ``ModalModel.from_dataset`` then ``bayes_update.calibrate``.

The records come from a two-mass chain in physical coordinates (masses 0.63 and 0.41 kg; springs
to ground 2710 N/m at mass 1 and 1830 N/m between the masses; Rayleigh damping 3.1 1/s and
2.7e-5 s; a cubic spring to ground at mass 1, 3.7e7 N/m^3), solved by scipy's DOP853 on the force
joined linearly between samples, with the force on mass 1 and accelerometers on both masses, at
fs = 400 Hz; 1 % noise on every channel.  Three tests of band-limited random force: low (linear),
high (nonlinear) and a middle level held out for validation.

The modal model has one cubic spring in the first mode's equation: the chain's spring acts on
the physical coordinate x1 = phi_11 q_1 + phi_12 q_2, so the model is of another form (it leaves
out the spring's coupling of the modes), as a user's modal model of a structure with a joint is.
The test asks what a user needs of it: the calibrated model predicts the held-out middle level
better than the linear one it started from, by the factor measured (in the comment), and its
first mode lies within 0.5 % of the chain's.
"""

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import butter, sosfiltfilt

import bayes_update as bu
from bayes_update.data.dataset import Dataset, Record
from bayes_update.models.modal import ModalModel, Nonlinearity

FS, N = 400.0, 4096
M = np.diag([0.63, 0.41])
K = np.array([[2710.0 + 1830.0, -1830.0], [-1830.0, 1830.0]])
C = 3.1 * M + 2.7e-5 * K
K3 = 3.7e7
SENSORS = [("acc1", "acceleration"), ("acc2", "acceleration")]
LEVELS = {"low": ("linear", 0.05, 11), "high": ("nonlinear", 2.4, 12), "middle": ("validation", 1.3, 13)}


def _record(level, seed):
    rng = np.random.default_rng(seed)
    u = sosfiltfilt(butter(4, (3.0, 60.0), "bandpass", fs=FS, output="sos"), rng.standard_normal(N))
    u = level * u / np.std(u)
    t = np.arange(N) / FS
    Minv = np.linalg.inv(M)

    def rhs(tt, s):
        x, v = s[:2], s[2:]
        f = np.array([np.interp(tt, t, u) - K3 * x[0] ** 3, 0.0])
        return np.concatenate([v, Minv @ (f - C @ v - K @ x)])

    sol = solve_ivp(rhs, (0, t[-1]), np.zeros(4), t_eval=t, method="DOP853", rtol=1e-9, atol=1e-12, max_step=0.5 / FS)
    x, v = sol.y[:2], sol.y[2:]
    f = np.vstack([u - K3 * x[0] ** 3, np.zeros(N)])
    a = (Minv @ (f - C @ v - K @ x)).T
    noisy_u = u + 0.01 * np.std(u) * rng.standard_normal(N)
    noisy_a = a + 0.01 * np.std(a, axis=0) * rng.standard_normal(a.shape)
    return t, noisy_u, noisy_a, a


@pytest.fixture(scope="module")
def campaign():
    tests, clean = [], {}
    for name, (role, level, seed) in LEVELS.items():
        t, u, y, a = _record(level, seed)
        tests.append(Record(f"{name}.csv", "noise", name, role, t, u, y, sensors=SENSORS))
        clean[name] = a
    return Dataset("two-mass chain, cubic spring at mass 1", FS, None, tests), clean


def _error(model, theta, record, clean):
    """rms of (model - clean response) over the clean response's, both sensors."""
    y = model.simulate(theta, record.force, FS)
    return float(np.sqrt(np.mean((y - clean) ** 2) / np.mean(clean**2)))


def test_a_one_mode_element_on_the_chain_is_told_where_it_misses(campaign):
    """The one-mode element cannot follow a spring at a physical point (it acts on both modes):
    measured, with f1 and zeta1 at the linear test's values, the high level stays 25.1-26.6 % off
    for k3_1 from 0 to 1e7 (noise 1 %).  What calibrate must then do: get the linear part right
    (its first stage: f1 7.0857 Hz for the chain's 7.0852) and say that the model misses the
    tests beyond their noise and that the tests disagree on f1 (an amplitude-dependent effect
    the model lacks), rather than report a fit."""
    data, clean = campaign
    model = ModalModel.from_dataset(data, updated=[1], nonlinear=[("k3", 1)])
    w, _ = np.linalg.eig(np.linalg.solve(M, K))
    f1 = float(np.sqrt(np.min(w.real)) / (2 * np.pi))
    cal = bu.calibrate(data, model)
    assert abs(cal.stage1["f1"] / f1 - 1) < 3e-4  # measured 7e-5
    warnings = " ".join(cal.fit_warnings)
    assert "the model misses test" in warnings and "test high by" in warnings
    assert [d["parameter"] for d in cal.disagreement] == ["f1"]


def test_a_joint_at_the_driving_point_follows_the_chain(campaign):
    """The chain's spring as what it is: a joint at mass 1, the point the force drives and acc1
    measures (``Nonlinearity("k3", at="acc1")``, ``driving_point="acc1"``).  Its force enters every
    mode's equation (share c_m1 / c_m1 = 1) and acts on x1 = sum_m c_m1 q_m, the fitted acc1
    coefficients, positive.  Its parameter is the chain's k3 per the unit input's 1 kg
    (bayes_update.models.modal.joints): k3 [N/m^3] = k3_at_acc1 [1/(m^2 s^2)] x 1 kg, with no mass
    normalisation to supply, since the measured force fixes the coefficients' scale (c_m1 =
    phi_1m^2 x 1 kg); the fitted c_m1 enter the model through x1, not this relation.

    Measured: calibrated, the held-out middle level is 0.79 % off (its force's own 1 % noise
    accounts for 0.61 %: the model at the chain's modes and k3, on that noisy force), against
    10.2 % for the linear model it started from, a factor 12.9; k3 3.58e7 N/m^3, 3.2 % under the
    chain's 3.7e7 (4 of its reported sd), in 408 model runs.  The miss is the force's noise, which
    the likelihood leaves out (errors in the input): on the same records with the clean force,
    calibrate finds k3 3.696e7 (0.1 % under, 1.2 sd) and warns of nothing, where on the noisy
    force it warns that the tests disagree on f1, f2 and zeta2."""
    data, clean = campaign
    model = ModalModel.from_dataset(
        data, updated=[1, 2], nonlinear=[Nonlinearity("k3", at="acc1")], driving_point="acc1"
    )
    assert np.all(model.coefficients[:, 0] > 0)
    cal = bu.calibrate(data, model)
    theta = dict(cal.theta)
    middle = data.test("middle")
    nominal = {f"{q}{k}": model.modes[k - 1, i] for k in (1, 2) for i, q in enumerate(("f", "zeta"))}
    linear = {**theta, **nominal, "k3_at_acc1": 0.0}
    e_cal, e_lin = _error(model, theta, middle, clean["middle"]), _error(model, linear, middle, clean["middle"])
    k3 = theta["k3_at_acc1"] * 1.0  # [N/m^3]: the parameter times the unit input's 1 kg
    print(
        f"\nheld-out middle level: calibrated {100 * e_cal:.2f} %, linear {100 * e_lin:.2f} % of its rms "
        f"(x{e_lin / e_cal:.1f}); k3 {k3:.4g} N/m^3 (chain {K3:.4g}, sd {cal.sd['k3_at_acc1']:.3g}), "
        f"{cal.n_model_runs} runs"
    )
    assert e_lin / e_cal > 6  # measured 12.9: about half that
    assert abs(k3 / K3 - 1) < 0.1  # measured 3.2 % under: 3x that
