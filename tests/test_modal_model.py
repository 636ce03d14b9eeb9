"""The modal superposition model (bayes_update.models.modal), each check against something
independent of its code: the closed-form FRF with the first-order hold's images summed, scipy's
DOP853 on the modal equations, a 2-DOF mass-spring system simulated by scipy.signal.lsim, and the
framework's own contract checks.  The constants here are used nowhere else in the repository.
"""

from __future__ import annotations

import json
import pickle

import numpy as np
import pytest
from scipy import integrate, linalg, signal

from bayes_update.core.model import ModelError, check_contract, check_model_on
from bayes_update.core.preflight import preflight
from bayes_update.data.dataset import Dataset, Record
from bayes_update.models.modal import ModalModel, Nonlinearity

# (a) three linear modes [Hz, -], sensors of the three kinds, coefficients [-], residual terms
# (m/N, m/N, 1/kg); a periodic multisine on exact DFT lines
A_FS, A_PERIOD, A_PERIODS = 3072.0, 3072, 6
A_MODES = [(23.9, 0.043), (87.6, 0.031), (211.3, 0.052)]
A_C = [[0.83, -0.37, 1.21], [-0.58, 0.94, 0.46], [0.29, 0.23, -0.71]]
A_RESIDUAL = [3.1e-7, 2.2e-8, 0.017]
A_LINES = np.arange(3, 291)  # 3-290 Hz


def multisine_period(seed):
    rng = np.random.default_rng(seed)
    X = np.zeros(A_PERIOD, complex)
    X[A_LINES] = np.exp(2j * np.pi * rng.random(A_LINES.size))
    X[A_PERIOD - A_LINES] = np.conj(X[A_LINES])
    x = np.fft.ifft(X).real
    return 7.3 * x / np.std(x)  # [N] rms


def foh_frf(lines, n, fs, f_hz, zeta, order, images=2000):
    """The sampled steady state's FRF at DFT lines ``lines`` of a period of ``n`` samples: the
    continuous mode (j w)^p / (w_m^2 - w^2 + 2 j zeta w_m w) driven by the samples joined linearly,
    whose Fourier series at f_l + r fs is X[l] sinc^2(l/n + r) / n; sampling folds every image r
    onto line l (``images`` each side: the terms fall as 1/r^3 or faster).  For p = 2,
    (j w)^2 / den = 1 - (w_m^2 + 2 j zeta w_m w) / den, and the constant's images sum to it
    exactly: sum_r sinc^2(x + r) = 1."""
    wm = 2 * np.pi * f_hz
    x = lines[:, None] / n + np.arange(-images, images + 1)[None, :]
    w = 2 * np.pi * x * fs
    den = wm**2 - w**2 + 2j * zeta * wm * w
    if order == 2:
        return 1.0 - np.sum(np.sinc(x) ** 2 * (wm**2 + 2j * zeta * wm * w) / den, axis=1)
    return np.sum(np.sinc(x) ** 2 * (1j * w) ** order / den, axis=1)


def test_linear_modes_match_the_closed_form_steady_state_of_a_multisine():
    model = ModalModel(
        A_MODES, A_C, sensors=["displacement", "velocity", "acceleration"], residual=A_RESIDUAL, updated=[2]
    )
    period = multisine_period(seed=417)
    force = np.concatenate([np.tile(period, A_PERIODS), period[:1]])
    # f2, zeta2 moved off their nominal values: theta reaches the simulation
    f2, z2 = 89.1, 0.027
    y = model.simulate({"f2": f2, "zeta2": z2}, force, A_FS)
    last = y[(A_PERIODS - 1) * A_PERIOD : A_PERIODS * A_PERIOD]
    X = np.fft.fft(period)
    modes = [A_MODES[0], (f2, z2), A_MODES[2]]
    for s, order in enumerate((0, 1, 2)):
        H = sum(A_C[m][s] * foh_frf(A_LINES, A_PERIOD, A_FS, f, z, order) for m, (f, z) in enumerate(modes))
        # the residual terms: the force itself at the samples, or its central difference
        rate = 1j * np.sin(2 * np.pi * A_LINES / A_PERIOD) * A_FS
        H = H + A_RESIDUAL[s] * (rate if order == 1 else 1.0)
        Y = np.zeros(A_PERIOD, complex)
        Y[A_LINES] = H * X[A_LINES]
        Y[A_PERIOD - A_LINES] = np.conj(Y[A_LINES])
        exact = np.fft.ifft(Y).real
        err = np.max(np.abs(last[:, s] - exact)) / np.max(np.abs(exact))
        # measured 0.7e-14 to 1.3e-14 (rounding, and the start's transient: e^-32 of it is left
        # after five periods); 3x the largest.  Without the hold's sinc^2 it would be 3e-2
        assert err < 4e-14, (s, err)


