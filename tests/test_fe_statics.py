"""fe: statics, linear frequencies, element consistency, input validation.

Each check is against an independent reference: closed forms, the continuous
beam's characteristic equation, the elastica, finite differences, or a
convergence rate.
"""

import math

import numpy as np
import pytest
from reference import cantilever_elastica, clamped_clamped_frequencies

import fe
from fe import BeamModel, BucklingError, InitialImperfection, Parameters, Rig
from fe import _kernels as K

RIG = Rig()
NO_LOAD = Parameters(eta=0.0, c=0.0, F=0.0, k_s=0.0)


def test_euler_load_of_clamped_guided_beam():
    p_cr = BeamModel().buckling_load()
    assert RIG.euler_load == pytest.approx(129.85, abs=0.01)  # 4 pi^2 EI / L^2
    assert p_cr == pytest.approx(RIG.euler_load, rel=0.01)


def test_static_preload_carried_by_beam_is_p_eff():
    params = Parameters()  # F = 77 N, k_s = 180 N/mm
    state = BeamModel().static_equilibrium(params)
    assert state.axial_force == pytest.approx(74.06, abs=0.01)
    # the top shortens by P_eff / K_b
    assert state.top_displacement == pytest.approx(-74.063 / RIG.axial_stiffness, rel=1e-4)


def test_unloaded_frequencies_clamped_clamped():
    f = BeamModel().modal_analysis(NO_LOAD, n_modes=3).frequencies_hz
    beta_l = np.array([4.730041, 7.853205, 10.995608])
    exact = beta_l**2 / (2 * np.pi * RIG.length_m**2) * math.sqrt(RIG.EI / RIG.mass_per_length)
    np.testing.assert_allclose(f, exact, rtol=0.005)


def test_loaded_frequencies_against_continuous_beam():
    params = Parameters(F=74.0, k_s=0.0)
    f = BeamModel().modal_analysis(params, n_modes=3).frequencies_hz
    exact = clamped_clamped_frequencies(RIG.EI, RIG.mass_per_length, RIG.length_m, P=74.0)
    assert exact[0] == pytest.approx(29.8, abs=0.05)
    np.testing.assert_allclose(f, exact, rtol=0.005)


def test_frequencies_depend_on_f_and_k_s_only_through_p_eff():
    model = BeamModel()
    kb = RIG.axial_stiffness
    p_eff = 74.0
    pairs = [(p_eff * (kb + ks) / kb, ks) for ks in (0.0, 180e3, 540e3)]
    freqs = [model.modal_analysis(Parameters(F=F, k_s=ks), n_modes=3).frequencies_hz for F, ks in pairs]
    for f in freqs[1:]:
        np.testing.assert_allclose(f, freqs[0], rtol=1e-7)
    # and they do depend on P_eff
    other = model.modal_analysis(Parameters(F=70.0, k_s=0.0), n_modes=1).frequencies_hz
    assert abs(other[0] - freqs[0][0]) > 0.5


@pytest.mark.parametrize("formulation,expected_order", [("shallow_arch", 4.0), ("linear", 2.0)])
def test_first_frequency_convergence_rate(formulation, expected_order):
    """Observed order of f1 at 74 N against a fine mesh of the same model.

    (The continuous inextensible beam is not the limit to 1e-4: the model also
    shortens under the preload, +6e-5 on f1, a physical O(P/EA) effect.)"""
    params = Parameters(F=74.0, k_s=0.0)

    def f1(n):
        return BeamModel(n_elements=n, formulation=formulation).modal_analysis(params, 1).frequencies_hz[0]

    fine = f1(128)
    ns = np.array([6, 8, 12, 16])
    err = np.array([f1(n) / fine - 1 for n in ns])
    assert np.all(err > 0)  # displacement elements converge from above
    slope = -np.polyfit(np.log(ns), np.log(err), 1)[0]
    assert slope == pytest.approx(expected_order, abs=0.35)
    if formulation == "shallow_arch":
        assert err[-1] < 3e-5


