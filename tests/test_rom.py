"""fe.ModalROM: the modal reduced-order model against the full FE.

Every accuracy check uses the full co-rotational FE (fe.BeamModel) as the
independent reference: its matrices and modes, its linear FRF, its static
Newton solution under an extra transverse load, and its transients on the
default data set's recorded forces.  Full table: benchmarks/rom_validation.py.
"""

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

import fe
from bayes_update.models.beam.rig import rig_of
from bayes_update.models.beam.virtual_rig import PAPER_EQUIVALENT_RIG, load_default_dataset
from fe import _kernels as K
from fe.equilibrium import _beam_axial_force
from fe.model import KD, hermite_weights
from fe.rom import ModalROM

RIG = PAPER_EQUIVALENT_RIG
KB = RIG.axial_stiffness
PAPER = fe.Parameters()
P_EFF = PAPER.effective_preload(RIG)
# away from the paper's point: a softer damper on a stiffer spring at the same
# P_eff (F adjusted), and a higher viscosity
STIFF_SPRING = fe.Parameters(c=5e3, k_s=400e3, F=P_EFF * (KB + 400e3) / KB)
VISCOUS = fe.Parameters(eta=5e6)
NO_TOP_DAMPER = fe.Parameters(c=0.0)  # the stiff (fast) top: relaxation time 60 us
BOW = fe.InitialImperfection(amplitude=3e-4)
N_REF = 30  # the ROM's default mesh: same element and mesh in both models


def rel_l2(a, b):
    return float(np.linalg.norm(np.asarray(a) - b) / np.linalg.norm(b))


@pytest.fixture(autouse=True, scope="module")
def _one_blas_thread():
    # the FE references solve dense systems of up to 240 dofs: threaded BLAS
    # only fights the other processes of a small machine
    with threadpool_limits(1):
        yield


@pytest.fixture(scope="module")
def dataset():
    return load_default_dataset()


def record(ds, name):
    return next(t for t in ds.tests if t.file == f"{name}.csv")


# ------------------------------------------------------------ inherited FE
def test_matrices_and_modes_are_the_full_fe():
    """The ROM's mass, bending and shortening matrices are the FE's element;
    its preloaded modes are the FE's modal analysis."""
    rom = ModalROM(rig=RIG, n_modes=4, n_elements=N_REF)
    model = fe.BeamModel(rig=RIG, n_elements=N_REF)
    rm = rom.rig_matrices
    transverse = np.flatnonzero(np.arange(model.n_dof) % 3 != 0)[2:-2]
    block = np.ix_(transverse, transverse)
    no_load = fe.Parameters(eta=0.0, c=0.0, F=0.0, k_s=0.0)
    m, k0, _, _ = model.matrices(no_load)
    np.testing.assert_allclose(rm.mass, m[block], rtol=0, atol=1e-14 * np.abs(m).max())
    np.testing.assert_allclose(rm.bending, k0[block], rtol=0, atol=1e-12 * np.abs(k0).max())
    # FE tangent at the preloaded equilibrium = K / lam^2 - P / lam G (lam = 1 - P / EA)
    _, kt, c, _ = model.matrices(PAPER, model.static_equilibrium(PAPER).u)
    lam = 1 - P_EFF / RIG.EA
    expected = rm.bending / lam**2 - P_EFF / lam * rm.geometric
    assert np.abs(kt[block] - expected).max() < 1e-6 * np.abs(expected).max()
    beta = RIG.beam_viscosity(PAPER.eta) / RIG.youngs_modulus_pa
    assert np.abs(c[block] - beta * rm.bending / lam**2).max() < 1e-6 * beta * np.abs(rm.bending).max()
    # modes (the residual 5e-7 on modes 2-4: the FE's string term uses the
    # current chord length, its shallow term the reference one)
    modes = model.modal_analysis(PAPER, n_modes=4)
    red = rom.reduced(PAPER)
    np.testing.assert_allclose(red.omega / (2 * np.pi), modes.frequencies_hz, rtol=1e-6)
    assert red.omega[0] / (2 * np.pi) == pytest.approx(modes.frequencies_hz[0], rel=2e-7)
    # same subspace: the FE's modes lie in the span of the ROM's basis (its
    # rotations are per current length, w' / lam: 3.5e-5 apart)
    fe_shapes = modes.shapes[transverse]
    miss = np.abs(red.shapes @ (red.shapes.T @ rm.mass @ fe_shapes) - fe_shapes)
    scale = np.abs(fe_shapes[0::2]).max(axis=0)
    assert np.all(miss[0::2].max(axis=0) < 1e-6 * scale)
    assert np.all(miss[1::2].max(axis=0) < 1e-4 * np.abs(fe_shapes[1::2]).max(axis=0))
    assert rom.buckling_load() == pytest.approx(model.buckling_load(), rel=2e-4)


