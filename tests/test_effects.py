"""The effects catalogue (fe.effects) against independent results."""
import numpy as np
import pytest

import fe
from fe import AmplitudeDependentDamping, ClampCompliance, ShakerAttachment

P = fe.Parameters.from_paper_units(3, 15, 60, 180)


def test_catalogue_has_the_four_names():
    assert set(fe.EFFECTS) == {"initial_imperfection", "amplitude_dependent_damping", "shaker_attachment",
                               "clamp_compliance"}


@pytest.mark.parametrize("kind", ["mass", "stiffness"])
def test_shaker_attachment_matches_first_order_perturbation(kind):
    """A small point mass m (spring k) at the shaker changes omega_j^2 by
    -omega_j^2 m phi_j(x_s)^2 (+k phi_j(x_s)^2) for mass-normalised modes."""
    base = fe.BeamModel(n_elements=20)
    modes = base.modal_analysis(fe.Parameters(eta=0.0, c=0.0, F=P.F, k_s=P.k_s), 3)
    node = int(np.argmin(np.abs(base.node_x - base.rig.shaker_position_m)))
    eff = ShakerAttachment(mass=1e-4) if kind == "mass" else ShakerAttachment(stiffness=20.0)
    changed = fe.BeamModel(n_elements=20, effects=(eff,)).modal_analysis(
        fe.Parameters(eta=0.0, c=0.0, F=P.F, k_s=P.k_s), 3)
    for j in range(3):
        phi = modes.shapes[:, j]                      # mass-normalised, all dofs
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
    assert soft == pytest.approx(20.19073 * ei / L ** 2, rel=2e-3)
    assert fe.BeamModel(n_elements=24, effects=(ClampCompliance(10 * ei / L),)).buckling_load() < clamped


def test_amplitude_dependent_damping_acts_at_high_amplitude_only():
    from bayes_update.signals import chirp

    plain = fe.BeamModel()
    rub = fe.BeamModel(effects=(AmplitudeDependentDamping(kind="quadratic", coefficient=2e6),))
    diffs = []
    for amp in (0.002, 0.2):
        f = chirp(amp)
        a = plain.simulate(P, f).sensor_velocity
        b = rub.simulate(P, f).sensor_velocity
        diffs.append(np.linalg.norm(a - b) / np.linalg.norm(a))
    assert diffs[0] < 1e-3 < diffs[1]


def test_bad_effect_parameters_are_rejected_and_the_rom_refuses_what_it_cannot_carry():
    with pytest.raises(ValueError, match="shaker_attachment mass"):
        ShakerAttachment(mass=-1.0)
    with pytest.raises(ValueError, match="clamp_compliance"):
        ClampCompliance(0.0)
    with pytest.raises(ValueError, match="kind"):
        AmplitudeDependentDamping(kind="viscous")
    with pytest.raises(ValueError, match="shaker_attachment"):
        fe.ModalROM(effects=(ShakerAttachment(mass=1e-3),))
