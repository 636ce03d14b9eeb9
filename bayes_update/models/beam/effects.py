"""The effects the beam may be missing, as parameters of the contract: each of
:data:`fe.EFFECTS` with its parameters, units and prior ranges
(:data:`EFFECT_PARAMETERS`), the :mod:`fe` effect built from them and back, the
diagnostic each effect's physics moves (:data:`SIGNATURES`), and the hidden
effects a virtual rig's data may carry (:data:`HIDDEN_EFFECT_RANGES`).  Apart
from :mod:`bayes_update.models.beam.model` (the beam's own parameters and coordinates): they are the
discrepancy workflow's vocabulary, and a virtual rig hides the same effects."""

from __future__ import annotations

import math

import numpy as np

import fe

#: The effects the beam may be missing (:meth:`~bayes_update.models.beam.model.Beam.candidate_effects`):
#: (parameter name, unit, low, high, factor to SI) per effect, priors on a
#: physical range for the rig (a strip 460 x 18 x 2 mm, EI/L = 0.58 N m/rad);
#: every parameter is null (the effect off) at 0.
EFFECT_PARAMETERS = {
    "initial_imperfection": (("bow_amplitude", "mm", -1.0, 1.0, 1e-3),),
    "amplitude_dependent_damping": (("quadratic_damping", "MN s^2/m^2", 0.0, 200.0, 1e6),),
    "shaker_attachment": (("shaker_mass", "g", 0.0, 40.0, 1e-3), ("shaker_stiffness", "N/mm", 0.0, 4.0, 1e3)),
    "clamp_compliance": (("clamp_flexibility", "rad/(N m)", 0.0, 0.2, 1.0),),
}
assert set(EFFECT_PARAMETERS) == set(fe.EFFECTS)

#: What each effect's physics moves (the diagnostic that should shrink when it
#: is named): a key of :meth:`~bayes_update.models.beam.model.Beam.signature_values`.
SIGNATURES = {
    "initial_imperfection": "y2",
    "amplitude_dependent_damping": "y3",
    "shaker_attachment": "validation",
    "clamp_compliance": "validation",
}
SIGNATURE_MEANING = {
    "y2": "the residual's second-order share in the high-level chirp (a broken symmetry)",
    "y3": "the residual's third-order share in the high-level chirp (nonlinear dissipation)",
    "validation": "the validation tests' misfit (a linear change the two-coefficient y1 absorbs)",
}


def effect_from_si(name: str, si: list):
    """The :mod:`fe` effect ``name`` at its parameters' SI values."""
    if name == "initial_imperfection":
        return fe.InitialImperfection(amplitude=si[0])
    if name == "amplitude_dependent_damping":
        return fe.AmplitudeDependentDamping(kind="quadratic", coefficient=max(si[0], 0.0))
    if name == "shaker_attachment":
        return fe.ShakerAttachment(mass=max(si[0], 0.0), stiffness=max(si[1], 0.0))
    if name == "clamp_compliance":
        return fe.ClampCompliance(stiffness=math.inf if si[0] <= 0 else 1.0 / si[0])
    raise ValueError(f"no effect named {name!r}")


#: Ranges the hidden-effect data sets draw magnitudes from (SI), uniform:
#: what a real rig of this size shows (a bow of a tenth of a millimetre, a
#: load cell and stud of 5-20 g on a 45 g strip, a bolted clamp of 20-70 EI/L,
#: a guide that rubs), at magnitudes where the effect moves the high-level
#: response by more than the noise.
HIDDEN_EFFECT_RANGES = {
    "initial_imperfection": {"amplitude": (0.05e-3, 0.2e-3)},  # m, either sign
    "amplitude_dependent_damping": {"coefficient": (30e6, 80e6)},  # N s^2/m^2 (quadratic)
    "shaker_attachment": {"mass": (5e-3, 20e-3), "stiffness": (0.5e3, 2e3)},  # kg, N/m
    "clamp_compliance": {"stiffness": (40.0, 120.0)},  # N m/rad
}


def hidden_effects(names, seed: int) -> tuple:
    """Effects named in ``names`` with magnitudes drawn (uniformly, seeded) from
    :data:`HIDDEN_EFFECT_RANGES`; for a virtual rig whose data hide them."""
    rng = np.random.default_rng(seed)
    out = []
    for name in names:
        if name not in HIDDEN_EFFECT_RANGES:
            raise ValueError(f"unknown effect {name!r}; choose from {sorted(HIDDEN_EFFECT_RANGES)}")
        v = {k: float(rng.uniform(*r)) for k, r in HIDDEN_EFFECT_RANGES[name].items()}
        if name == "initial_imperfection":
            v["amplitude"] *= float(rng.choice([-1.0, 1.0]))
            out.append(fe.InitialImperfection(**v))
        elif name == "amplitude_dependent_damping":
            out.append(fe.AmplitudeDependentDamping(kind="quadratic", **v))
        elif name == "shaker_attachment":
            out.append(fe.ShakerAttachment(**v))
        else:
            out.append(fe.ClampCompliance(**v))
    return tuple(out)


def effect_values(effect) -> dict:
    """{parameter name: value in its report unit} of an :mod:`fe` effect (the
    inverse of what :meth:`~bayes_update.models.beam.model.Beam.simulate` builds from theta)."""
    name = effect.name
    if name == "initial_imperfection":
        si = [effect.amplitude]
    elif name == "amplitude_dependent_damping":
        si = [effect.coefficient]
    elif name == "shaker_attachment":
        si = [effect.mass, effect.stiffness]
    elif name == "clamp_compliance":
        si = [0.0 if math.isinf(effect.stiffness) else 1.0 / effect.stiffness]
    else:
        raise ValueError(f"no effect named {name!r}")
    return {p[0]: s / p[4] for s, p in zip(si, EFFECT_PARAMETERS[name])}