@pytest.mark.parametrize("formulation", ["shallow_arch", "linear"])
def test_tangent_matches_finite_differences(formulation):
    """K = d f_int / d u and C = d f_int / d v against central differences."""
    model = BeamModel(n_elements=5, formulation=formulation, effects=[InitialImperfection(amplitude=2e-3)])
    params = Parameters(eta=5e6, c=2e3, F=50.0, k_s=1e5)
    rng = np.random.default_rng(1)
    n = model.n_dof
    u = 1e-3 * rng.standard_normal(n)
    v = 0.3 * rng.standard_normal(n)
    _, kt, c, f0 = model.matrices(params, u, v)
    h = 1e-7
    kfd = np.empty_like(kt)
    cfd = np.empty_like(c)
    for j in range(n):
        du = np.zeros(n)
        du[j] = h
        kfd[:, j] = (model.matrices(params, u + du, v)[3] - model.matrices(params, u - du, v)[3]) / (2 * h)
        dv = np.zeros(n)
        dv[j] = h * 1e3
        cfd[:, j] = (model.matrices(params, u, v + dv)[3] - model.matrices(params, u, v - dv)[3]) / (2e3 * h)
    np.testing.assert_allclose(kt, kfd, atol=1e-6 * np.abs(kfd).max())
    np.testing.assert_allclose(c, cfd, atol=1e-6 * np.abs(cfd).max())


def test_fast_force_kernel_equals_assembly_force():
    model = BeamModel(n_elements=7, effects=[InitialImperfection(amplitude=1e-3)])
    params = Parameters(eta=4e6, c=1e4, F=60.0, k_s=2e5)
    a = model._arrays(model.describe(params), params)
    rng = np.random.default_rng(2)
    u, v = 1e-3 * rng.standard_normal(model.n_dof), rng.standard_normal(model.n_dof)
    f1, f2 = np.empty(model.n_dof), np.empty(model.n_dof)
    K.internal_force(a["elements"], a["discrete"], u, v, f1)
    K.assemble(a["elements"], a["discrete"], u, v, f2, False, 0.0, 0.0, np.empty((1, 1)), 5)
    np.testing.assert_allclose(f1, f2, rtol=1e-10, atol=1e-9)


@pytest.mark.parametrize("load_parameter", [1.0, 2.0, 5.0])
def test_cantilever_large_deflection_against_elastica(load_parameter):
    """Tip-loaded cantilever (Bisshopp-Drucker): tip deflections within 1 %."""
    model = BeamModel(n_elements=20)
    system = model.describe(NO_LOAD)
    system.fixed[:] = False
    system.fixed[0:3] = True  # clamp only: the tip is free
    a = model._arrays(system, NO_LOAD)
    tip = model.n_dof - 3
    f_ext = np.zeros(model.n_dof)
    f_ext[tip + 1] = load_parameter * RIG.EI / RIG.length_m**2
    u = np.zeros(model.n_dof)
    status, _ = K.static_newton(a["elements"], a["discrete"], a["fixed"], f_ext, u, 5, 20, 1e-7, 50)
    assert status == 0
    deflection, shortening = cantilever_elastica(load_parameter)
    assert u[tip + 1] / RIG.length_m == pytest.approx(deflection, rel=0.01)
    # axial tip displacement includes the (tiny) extension of the beam
    assert -u[tip] / RIG.length_m == pytest.approx(shortening, rel=0.01)


