"""The effects catalogue (fe.effects) against independent results."""

import numpy as np
import pytest

import fe
from fe import AmplitudeDependentDamping, ClampCompliance, ShakerAttachment

P = fe.Parameters.from_paper_units(3, 15, 60, 180)


def test_catalogue_has_the_four_names():
    assert set(fe.EFFECTS) == {
        "initial_imperfection",
        "amplitude_dependent_damping",
        "shaker_attachment",
        "clamp_compliance",
    }


@pytest.mark.parametrize("kind", ["mass", "stiffness"])
def test_shaker_attachment_matches_first_order_perturbation(kind):
    """A small point mass m (spring k) at the shaker changes omega_j^2 by
    -omega_j^2 m phi_j(x_s)^2 (+k phi_j(x_s)^2) for mass-normalised modes."""
    base = fe.BeamModel(n_elements=20)
    modes = base.modal_analysis(fe.Parameters(eta=0.0, c=0.0, F=P.F, k_s=P.k_s), 3)
    node = int(np.argmin(np.abs(base.node_x - base.rig.shaker_position_m)))
    eff = ShakerAttachment(mass=1e-4) if kind == "mass" else ShakerAttachment(stiffness=20.0)
    changed = fe.BeamModel(n_elements=20, effects=(eff,)).modal_analysis(
        fe.Parameters(eta=0.0, c=0.0, F=P.F, k_s=P.k_s), 3
    )
    for j in range(3):
        phi = modes.shapes[:, j]  # mass-normalised, all dofs
        w2 = (2 * np.pi * modes.frequencies_hz[j]) ** 2
        s = phi[3 * node + 1] ** 2
        expected = -w2 * 1e-4 * s if kind == "mass" else 20.0 * s
        measured = (2 * np.pi * changed.frequencies_hz[j]) ** 2 - w2
        assert measured == pytest.approx(expected, rel=0.02)


def test_clamp_compliance_limits_give_clamped_and_pinned_buckling():
    rig = fe.Rig()
    ei, L = rig.EI, rig.length_m
    clamped = fe.BeamModel(n_elements=24).buckling_load()
    stiff = fe.BeamModel(n_elements=24, effects=(ClampCompliance(1e6 * ei / L),)).buckling_load()
    soft = fe.BeamModel(n_elements=24, effects=(ClampCompliance(1e-6 * ei / L),)).buckling_load()
    assert stiff == pytest.approx(clamped, rel=1e-4)
    # pinned at the bottom, clamped (sliding) at the top: P_cr = 20.19 EI / L^2
    assert soft == pytest.approx(20.19073 * ei / L**2, rel=2e-3)
    assert fe.BeamModel(n_elements=24, effects=(ClampCompliance(10 * ei / L),)).buckling_load() < clamped


def test_amplitude_dependent_damping_acts_at_high_amplitude_only():
    from bayes_update.data.signals import chirp

    plain = fe.BeamModel()
    rub = fe.BeamModel(effects=(AmplitudeDependentDamping(kind="quadratic", coefficient=2e6),))
    diffs = []
    for amp in (0.002, 0.2):
        f = chirp(amp)
        a = plain.simulate(P, f).sensor_velocity
        b = rub.simulate(P, f).sensor_velocity
        diffs.append(np.linalg.norm(a - b) / np.linalg.norm(a))
    assert diffs[0] < 1e-3 < diffs[1]


# ------------------------------------------- the top-guide friction, quantitatively
# A free decay in the first mode with the top free (c = k_s = 0, F constant):
# the top then follows the beam's end shortening, s(t) = alpha q(t)^2 with
# q(t) = A cos(w t) the mid-span displacement, i.e. the guide slides at twice
# the vibration frequency with speed V |sin 2wt|, V = alpha A^2 w.  Energy the
# guide takes per vibration period T (time average over the period):
#     Coulomb f = F_c tanh(v / v_s):  E = T < F_c V sin(th) tanh(V sin(th) / v_s) >
#                                      -> 4 F_c alpha A^2 for V >> v_s (4 strokes of alpha A^2)
#     quadratic f = c_q |v| v:       E = T c_q V^3 4 / (3 pi)
# and the mode's energy is (1/2) M w^2 A^2, so the envelope obeys
#     d ln A / dt = -sigma_0 - E(A) / (2 pi M w A^2),
# sigma_0 the linear (viscous) decay rate, measured on the same run without the
# effect.  alpha, M, w come from the continuous beam (tests/reference.py), not
# from fe.  Coulomb friction driven by the quadratic shortening takes energy in
# proportion to A^2, like a viscous damper: its envelope decays exponentially
# (the extra rate 2 F_c alpha / (pi M w) does not depend on A), not linearly as
# Coulomb friction on the vibrating coordinate itself would make it.
# A little viscosity (eta = 0.3 MPa s) damps the axial modes, which the guide's
# friction would otherwise excite (the top node is light and stiff).
FREE_TOP = fe.Parameters(eta=0.3e6, c=0.0, F=60.0, k_s=0.0)