# (b) a Duffing mode beside a linear one, two sensors; the force low-passed noise [N]
B_FS, B_N = 1250.0, 1500
B_MODES = [(26.3, 0.024), (61.7, 0.036)]
B_C = [[1.0, 0.62], [0.47, -0.88]]
B_SENSORS = ["acceleration", "displacement"]


def b_force():
    sos = signal.butter(4, 90.0, fs=B_FS, output="sos")
    u = signal.sosfilt(sos, np.random.default_rng(83).standard_normal(B_N))
    return 40.0 * u / np.std(u)


def dop853_outputs(force, k2=0.0, k3=0.0, c3=0.0):
    """The two sensors from scipy's DOP853 (rtol 1e-10) on the modal equations, one sample
    interval at a time (the force is linear on each: the right-hand side smooth there)."""
    w = 2 * np.pi * np.array([f for f, _ in B_MODES])
    z = np.array([zeta for _, zeta in B_MODES])

    def accel(q, v, f):
        return f - 2 * z * w * v - w**2 * q - np.array([k2 * q[0] ** 2 + k3 * q[0] ** 3 + c3 * v[0] ** 3, 0.0])

    def rhs(t, x, i):
        f = force[i] + (force[i + 1] - force[i]) * (t * B_FS - i)
        return np.concatenate([x[2:], accel(x[:2], x[2:], f)])

    X = np.zeros((force.size, 4))
    for i in range(force.size - 1):
        span = (i / B_FS, (i + 1) / B_FS)
        sol = integrate.solve_ivp(rhs, span, X[i], method="DOP853", rtol=1e-10, atol=1e-14, args=(i,))
        X[i + 1] = sol.y[:, -1]
    A = np.array([accel(x[:2], x[2:], f) for x, f in zip(X, force)])
    C = np.array(B_C)
    return np.column_stack([A @ C[:, 0], X[:, :2] @ C[:, 1]])


def rel_rms(y, ref):
    return np.sqrt(np.mean((y - ref) ** 2, axis=0) / np.mean(ref**2, axis=0))


def b_model(elements, substeps=4):
    bounds = {"k3_1": (-1e9, 1e9), "k2_1": (-1e7, 1e7), "c3_1": (0.0, 100.0)}
    return ModalModel(
        B_MODES,
        B_C,
        sensors=B_SENSORS,
        updated=[],
        nonlinear=[(name.split("_")[0], 1) for name in elements],
        bounds={k: v for k, v in bounds.items() if k in elements},
        substeps=substeps,
    )


def test_a_duffing_mode_matches_dop853_and_rk4_converges_at_fourth_order():
    force = b_force()
    ref = dop853_outputs(force, k3=3.4e8)
    # the cubic spring matters: without it the response differs by 0.9-1.1 times its rms
    assert np.all(rel_rms(dop853_outputs(force), ref) > 0.3)
    model = b_model(["k3_1"], substeps=1)
    errors = []
    for _ in range(4):  # 1, 2, 4 and 8 RK4 steps a sample (this rate and mode need no more)
        errors.append(rel_rms(model.simulate({"k3_1": 3.4e8}, force, B_FS), ref))
        model = model.refined()
    errors = np.array(errors)
    # the default four substeps: measured 3.1e-7 and 3.5e-7 (rms of the error over the rms); 3x that
    assert np.all(errors[2] < 1e-6), errors
    # halving the step divides the error by 2^4: measured 16.3 to 17.7
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 13) & (ratios < 21)), ratios