# --------------------------------------------------------------- 1. linear
def frf_error(n_modes, params=PAPER, effects=(), n_elements=N_REF, n_freqs=280):
    freqs = np.linspace(0.5, 140.0, n_freqs)
    ref = fe.BeamModel(rig=RIG, n_elements=n_elements, effects=effects).linear_frf(params, freqs)
    rom = ModalROM(rig=RIG, n_modes=n_modes, n_elements=N_REF, effects=effects)
    return float(np.max(np.abs(np.abs(rom.linear_frf(params, freqs)) / np.abs(ref) - 1)))


def test_linear_frf_converges_to_full_fe():
    """Largest relative magnitude error over 0-140 Hz at the sensor (same mesh:
    only the modal truncation differs).  Measured: 53 %, 7.2 %, 1.3 %,
    0.011 %, 0.22 % for 1, 3, 5, 7, 9 modes (the tail of the modal series
    changes sign, so it is not monotone beyond 7); the 3-mode error is largest
    at 140 Hz and 0.1-0.9 % across the chirp's 20-50 Hz."""
    err = {n: frf_error(n) for n in (1, 3, 5, 7, 9)}
    print("FRF error per n_modes:", {n: f"{100 * e:.3f} %" for n, e in err.items()})
    assert err[1] > err[3] > err[5] > err[7]
    assert err[7] < 0.005
    assert err[9] < 0.005


def test_linear_frf_with_bow_and_top_dynamics():
    """With a bow the top's dynamics (k_s, c, beta K_b) enter the linearisation
    at first order; the ROM's linear FRF still meets the FE's (same mesh).
    Measured 0.010 % and 0.041 % with 7 modes."""
    assert frf_error(7, effects=(BOW,), n_freqs=140) < 0.005
    assert frf_error(7, params=NO_TOP_DAMPER, effects=(BOW,), n_freqs=140) < 0.005


# --------------------------------------------------------------- 2. statics
def fe_static(model, params, shaker_force):
    """The full FE's static Newton solution with a constant shaker force added."""
    system = model.describe(params)
    a = model._arrays(system, params)
    u = np.zeros(model.n_dof)
    f_ext = a["f_const"] + shaker_force * a["b_load"]
    status, _ = K.static_newton(a["elements"], a["discrete"], a["fixed"], f_ext, u, KD, 10, 1e-10 * params.F, 50)
    assert status == 0
    return u, a


@pytest.fixture(scope="module")
def static_reference():
    """FE end shortening and drop of the beam's compression under a static
    shaker force (0.2 and 0.8 mm at mid-span), at the paper's point and on
    the stiffest spring of the prior box (k_s = 600 N/mm, same P_eff)."""
    out = {}
    model = fe.BeamModel(rig=RIG, n_elements=N_REF)
    for label, params in (("paper", PAPER), ("k_s=600", fe.Parameters(k_s=600e3, F=P_EFF * (KB + 600e3) / KB))):
        u0, _ = fe_static(model, params, 0.0)
        for load in (1.0, 4.0):
            u, a = fe_static(model, params, load)
            top = u[model.top_axial_dof]
            compression = params.F + params.k_s * top  # the top's balance
            # the top's displacement = elastic shortening P/K_b + the shortening s
            out[label, load] = dict(
                params=params,
                load=load,
                shortening=-top - compression / KB,
                drop=compression - (params.F + params.k_s * u0[model.top_axial_dof]),
                chord_force=_beam_axial_force(model, u, a),
                compression=compression,
            )
    return out