def free_decay_peaks(effects, substeps=4, amplitude=2e-3, n_samples=1024):
    """Times [s] and values [m] of the mid-span displacement's maxima (parabolic
    interpolation), after a release in the first mode; the first 50 ms (the
    release's axial transient) are dropped."""
    model = fe.BeamModel(substeps=substeps, effects=effects)
    modes = model.modal_analysis(FREE_TOP, 1)
    phi = modes.shapes[:, 0]
    mid = np.argmin(np.abs(model.node_x - model.rig.length_m / 2))
    d = model.simulate(
        FREE_TOP, np.zeros(n_samples), 1024.0, initial_displacement=amplitude * phi / phi[3 * mid + 1]
    ).sensor_displacement
    i = np.flatnonzero((d[1:-1] > d[:-2]) & (d[1:-1] >= d[2:])) + 1
    y0, y1, y2 = d[i - 1], d[i], d[i + 1]
    t = (i + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)) / 1024.0
    peak = y1 - (y0 - y2) ** 2 / (8 * (y0 - 2 * y1 + y2))
    keep = t > 0.05
    return t[keep], peak[keep]


def extra_decay(effect, substeps):
    """ln(A_without / A_with) along the decay: simulated, and from the energy balance."""
    from reference import first_mode_shape_integrals
    from scipy.integrate import solve_ivp

    rig = fe.Rig()
    f1, alpha, M = first_mode_shape_integrals(rig.EI, rig.mass_per_length, rig.length_m, FREE_TOP.F)
    w = 2 * np.pi * f1
    th = np.linspace(0.0, 2 * np.pi, 2001)[:-1]

    def energy_per_period(A):
        V = alpha * A * A * w
        if effect.kind == "coulomb":
            return (
                2
                * np.pi
                / w
                * effect.friction_force
                * V
                * np.mean(np.sin(th) * np.tanh(V * np.sin(th) / effect.velocity_scale))
            )
        return 2 * np.pi / w * effect.coefficient * V**3 * 4 / (3 * np.pi)

    t0, p0 = free_decay_peaks((), substeps)
    t, p = free_decay_peaks((effect,), substeps)
    assert t.size == t0.size and np.max(np.abs(t - t0)) < 2e-3  # the same cycles
    sigma0 = -np.polyfit(t0, np.log(p0), 1)[0]
    sol = solve_ivp(
        lambda tt, y: [-sigma0 - energy_per_period(np.exp(y[0])) / (2 * np.pi * M * w * np.exp(2 * y[0]))],
        (t[0], t[-1]),
        [np.log(p[0])],
        t_eval=t,
        rtol=1e-10,
        atol=1e-12,
    )
    expected = np.log(p[0]) - sigma0 * (t - t[0]) - sol.y[0]
    simulated = np.log(p0 / p) - np.log(p0[0] / p[0])
    return simulated, expected


def test_coulomb_guide_friction_takes_the_energy_of_its_strokes():
    """Coulomb kind (the default), F_c = 0.1 N, default v_s = 1e-4 m/s: over 1 s
    the guide adds 0.087 to ln A (the viscosity alone: 0.24).  Measured: simulated
    / expected at the end 0.997, largest deviation along the decay 0.30 % of the
    total (4 substeps; 8 / 16 / 32 substeps: 0.29 / 0.28 / 0.28 %, so it is the
    reference's single-mode averaging, not the time step); tolerance 1 %, 3.3x
    that.  A friction force off by a factor 2 is off by ~50 %."""
    effect = AmplitudeDependentDamping(friction_force=0.1)
    assert effect.kind == "coulomb"
    simulated, expected = extra_decay(effect, substeps=4)
    assert expected[-1] == pytest.approx(0.087, rel=0.02)
    np.testing.assert_allclose(simulated, expected, rtol=0, atol=0.01 * expected[-1])