def test_quadratic_spring_and_cubic_damper_match_dop853():
    force = b_force()
    theta = {"k2_1": 1.3e6, "c3_1": 23.0}
    ref = dop853_outputs(force, **{k.split("_")[0]: v for k, v in theta.items()})
    # the two elements matter: without them the response differs by 0.4-0.5 times its rms
    assert np.all(rel_rms(dop853_outputs(force), ref) > 0.2)
    err = rel_rms(b_model(list(theta)).simulate(theta, force, B_FS), ref)
    # measured 7.5e-8 and 9.4e-8 (four substeps); 2.7x the larger
    assert np.all(err < 2.5e-7), err


# (c, e) a 2-DOF chain: masses [kg], springs ground-1 and 1-2 [N/m], proportional damping
# C = alpha M + beta K [1/s, s]; the force on mass 2, an accelerometer on mass 1 and a
# displacement sensor on mass 2; white force [N rms], 1 % noise on each sensor
C_MASS, C_K1, C_K2, C_ALPHA, C_BETA = (2.7, 1.3), 41000.0, 23000.0, 1.9, 2.3e-5
C_FS, C_N, C_FORCE_RMS, C_NOISE = 512.0, 8192, 5.0, 0.01
C_SENSORS = (("a1", "acceleration"), ("x2", "displacement"))


def chain():
    """(lsim system, modes [(f_hz, zeta)], the modal participations c_ms = phi_sm phi_2m / mu_m)."""
    M = np.diag(C_MASS)
    K = np.array([[C_K1 + C_K2, -C_K2], [-C_K2, C_K2]])
    lam, phi = linalg.eigh(K, M)
    w = np.sqrt(lam)
    modes = [(wm / (2 * np.pi), C_ALPHA / (2 * wm) + C_BETA * wm / 2) for wm in w]
    mu = np.einsum("im,ij,jm->m", phi, M, phi)
    participation = np.array([[phi[0, m] * phi[1, m], phi[1, m] ** 2] for m in range(2)]) / mu[:, None]
    Minv = np.linalg.inv(M)
    A = np.block([[np.zeros((2, 2)), np.eye(2)], [-Minv @ K, -Minv @ (C_ALPHA * M + C_BETA * K)]])
    B = np.concatenate([np.zeros(2), Minv @ [0.0, 1.0]])[:, None]
    out = np.vstack([A[2], [0.0, 1.0, 0.0, 0.0]])  # mass 1's acceleration, mass 2's displacement
    D = np.array([[(Minv @ [0.0, 1.0])[0]], [0.0]])
    return signal.StateSpace(A, B, out, D), modes, participation


def chain_record(seed, level=1.0):
    """(force, clean response, noisy response, noise sd per sensor) by lsim, the force linear
    between samples (interp=True, as the model takes it)."""
    system = chain()[0]
    rng = np.random.default_rng(seed)
    u = level * C_FORCE_RMS * rng.standard_normal(C_N)
    y = signal.lsim(system, u, np.arange(C_N) / C_FS, interp=True)[1]
    sd = C_NOISE * np.std(y, axis=0)
    return u, y, y + sd * rng.standard_normal(y.shape), sd


def test_from_modes_fits_a_record_of_another_generator_and_predicts_a_held_out_one():
    _, modes, participation = chain()
    u, _, y_noisy, _ = chain_record(601)
    model = ModalModel.from_modes(modes, u, y_noisy, C_FS, sensors=C_SENSORS)
    # the coefficients are the modes' participations: measured within 5.5e-4 of them; ~3x that
    assert np.allclose(model.coefficients, participation, rtol=1.5e-3, atol=0), model.coefficients
    # the fit leaves the noise: measured 0.998 and 1.006 % of each sensor's rms
    assert all(0.0097 < v < 0.0103 for v in model.record_misfit.values()), model.record_misfit
    u2, clean2, noisy2, sd2 = chain_record(602)
    theta = {f"{q}{m + 1}": v for m, mode in enumerate(modes) for q, v in zip(("f", "zeta"), mode)}
    predicted = model.simulate(theta, u2, C_FS)
    off_truth = np.sqrt(np.mean((predicted - clean2) ** 2, axis=0)) / sd2
    off_record = np.sqrt(np.mean((predicted - noisy2) ** 2, axis=0)) / sd2
    # measured 0.022 and 0.011 noise sd from the clean response; 3x the larger
    assert np.all(off_truth < 0.07), off_truth
    # and so the held-out record is missed by its noise alone: measured 1.001 and 1.016 sd
    assert np.all(off_record < 1.05), off_record