@pytest.mark.parametrize(
    "n_modes",
    [
        pytest.param(
            3,
            marks=pytest.mark.xfail(
                strict=True,
                reason="measured 2.6 %: a static point load needs the modal series' "
                "tail (residual flexibility); 3 modes give w at mid-span 1.2 % "
                "low and the shortening 2.6 % high",
            ),
        ),
        5,
        7,
    ],
)
def test_static_shortening_and_axial_force(static_reference, n_modes):
    """End shortening and the drop of the beam's compression within 1 % of the
    full FE (measured 0.42 % with 5 modes, 0.15 % with 7)."""
    rom = ModalROM(rig=RIG, n_modes=n_modes, n_elements=N_REF)
    for ref in static_reference.values():
        # the FE's force from the top element's chord agrees with the top's balance
        assert ref["chord_force"] == pytest.approx(ref["compression"], rel=2e-3)
        loaded = rom.static_equilibrium(ref["params"], shaker_force=ref["load"])
        unloaded = rom.static_equilibrium(ref["params"])
        assert loaded.shortening == pytest.approx(ref["shortening"], rel=0.01)
        drop = loaded.axial_force - unloaded.axial_force
        assert drop == pytest.approx(ref["drop"], rel=0.01)


def test_static_bow_against_full_fe():
    """With a bow the static state is bent: deflection and top displacement
    as the FE's static equilibrium."""
    model = fe.BeamModel(rig=RIG, n_elements=N_REF, effects=(BOW,))
    rom = ModalROM(rig=RIG, n_elements=N_REF, effects=(BOW,))
    st_fe = model.static_equilibrium(PAPER)
    st = rom.static_equilibrium(PAPER)
    w_fe = hermite_weights(model.node_x, RIG.sensor_position_m) @ st_fe.u
    w = rom.simulate(PAPER, np.zeros(2)).displacement[0, 0]
    # the preload amplifies the bow by P / (P_cr - P)
    assert w == pytest.approx(BOW.amplitude * P_EFF / (rom.buckling_load() - P_EFF), rel=0.02)
    assert w == pytest.approx(w_fe, rel=0.01)
    assert st.top_displacement == pytest.approx(st_fe.top_displacement, rel=0.01)
    assert st.axial_force == pytest.approx(st_fe.axial_force, rel=1e-3)


# -------------------------------------------------------------- 3. transient
FE_REFERENCE = dict(n_elements=24, substeps=16)  # 0.05 % from 40 elements / 32 substeps
# the FE's elements carry a bow as cubics: with a 0.3 mm bow 20 elements are
# 0.007 % from 160 (10 elements 0.12 %)
FE_REFERENCE_BOW = FE_REFERENCE
TOLERANCE = {"low": 0.01, "medium": 0.01, "high": 0.015}
CASES = [  # (label, params, effects, test); the full table: benchmarks/rom_validation.py
    ("paper", PAPER, (), "chirp_low"),
    ("paper", PAPER, (), "chirp_high"),
    ("paper", PAPER, (), "sine_high"),
    ("c=5,k_s=400", STIFF_SPRING, (), "chirp_high"),
    ("eta=5", VISCOUS, (), "chirp_high"),
    ("c=0", NO_TOP_DAMPER, (), "chirp_high"),
    ("bow 0.3 mm", PAPER, (BOW,), "chirp_medium"),
]


@pytest.mark.parametrize("label,params,effects,test", CASES, ids=[f"{c[0]}-{c[3]}" for c in CASES])
def test_transient_against_full_fe(dataset, label, params, effects, test):
    """Relative L2 of the sensor velocity (3 modes, automatic substeps) against
    the converged full FE, driven by the data set's recorded force.  Measured
    0.12-0.35 %."""
    rec = record(dataset, test)
    settings = FE_REFERENCE_BOW if effects else FE_REFERENCE
    ref = fe.BeamModel(rig=rig_of(dataset), effects=effects, **settings).simulate(
        params, rec.force, dataset.sampling_rate_hz
    )
    rom = ModalROM(rig=rig_of(dataset), effects=effects)
    res = fe.simulate(rom, params, rec.force, dataset.sampling_rate_hz)
    err = rel_l2(res.sensor_velocity, ref.sensor_velocity)
    print(f"{label} {test}: {100 * err:.3f} %")
    assert err < TOLERANCE[rec.level]
    # same conventions for the displacement and the top's axial displacement
    assert rel_l2(res.sensor_displacement, ref.sensor_displacement) < TOLERANCE[rec.level]
    assert res.axial_top[0] == pytest.approx(ref.axial_top[0], rel=1e-3)
    dyn_ref = ref.axial_top - ref.axial_top[0]
    assert rel_l2(res.axial_top - res.axial_top[0], dyn_ref) < 0.01


