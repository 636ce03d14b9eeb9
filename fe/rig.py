"""The test rig (geometry, material) and the updated parameters, in SI units.

A :class:`Rig` describes the physical beam and where it is excited and
measured; :class:`Parameters` holds the four quantities the paper updates
(eta, c, F, k_s).  Both validate their input and raise ``ValueError`` naming
the offending field.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

# Public constants of the paper (Bussetta, Shiki and da Silva 2017, Table 3).
PAPER_ETA = 3.0e6  # Pa s (deviatoric Kelvin-Voigt viscosity)
PAPER_C = 15.0e3  # N s/m (15 N s/mm)
PAPER_F = 77.0  # N
PAPER_K_S = 180.0e3  # N/m (180 N/mm)


def _check_positive_finite(name: str, value: float, allow_zero: bool = False) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    if value < 0 or (value == 0 and not allow_zero):
        bound = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must be {bound}, got {value}")
    return value


@dataclass(frozen=True)
class Rig:
    """Geometry and material of the preloaded beam rig (SI units).

    Positions are measured from the clamped bottom.  ``bending_stiffness_factor``
    multiplies the bending stiffness EI only (not EA); 1.0 is a locking-free
    model of a real beam, 1.24 reproduces the paper's shear-locking hexahedral
    mesh (see docs/design.md#mesh-locking-and-the-bending-stiffness-factor).
    """

    length_m: float = 0.46
    width_m: float = 0.018
    thickness_m: float = 0.002
    youngs_modulus_pa: float = 58e9
    poisson_ratio: float = 0.33
    density_kg_m3: float = 2700.0
    shaker_position_m: float = 0.065
    sensor_position_m: float = 0.23
    bending_stiffness_factor: float = 1.0

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name == "poisson_ratio":
                value = float(value)
                if not (math.isfinite(value) and -1.0 < value < 0.5):
                    raise ValueError(f"poisson_ratio must lie in (-1, 0.5), got {value}")
            else:
                value = _check_positive_finite(f.name, value)
            object.__setattr__(self, f.name, value)
        for name in ("shaker_position_m", "sensor_position_m"):
            if not 0.0 < getattr(self, name) < self.length_m:
                raise ValueError(
                    f"{name} = {getattr(self, name)} m must lie strictly inside the beam "
                    f"(0, length_m = {self.length_m} m)"
                )

    # derived section properties -------------------------------------------
    @property
    def area(self) -> float:
        """Cross-section area A [m^2]."""
        return self.width_m * self.thickness_m

    @property
    def second_moment(self) -> float:
        """Second moment of area I about the bending axis [m^4]."""
        return self.width_m * self.thickness_m**3 / 12.0

    @property
    def EA(self) -> float:
        """Axial stiffness E A [N]."""
        return self.youngs_modulus_pa * self.area

    @property
    def EI(self) -> float:
        """Bending stiffness E I times ``bending_stiffness_factor`` [N m^2]."""
        return self.youngs_modulus_pa * self.second_moment * self.bending_stiffness_factor

    @property
    def mass_per_length(self) -> float:
        """rho A [kg/m]."""
        return self.density_kg_m3 * self.area

    @property
    def axial_stiffness(self) -> float:
        """K_b = E A / L [N/m], the beam's static axial stiffness."""
        return self.EA / self.length_m

    @property
    def euler_load(self) -> float:
        """Buckling load of the clamped-guided beam, 4 pi^2 EI / L^2 [N]."""
        return 4.0 * math.pi**2 * self.EI / self.length_m**2

    def beam_viscosity(self, eta: float) -> float:
        """Uniaxial Kelvin-Voigt viscosity eta_b [Pa s] from the paper's deviatoric eta.

        Dissipation-equivalent mapping of eta * dev(D) in uniaxial stress with the
        elastic lateral contraction: eta_b = (2/3) (1 + nu)^2 eta.
        """
        return 2.0 / 3.0 * (1.0 + self.poisson_ratio) ** 2 * eta

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict) -> "Rig":
        """Build a rig from the ``rig`` block of a ``dataset.json``; absent keys take defaults."""
        known = {f.name for f in fields(cls)}
        unknown = set(data) - known
        if unknown:
            raise ValueError(f"unknown rig key(s) {sorted(unknown)}; known keys are {sorted(known)}")
        return cls(**data)


@dataclass(frozen=True)
class Parameters:
    """The updated parameters, SI units.

    eta : deviatoric Kelvin-Voigt viscosity of the material [Pa s] (paper: 3 MPa s)
    c   : axial viscous damper at the top guide [N s/m] (paper: 15 N s/mm = 15e3 N s/m)
    F   : constant compressive preload at the top [N] (paper: 77 N)
    k_s : axial spring at the top, to ground [N/m] (paper: 180 N/mm = 180e3 N/m)
    """

    eta: float = PAPER_ETA
    c: float = PAPER_C
    F: float = PAPER_F
    k_s: float = PAPER_K_S

    def __post_init__(self):
        for name in ("eta", "c", "F", "k_s"):
            object.__setattr__(self, name, _check_positive_finite(name, getattr(self, name), allow_zero=True))

    @classmethod
    def from_paper_units(cls, eta_mpa_s: float, c_n_s_per_mm: float, F_n: float, k_s_n_per_mm: float) -> "Parameters":
        """Parameters from the paper's units (MPa s, N s/mm, N, N/mm)."""
        return cls(eta=eta_mpa_s * 1e6, c=c_n_s_per_mm * 1e3, F=F_n, k_s=k_s_n_per_mm * 1e3)

    def effective_preload(self, rig: Rig) -> float:
        """Static axial load carried by the beam, P_eff = F K_b / (K_b + k_s) [N]."""
        kb = rig.axial_stiffness
        return self.F * kb / (kb + self.k_s)

    def to_dict(self) -> dict:
        return asdict(self)


PAPER_PARAMETERS = Parameters()