def chain_dataset():
    t = np.arange(C_N) / C_FS
    tests = []
    for name, role, seed, level in (("low", "linear", 611, 1.0), ("high", "nonlinear", 612, 3.0)):
        u, _, y, _ = chain_record(seed, level)
        tests.append(Record(f"{name}.csv", "noise", name, role, t, u, y, sensors=C_SENSORS))
    return Dataset("two-dof-chain", C_FS, None, tests)


def test_from_dataset_passes_the_contract_checks_and_pickles():
    data = chain_dataset()
    model = ModalModel.from_dataset(data, updated=[1], nonlinear=[("k3", 1), Nonlinearity("c3", 1)])
    truth = chain()[1]
    # the modes the first look finds: measured 2e-6 (frequencies) and 3.4e-4 (damping) off; 3x that
    assert np.allclose(model.modes, truth, rtol=1e-3)
    assert [p.name for p in model.parameters] == ["f1", "zeta1", "k3_1", "c3_1"]
    assert [p.null for p in model.parameters] == [None, None, 0.0, 0.0]
    f1 = model.parameters[0]
    assert np.isclose(f1.low, 0.95 * model.modes[0, 0]) and np.isclose(f1.high, 1.05 * model.modes[0, 0])
    space = check_model_on(model, data)
    assert space.names == ("f1", "zeta1", "k3_1", "c3_1")
    preflight(data, model)  # the checks every command runs first, the model's check_dataset among them
    check_contract(model.refined())
    json.dumps(model.describe())
    clone = pickle.loads(pickle.dumps(model))
    theta = space.center()
    force = data.tests[1].force
    assert np.array_equal(clone.simulate(theta, force, C_FS), model.simulate(theta, force, C_FS))
    assert model.refined().substeps == 2 * model.substeps
    other = Dataset("swapped", C_FS, None, [chain_dataset_swapped()])
    with pytest.raises(ValueError, match="sensors"):
        model.check_dataset(other)


def chain_dataset_swapped():
    t = np.arange(64) / C_FS
    u = np.sin(t)
    return Record("x.csv", "noise", "low", "linear", t, u, np.column_stack([u, u]), sensors=C_SENSORS[::-1])


# (d) bad input, each refused with a ValueError that names what is wrong
D_MODES = [(12.7, 0.019)]


def d_model(**kw):
    args = {"modes": D_MODES, "coefficients": [0.7], "sensors": "velocity"}
    return ModalModel(**{**args, **kw})


@pytest.mark.parametrize(
    "kw, words",
    [
        ({"modes": [(-12.7, 0.019)]}, "modes: mode 1 has frequency"),
        ({"modes": [(12.7, 0.0)]}, "modes: mode 1 has damping ratio"),
        ({"modes": [(12.7, 1.3)]}, "modes: mode 1 has damping ratio"),
        ({"modes": [12.7]}, "modes must be"),
        ({"sensors": "strain"}, "kind 'strain'"),
        ({"coefficients": [0.7, 0.1]}, r"coefficients has shape \(2, 1\)"),
        ({"coefficients": [0.7j]}, "coefficients must be real"),
        ({"residual": [1e-3, 2e-3]}, r"residual has shape"),
        ({"updated": [2]}, r"updated names mode\(s\) \[2\]"),
        ({"nonlinear": [("k5", 1)]}, "unknown element 'k5'"),
        ({"nonlinear": [("k3", 2)]}, "k3 on mode 2"),
        ({"nonlinear": [("k3", 1)]}, r"bounds\['k3_1'\] is missing"),
        ({"bounds": {"f9": (1.0, 2.0)}}, r"bounds names \['f9'\]"),
        ({"bounds": {"zeta1": (0.01, 1.2)}}, r"bounds\['zeta1'\]"),
        ({"bounds": {"f1": (0.0, 14.0)}}, r"bounds\['f1'\]"),
        ({"substeps": 0}, "substeps"),
        ({"updated": []}, "nothing to update"),
        # (f, c) joints: an element at a sensor that does not exist, at a sensor without a driving
        # point, in no place; a driving point that is no sensor, or where a mode's coefficient is
        # not positive, or too small to be seen there (phi_d = 1e-3 of the mode's largest shape)
        ({"nonlinear": [Nonlinearity("k3", at="acc9")]}, "k3 at sensor 'acc9', which does not exist"),
        ({"nonlinear": [("k3", "sensor1")]}, r"k3_at_sensor1 sits at sensor 'sensor1', but no driving point"),
        ({"nonlinear": [Nonlinearity("k3")]}, "k3 needs one place"),
        ({"driving_point": "acc9"}, "driving_point 'acc9' is not a sensor"),
        (
            {"modes": [*D_MODES, (31.3, 0.02)], "coefficients": [0.7, -0.2], "driving_point": "sensor1"},
            "driving_point 'sensor1': its coefficient of mode 2 is -0.2",
        ),
        (
            {"coefficients": [[7e-4, 0.7]], "sensors": ["velocity"] * 2, "driving_point": "sensor1"},
            "mode 1 is not seen there",
        ),
    ],
)
def test_bad_model_arguments_are_refused_by_name(kw, words):
    with pytest.raises(ValueError, match=words):
        d_model(**kw)