def test_outputs_at_several_positions(dataset):
    """Displacement and velocity at any positions.  At the driving point (the
    shaker) the response carries more of the modal series' tail: 3 modes give
    3.1 % there (0.5-0.6 % at 0.1-0.15 m, 0.16 % at mid-span), 5 modes 0.5 %."""
    rec = record(dataset, "chirp_medium")
    positions = [0.0, 0.1, 0.15, RIG.sensor_position_m, 0.3, RIG.length_m, RIG.shaker_position_m]
    ref = fe.BeamModel(rig=RIG, **FE_REFERENCE).simulate(PAPER, rec.force, positions=positions)
    res = ModalROM(rig=RIG).simulate(PAPER, rec.force, positions=positions)
    assert res.velocity.shape == res.displacement.shape == (rec.force.size, 7)
    np.testing.assert_array_equal(res.velocity[:, [0, 5]], 0.0)  # held ends
    for j in (1, 2, 3, 4):
        assert rel_l2(res.velocity[:, j], ref.velocity[:, j]) < 0.01
        assert rel_l2(res.displacement[:, j], ref.displacement[:, j]) < 0.01
    np.testing.assert_array_equal(res.time, ref.time)
    np.testing.assert_array_equal(res.force, rec.force)
    shaker = ModalROM(rig=RIG, n_modes=5).simulate(PAPER, rec.force, positions=RIG.shaker_position_m)
    assert rel_l2(shaker.sensor_velocity, ref.velocity[:, 6]) < 0.01


# ------------------------------------------------------- time integration
def test_rk4_order_and_automatic_substeps(dataset):
    force = record(dataset, "chirp_high").force
    ref = ModalROM(rig=RIG, substeps=32).simulate(PAPER, force).sensor_velocity
    err = [rel_l2(ModalROM(rig=RIG, substeps=m).simulate(PAPER, force).sensor_velocity, ref) for m in (1, 2, 4)]
    order = -np.polyfit(np.log([1, 2, 4]), np.log(err), 1)[0]
    assert order == pytest.approx(4.0, abs=0.3)
    assert err[0] < 2e-3  # one substep per sample is enough with 3 modes
    assert ModalROM(rig=RIG).choose_substeps(PAPER, 1024.0) == 1
    # the highest retained (unloaded) mode sets the substeps: 5 modes, ~650 Hz
    rom5 = ModalROM(rig=RIG, n_modes=5)
    w = np.sqrt(rom5.reduced(PAPER).kappa.max())
    assert rom5.choose_substeps(PAPER, 1024.0) == int(np.ceil(w / 1024.0 / 2.0)) > 1


def test_stiff_and_algebraic_top(dataset):
    """With c = 0 the top relaxes in (beta K_b) / (K_b + k_s) (20 us at
    eta = 1 MPa s): its exact integration keeps one substep per sample
    accurate; with c = eta = 0 the top is quasi-static and the limit is
    continuous."""
    force = record(dataset, "chirp_high").force
    fast = fe.Parameters(eta=1e6, c=0.0)
    ref = ModalROM(rig=RIG, substeps=64).simulate(fast, force).sensor_velocity
    assert rel_l2(ModalROM(rig=RIG).simulate(fast, force).sensor_velocity, ref) < 5e-3
    rom = ModalROM(rig=RIG, substeps=4)
    limit = rom.simulate(fe.Parameters(eta=0.0, c=0.0), force)
    near = rom.simulate(fe.Parameters(eta=0.0, c=1e-6), force)
    assert rel_l2(near.sensor_velocity, limit.sensor_velocity) < 1e-8
    assert np.all(np.isfinite(limit.axial_top))