def test_imperfection_amplified_by_preload():
    """Linear theory: a bow in the buckling-mode shape grows by P/(P_cr - P).

    The elements carry the bow as cubics (nodal offsets and slopes), so the
    amplification converges as O(h^4): measured 0.074 % off at 10 elements,
    0.014 % at 20; straight elements between bowed nodes (the earlier form)
    were 3.7 % off at 10 and converged as O(h^2).  What remains at 80
    elements (0.012 %) is the axial shortening under the preload that the
    closed form leaves out (P/EA = 3e-5)."""
    a0 = 1e-5  # small, so the response is linear
    params = Parameters(F=60.0, k_s=0.0)
    p_cr = RIG.euler_load
    expected = a0 * 60.0 / (p_cr - 60.0)
    err = []
    for n in (10, 20, 80):
        model = BeamModel(n_elements=n, effects=[InitialImperfection(amplitude=a0)])
        state = model.static_equilibrium(params)
        mid = np.argmin(np.abs(model.node_x - RIG.length_m / 2))
        err.append(state.u[3 * mid + 1] / expected - 1)
    assert abs(err[0]) < 1e-3
    assert abs(err[2]) < 3e-4
    # halving h divides the discretisation error by 2^4 = 16 (2^2 = 4 for chords)
    assert (err[0] - err[2]) / (err[1] - err[2]) > 10


def test_bad_parameters_name_the_parameter():
    for name in ("eta", "c", "F", "k_s"):
        with pytest.raises(ValueError, match=name):
            Parameters(**{name: -1.0})
        with pytest.raises(ValueError, match=name):
            Parameters(**{name: float("nan")})


def test_rig_validation_names_the_key():
    with pytest.raises(ValueError, match="bending_stiffness_factor"):
        Rig(bending_stiffness_factor=0.0)
    with pytest.raises(ValueError, match="bending_stiffness_factor"):
        Rig(bending_stiffness_factor=float("inf"))
    with pytest.raises(ValueError, match="sensor_position_m"):
        Rig(sensor_position_m=0.5)
    with pytest.raises(ValueError, match="unknown rig key"):
        Rig.from_dict({"lenght_m": 0.4})


def test_preload_beyond_buckling_raises():
    with pytest.raises(BucklingError, match="buckling"):
        BeamModel().static_equilibrium(Parameters(F=140.0, k_s=0.0))
    # the spring shares the load: F = 140 N with a stiff spring is fine, because the
    # beam carries only P_eff = F K_b / (K_b + k_s) = 84.29 N < 4 pi^2 EI / L^2
    params = Parameters(F=140.0, k_s=3e6)
    model = BeamModel()
    state = model.static_equilibrium(params)
    kb = RIG.axial_stiffness
    p_eff = 140.0 * kb / (kb + 3e6)
    assert p_eff < RIG.euler_load < 140.0
    # statics of two springs in parallel (K_b and k_s) under F: measured 8e-13 and
    # 1e-15 relative; the static Newton stops at 1e-9 F, hence 1e-8
    assert state.axial_force == pytest.approx(p_eff, rel=1e-8)
    assert state.top_displacement == pytest.approx(-140.0 / (kb + 3e6), rel=1e-8)
    assert np.max(np.abs(state.u[1::3])) < 1e-12 and np.max(np.abs(state.u[2::3])) < 1e-12  # straight (measured 0)
    # and the beam vibrates as the continuous beam under P_eff (26.97 Hz): measured
    # 3.2e-4 at 10 elements (the h^4 discretisation error), 1e-3 allowed
    f1 = model.modal_analysis(params, n_modes=1).frequencies_hz[0]
    exact = clamped_clamped_frequencies(RIG.EI, RIG.mass_per_length, RIG.length_m, P=p_eff, n_modes=1)[0]
    assert f1 == pytest.approx(exact, rel=1e-3)


def test_bending_stiffness_factor_scales_ei_only():
    stiff = Rig(bending_stiffness_factor=1.24)
    assert stiff.EI == pytest.approx(1.24 * RIG.EI)
    assert stiff.EA == RIG.EA
    f = BeamModel(rig=stiff).modal_analysis(NO_LOAD, 1).frequencies_hz[0]
    assert f == pytest.approx(45.03 * math.sqrt(1.24), rel=0.002)


def test_simulate_dispatches_and_rejects_non_models():
    with pytest.raises(TypeError):
        fe.simulate(object(), Parameters(), np.zeros(4))
    with pytest.raises(ValueError, match="NaN"):
        BeamModel().simulate(Parameters(), np.array([0.0, np.nan, 0.0]))