@pytest.mark.parametrize(
    "theta, force, fs, words",
    [
        ({"f1": 12.7, "zeta1": 0.019}, np.ones((8, 2)), 100.0, r"force must be one channel"),
        ({"f1": 12.7, "zeta1": 0.019}, [0.0, np.nan, 1.0], 100.0, "force holds non-finite"),
        ({"f1": 12.7, "zeta1": 0.019}, np.ones(8), 0.0, "fs must be a positive"),
        ({"f1": -1.0, "zeta1": 0.019}, np.ones(8), 100.0, r"theta\['f1'\]"),
        ({"f1": 12.7, "zeta1": 1.5}, np.ones(8), 100.0, r"theta\['zeta1'\]"),
        ({"f1": 12.7}, np.ones(8), 100.0, r"theta lacks \['zeta1'\]"),
    ],
)
def test_bad_simulate_arguments_are_refused_by_name(theta, force, fs, words):
    with pytest.raises(ValueError, match=words):
        d_model().simulate(theta, force, fs)


def test_a_run_that_diverges_raises_model_error_not_nan():
    """A softening spring driven past its barrier (k3 q^2 > w^2): the contract's ModelError."""
    model = d_model(nonlinear=[("k3", 1)], bounds={"k3_1": (-1e9, 1e9)})
    force = 900.0 * np.sin(2 * np.pi * 12.1 * np.arange(400) / 200.0)
    with pytest.raises(ModelError, match="mode 1 diverged"):
        model.simulate({"f1": 12.7, "zeta1": 0.019, "k3_1": -1e9}, force, 200.0)
    assert np.all(np.isfinite(model.simulate({"f1": 12.7, "zeta1": 0.019, "k3_1": 1e9}, force, 200.0)))
    joint = d_model(nonlinear=[("k3", "sensor1")], bounds={"k3_at_sensor1": (-1e9, 1e9)}, driving_point="sensor1")
    with pytest.raises(ModelError, match=r"modes \[1\], coupled by the joint\(s\) at sensor1"):
        joint.simulate({"f1": 12.7, "zeta1": 0.019, "k3_at_sensor1": -1e9}, force, 200.0)


def test_bad_records_are_refused_by_name():
    u = np.random.default_rng(7).standard_normal(400)
    with pytest.raises(ValueError, match=r"response has shape \(399,\)"):
        ModalModel.from_modes(D_MODES, u, u[:-1], 100.0)
    with pytest.raises(ValueError, match=r"response has 2 column\(s\) but sensors names 1"):
        ModalModel.from_modes(D_MODES, u, np.column_stack([u, u]), 100.0)
    with pytest.raises(ValueError, match="Nyquist"):
        ModalModel.from_modes(D_MODES, u, u, 20.0)
    with pytest.raises(ValueError, match="role 'linear'"):
        ModalModel.from_dataset(Dataset("no-linear", C_FS, None, []))