@pytest.mark.parametrize("damping", [0.0, 92.0, 277.0, 15e3, 1e9])
def test_top_weights_exact_for_quadratic_drive(damping):
    """The top's step, D U' + K U = r(t), is exact when r is linear over the
    half step and quadratic over the full step (checked by quadrature), from
    the algebraic limit D = 0 to a nearly frozen top."""
    from scipy.integrate import quad

    from fe._rom_kernels import _top_weights

    stiffness, h, u0 = KB + 180e3, 1 / 1024, -1.6e-5
    r = np.polynomial.Polynomial([-74.0, 3e3, -4e6])  # N, N/s, N/s^2
    w = np.empty(7)
    _top_weights(damping, stiffness, h, w)

    def exact(theta, drive):
        if damping == 0.0:
            return drive(theta) / stiffness
        tau = damping / stiffness
        integral = quad(lambda t: np.exp(-(theta - t) / tau) * drive(t), 0, theta, epsabs=0, epsrel=1e-13, limit=200)[0]
        return np.exp(-theta / tau) * u0 + integral / damping

    line = np.polynomial.Polynomial.fit([0, h / 2], [r(0), r(h / 2)], 1, domain=[0, h])
    half = w[0] * u0 + w[1] * r(0) + w[2] * r(h / 2)
    assert half == pytest.approx(exact(h / 2, line), rel=1e-11, abs=1e-20)
    full = w[3] * u0 + w[4] * r(0) + w[5] * r(h / 2) + w[6] * r(h)
    assert full == pytest.approx(exact(h, r), rel=1e-11, abs=1e-20)


def test_static_state_near_buckling():
    """The bowed beam's static Newton converges up to 99.5 % of the buckling
    load and follows the amplification P / (P_cr - P)."""
    rom = ModalROM(rig=RIG, effects=(BOW,))
    p = 0.995 * rom.buckling_load()
    st = rom.static_equilibrium(fe.Parameters(F=p, k_s=0.0))
    w = rom._output_weights(rom.reduced(fe.Parameters(F=p, k_s=0.0)), np.array([RIG.sensor_position_m]))[0] @ st.q
    assert w == pytest.approx(BOW.amplitude * p / (rom.buckling_load() - p), rel=0.02)


def test_deterministic_and_cached(dataset):
    force = record(dataset, "sine_medium").force
    rom = ModalROM(rig=RIG)
    a = rom.simulate(PAPER, force)
    rom.cache_clear()
    b = ModalROM(rig=RIG).simulate(PAPER, force)
    np.testing.assert_array_equal(a.velocity, b.velocity)
    np.testing.assert_array_equal(a.axial_top, b.axial_top)
    # the basis depends on P_eff only: shared along the (F, k_s) ridge
    same_p_eff = fe.Parameters(k_s=0.0, F=P_EFF)
    assert rom.reduced(same_p_eff) is rom.reduced(PAPER)


# ------------------------------------------------------------ 4. bad input
class _TopFriction(fe.Effect):
    """A test effect the ROM cannot carry (a discrete element at the top)."""

    name = "top_friction"

    def apply(self, system, rig, params):
        from fe.model import DiscreteElement

        system.discrete.append(DiscreteElement(system.n_dof - 3, "coulomb", 0.1, 1e-3))


def test_bad_input_raises_clear_errors():
    force = np.sin(np.arange(64) / 10)
    rom = ModalROM(rig=RIG)
    with pytest.raises(ValueError, match="eta"):
        rom.simulate(fe.Parameters(eta=-1.0), force)
    with pytest.raises(TypeError, match="fe.Parameters"):
        rom.simulate({"eta": 3e6}, force)
    with pytest.raises(fe.BucklingError, match="buckling"):
        rom.simulate(fe.Parameters(F=200.0, k_s=0.0), force)
    with pytest.raises(ValueError, match=r"n_modes must be an integer in \[1, 10\]"):
        ModalROM(rig=RIG, n_elements=6, n_modes=11)
    with pytest.raises(ValueError, match="n_modes"):
        ModalROM(n_modes=0)
    with pytest.raises(ValueError, match="substeps"):
        ModalROM(substeps=0)
    with pytest.raises(ValueError, match="top_friction.*does not fit the modal ROM"):
        ModalROM(effects=(_TopFriction(),))
    with pytest.raises(TypeError, match="Effect"):
        ModalROM(effects=("bow",))
    for bad in (np.ones((4, 2)), np.ones(1), np.array([0.0, np.nan, 1.0]), ["a", "b"]):
        with pytest.raises(ValueError, match="force"):
            rom.simulate(PAPER, bad)
    with pytest.raises(ValueError, match="fs"):
        rom.simulate(PAPER, force, fs=0.0)
    with pytest.raises(ValueError, match="outside the beam"):
        rom.simulate(PAPER, force, positions=[0.5])
    # too few manual substeps for the retained modes: the run diverges, and says so
    with pytest.raises(fe.ConvergenceError, match="substeps"):
        ModalROM(rig=RIG, n_modes=8, substeps=1).simulate(PAPER, 0.1 * force)