def test_quadratic_guide_damper_takes_the_energy_of_its_strokes():
    """Quadratic kind, c_q = 2e4 N s^2/m^2: its extra decay rate falls as A^4.
    Measured simulated / expected at the end of 1 s: 0.975 / 1.010 / 1.014 /
    1.014 at 4 / 8 / 16 / 32 substeps: converged to 1.4 %, the single-mode
    averaging's error (|v|^3 weighs the peaks of the guide's speed, where the
    other modes and the axial motion add most).  8 substeps, tolerance 4 %
    (2.8x the converged error, 4x the error at 8 substeps)."""
    simulated, expected = extra_decay(AmplitudeDependentDamping(kind="quadratic", coefficient=2e4), substeps=8)
    assert simulated[-1] == pytest.approx(expected[-1], rel=0.04)


def test_bad_effect_parameters_are_rejected_and_the_rom_refuses_what_it_cannot_carry():
    with pytest.raises(ValueError, match="shaker_attachment mass"):
        ShakerAttachment(mass=-1.0)
    with pytest.raises(ValueError, match="clamp_compliance"):
        ClampCompliance(0.0)
    with pytest.raises(ValueError, match="kind"):
        AmplitudeDependentDamping(kind="viscous")
    with pytest.raises(ValueError, match="shaker_attachment"):
        fe.ModalROM(effects=(ShakerAttachment(mass=1e-3),))


def test_an_effect_at_its_null_or_on_a_bound_is_flagged_and_not_named():
    """The wrong-form case of the new-user issue: decisive 2 ln B for an effect fitted at
    its null (3e-32 N of friction) or on a bound of its prior (a damper at its upper limit)
    must not name it."""
    from types import SimpleNamespace

    from bayes_update.core.fits import DECISIVE, effect_at_bound, effect_at_null, names_effect

    def fit(x):  # one base coordinate, one effect coordinate on [0, 5] with null 0
        space = SimpleNamespace(
            box=lambda: np.array([[0.0, 1.0], [0.0, 5.0]]), n_base=1, null_internal=lambda: np.array([0.0])
        )  # the added parameters' nulls
        return SimpleNamespace(space=space, mode=SimpleNamespace(x=np.array([0.5, x])), covariance=np.eye(2) * 0.01)

    rows = {}
    for label, x in (("at null", 3e-32), ("on bound", 5.0), ("inside", 2.0)):
        f = fit(x)
        rows[label] = {
            "two_ln_B": 10 * DECISIVE,
            "excludes_null": True,
            "at_null": effect_at_null(f, 1),
            "at_bound": effect_at_bound(f, 1),
        }
    assert rows["at null"]["at_null"] and not rows["at null"]["at_bound"]
    assert rows["on bound"]["at_bound"] and not rows["on bound"]["at_null"]
    assert not rows["inside"]["at_null"] and not rows["inside"]["at_bound"]
    assert [label for label, row in rows.items() if names_effect(row)] == ["inside"]


def test_a_pair_is_named_only_inside_its_priors_and_beyond_each_member_alone():
    """The rule for an effect on a bound tried with a partner (a damper taking a bow's
    share): the pair must be decisive against each member alone, and both members
    inside their priors, away from their nulls."""
    from bayes_update.core.fits import DECISIVE, names_pair

    inside = {"excludes_null": True, "at_null": False, "at_bound": False}
    row = {"two_ln_B": 900.0, "members": {"damper": dict(inside), "bow": dict(inside)}}
    assert names_pair(row, partner_alone=545.0, first_alone=600.0)
    # a partner that is nothing alone (masked by the other's missing share) is named with it
    assert names_pair(row, partner_alone=-7.0, first_alone=600.0)
    assert not names_pair(
        row, partner_alone=900.0 - DECISIVE / 2, first_alone=600.0
    )  # the damper adds nothing decisive
    assert not names_pair(row, partner_alone=-7.0, first_alone=900.0 - DECISIVE / 2)  # nor does the bow
    assert not names_pair({**row, "members": {"damper": {**inside, "at_bound": True}, "bow": inside}}, 545.0, 600.0)
    assert not names_pair(
        {**row, "members": {"damper": inside, "bow": {**inside, "excludes_null": False}}}, 545.0, 600.0
    )
    assert not names_pair({**row, "two_ln_B": DECISIVE / 2}, partner_alone=-100.0, first_alone=-100.0)