# (f) joints: a 3-DOF chain in physical coordinates, masses [kg], springs ground-1, 1-2, 2-3 [N/m],
# C = alpha M + beta K [1/s, s] (modes 11.5, 24.9, 35.9 Hz), the force on mass 1, a nonlinear
# element to ground at mass 1 or 3.  Sensors are (name, kind, mass): the exact coefficients are
# phi_s phi_1 of the mass-normalised shapes, whatever the kind
F_MASS, F_SPRINGS, F_ALPHA, F_BETA = (1.9, 1.1, 0.7), (31000.0, 22000.0, 14000.0), 2.3, 3.1e-5


def f_chain():
    """(M, K, C, modes [(f_hz, zeta)], phi (3, 3) mass-normalised by scipy.linalg.eigh)."""
    k = np.array(F_SPRINGS)
    K = np.diag(k + np.append(k[1:], 0.0)) - np.diag(k[1:], 1) - np.diag(k[1:], -1)
    M = np.diag(F_MASS)
    lam, phi = linalg.eigh(K, M)
    w = np.sqrt(lam)
    return M, K, F_ALPHA * M + F_BETA * K, [(wm / (2 * np.pi), F_ALPHA / (2 * wm) + F_BETA * wm / 2) for wm in w], phi


def f_physical(u, fs, sensors, at, k2=0.0, k3=0.0, c3=0.0):
    """Each sensor's output by DOP853 (rtol 1e-10) on M x'' + C x' + K x = e_1 u - e_at g(x_at, x_at'),
    one sample interval at a time, the force linear on each."""
    M, K, C, _, _ = f_chain()
    Minv = np.linalg.inv(M)

    def accel(x, v, f):
        load = -K @ x - C @ v
        load[0] += f
        load[at] -= k2 * x[at] ** 2 + k3 * x[at] ** 3 + c3 * v[at] ** 3
        return Minv @ load

    def rhs(t, s, i):
        return np.concatenate([s[3:], accel(s[:3], s[3:], u[i] + (u[i + 1] - u[i]) * (t * fs - i))])

    X = np.zeros((u.size, 6))
    for i in range(u.size - 1):
        sol = integrate.solve_ivp(rhs, (i / fs, (i + 1) / fs), X[i], "DOP853", rtol=1e-10, atol=1e-14, args=(i,))
        X[i + 1] = sol.y[:, -1]
    A = np.array([accel(x[:3], x[3:], f) for x, f in zip(X, u)])
    kinds = {"displacement": X[:, :3], "velocity": X[:, 3:], "acceleration": A}
    return np.column_stack([kinds[kind][:, j] for _, kind, j in sensors])


def f_force(n, fs, rms, seed, top_hz):
    u = signal.sosfilt(signal.butter(4, top_hz, fs=fs, output="sos"), np.random.default_rng(seed).standard_normal(n))
    return rms * u / np.std(u)


@pytest.mark.parametrize(
    "sensors, at, theta",
    [  # k3 at mass 3 (not the driving point); k2 and c3 at mass 1, the driving point itself
        ((("x1", "displacement", 0), ("a3", "acceleration", 2)), "a3", {"k3_at_a3": 3e7}),
        ((("v1", "velocity", 0), ("x3", "displacement", 2)), "v1", {"k2_at_v1": 2e6, "c3_at_v1": 100.0}),
    ],
)
def test_a_joint_matches_dop853_on_the_physical_chain(sensors, at, theta):
    fs, u = 1000.0, f_force(1200, 1000.0, 30.0, 5, 70.0)
    _, _, _, modes, phi = f_chain()
    model = ModalModel(
        modes,
        np.array([[phi[j, m] * phi[0, m] for _, _, j in sensors] for m in range(3)]),
        sensors=[s[:2] for s in sensors],
        updated=[],
        nonlinear=[Nonlinearity(name[:2], at=at) for name in theta],
        bounds={name: (-1e9, 1e9) for name in theta},
        substeps=1,
        driving_point=sensors[0][0],
    )
    mass = next(j for name, _, j in sensors if name == at)
    ref = f_physical(u, fs, sensors, mass, **{name[:2]: v for name, v in theta.items()})
    # the joint matters: without it the response differs by 0.6 to 1.1 times its rms
    assert np.all(rel_rms(f_physical(u, fs, sensors, mass), ref) > 0.3)
    errors = []
    for _ in range(4):  # 1, 2, 4 and 8 RK4 steps a sample (this rate and these modes need 1)
        errors.append(rel_rms(model.simulate(theta, u, fs), ref))
        model = model.refined()
    errors = np.array(errors)
    # the default four steps: measured 1.4e-6 and 2.4e-6 (k3), 1.4e-6 and 6.7e-7 (k2, c3); 2.5x the largest
    assert np.all(errors[2] < 6e-6), errors
    # halving the step divides the error by 2^4: measured 15.9 to 16.2
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 13) & (ratios < 21)), ratios


F_SENSORS, F_K3 = (("acc1", "acceleration", 0), ("acc3", "acceleration", 2)), 3e7


def test_from_dataset_fits_a_joint_on_a_record_of_the_chain():
    """Low (linear) and high tests of the chain with its cubic spring at mass 3, 1 % noise on every
    channel: the fitted coefficients are the shapes' phi_s phi_1 (those at the driving point
    positive), the joint's prior holds the chain's k3 [N/m^3 = 1/(m^2 s^2) per kg], and at that
    value the model predicts the high test."""
    fs, n = 250.0, 4096
    tests, clean = [], []
    for name, role, level, seed in (("low", "linear", 1.0, 21), ("high", "nonlinear", 30.0, 22)):
        u = f_force(n, fs, level, seed, 60.0)
        y = f_physical(u, fs, F_SENSORS, 2, k3=F_K3)
        rng = np.random.default_rng(seed + 100)
        u_noisy = u + 0.01 * np.std(u) * rng.standard_normal(n)
        y_noisy = y + 0.01 * np.std(y, axis=0) * rng.standard_normal(y.shape)
        t = np.arange(n) / fs
        tests.append(
            Record(f"{name}.csv", "noise", name, role, t, u_noisy, y_noisy, sensors=[s[:2] for s in F_SENSORS])
        )
        clean.append((u, y))
    data = Dataset("three-mass chain", fs, None, tests)
    model = ModalModel.from_dataset(data, updated=[], nonlinear=[("k3", "acc3")], driving_point="acc1")
    _, _, _, modes, phi = f_chain()
    exact = np.column_stack([phi[0] * phi[0], phi[2] * phi[0]])
    assert np.all(model.coefficients[:, 0] > 0)
    # measured within 4e-3 of the shapes' products (the first mode at mass 1; the others 8e-4); 3x that
    assert np.allclose(model.coefficients, exact, rtol=1.2e-2, atol=0), model.coefficients
    (k3,) = model.parameters
    assert k3.name == "k3_at_acc3" and k3.low == -k3.high
    # the prior's top: measured 1.8 times the chain's k3 (its force at the rms displacement of mass 3
    # in the high test is 12 % of the point's static stiffness force; the prior allows 25 %)
    assert 1.2 * F_K3 < k3.high < 4 * F_K3, k3
    u, y = clean[1]
    # on the high test's clean force: measured 0.85 and 0.96 % of the clean response's rms (the
    # modes found and the coefficients fitted on noisy records); 2.5x that.  Linear: 91 and 95 %
    assert np.all(rel_rms(model.simulate({"k3_at_acc3": F_K3}, u, fs), y) < 0.025)
    assert np.all(rel_rms(model.simulate({"k3_at_acc3": 0.0}, u, fs), y) > 0.8)


def test_a_mode_element_beside_a_joint_matches_dop853():
    """A mode's own element integrated in the joint's RK4, the joint at its null; the modal
    equations of (b) by DOP853.  RK4 now carries both modes: the second, at 61.7 Hz, sets the
    step (the joint's rule) and its RK4 error adds to the first's."""
    force = b_force()
    joint = ModalModel(
        B_MODES,
        B_C,
        sensors=B_SENSORS,
        updated=[],
        nonlinear=[("k3", 1), ("c3", "sensor1")],
        bounds={"k3_1": (-1e9, 1e9), "c3_at_sensor1": (0.0, 1.0)},
        driving_point="sensor1",
    )
    err = rel_rms(joint.simulate({"k3_1": 3.4e8, "c3_at_sensor1": 0.0}, force, B_FS), dop853_outputs(force, k3=3.4e8))
    # measured 2.8e-6 and 2.2e-6 (the mode alone: 3.1e-7 and 3.5e-7); 2.5x the larger
    assert np.all(err < 7e-6), err
