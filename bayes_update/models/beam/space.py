"""The beam's parameter space: the prior box of (eta, c, F, k_s) and its internal coordinates.

Parameter space: the prior is uniform on the box of (eta, c, F, k_s) of
docs/design.md#parameters-units-and-the-prior-box.  Inference runs in the
internal coordinates x = (eta [MPa s], c [N
s/mm], P_eff [N], k_s [N/mm]), because e_lin depends on F and k_s almost only
through the preload the beam carries, P_eff = F K_b / (K_b + k_s); the
uniform prior then has density (K_b + k_s) / K_b (the Jacobian of F ->
P_eff) on the image of the box.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
import numpy as np

import fe


MPA_S, N_S_PER_MM, N_PER_MM = 1e6, 1e3, 1e3


#: Internal coordinate names and units.
NAMES = ("eta", "c", "P_eff", "k_s")


UNITS = {"eta": "MPa s", "c": "N s/mm", "P_eff": "N", "k_s": "N/mm", "F": "N"}


#: SI units of the public parameters.
SI_UNITS = {"eta": "Pa s", "c": "N s/m", "F": "N", "k_s": "N/m", "P_eff": "N"}


#: Factors from paper units to SI.
TO_SI = {"eta": MPA_S, "c": N_S_PER_MM, "F": 1.0, "k_s": N_PER_MM, "P_eff": 1.0}


@dataclass(frozen=True)
class ParameterSpace:
    """Uniform prior box of (eta, c, F, k_s) in paper units, and the internal
    coordinates x = (eta [MPa s], c [N s/mm], P_eff [N], k_s [N/mm])."""

    rig: fe.Rig = field(default_factory=fe.Rig)
    eta: tuple = (1.0, 6.0)       # MPa s
    c: tuple = (0.0, 30.0)        # N s/mm
    F: tuple = (60.0, 95.0)       # N
    k_s: tuple = (0.0, 600.0)     # N/mm

    def __post_init__(self):
        for name in ("eta", "c", "F", "k_s"):
            lo, hi = (float(v) for v in getattr(self, name))
            if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
                raise ValueError(f"prior range of {name} must be finite with low < high, got {(lo, hi)}")
            if lo < 0 or (name in ("eta", "F") and lo <= 0):
                raise ValueError(f"prior range of {name} must be {'positive' if name in ('eta', 'F') else 'non-negative'}, "
                                 f"got {(lo, hi)} {UNITS[name]}")
            object.__setattr__(self, name, (lo, hi))

    @property
    def kb(self) -> float:
        """Axial stiffness of the beam EA/L [N/mm]."""
        return self.rig.axial_stiffness / N_PER_MM

    def box(self) -> np.ndarray:
        """(4, 2) bounding box of the prior in internal coordinates."""
        kb = self.kb
        p_lo = self.F[0] * kb / (kb + self.k_s[1])
        p_hi = self.F[1] * kb / (kb + self.k_s[0])
        return np.array([self.eta, self.c, (p_lo, p_hi), self.k_s], float)

    def F_of(self, X) -> np.ndarray:
        X = np.atleast_2d(X)
        return X[:, 2] * (self.kb + X[:, 3]) / self.kb

    def log_prior(self, X) -> np.ndarray:
        """Log density (up to a constant) of the uniform box prior at internal points (n, 4)."""
        X = np.atleast_2d(np.asarray(X, float))
        F = self.F_of(X)
        inside = ((X[:, 0] >= self.eta[0]) & (X[:, 0] <= self.eta[1]) & (X[:, 1] >= self.c[0])
                  & (X[:, 1] <= self.c[1]) & (X[:, 3] >= self.k_s[0]) & (X[:, 3] <= self.k_s[1])
                  & (F >= self.F[0]) & (F <= self.F[1]))
        with np.errstate(divide="ignore"):
            return np.where(inside, np.log((self.kb + X[:, 3]) / self.kb), -np.inf)

    def contains(self, params: fe.Parameters) -> bool:
        return bool(np.isfinite(self.log_prior(self.to_internal(params)))[0])

    def check(self, params: fe.Parameters, what: str = "parameters") -> None:
        """Raise a ValueError naming the parameter that is outside the prior box."""
        u = {"eta": params.eta / MPA_S, "c": params.c / N_S_PER_MM, "F": params.F, "k_s": params.k_s / N_PER_MM}
        for name, v in u.items():
            lo, hi = getattr(self, name)
            if not lo <= v <= hi:
                raise ValueError(f"{what}: {name} = {v:g} {UNITS[name]} is outside the prior box "
                                 f"[{lo:g}, {hi:g}] {UNITS[name]}")

    def to_internal(self, params: fe.Parameters) -> np.ndarray:
        return np.array([params.eta / MPA_S, params.c / N_S_PER_MM, params.effective_preload(self.rig),
                         params.k_s / N_PER_MM])

    def to_parameters(self, x) -> fe.Parameters:
        x = np.asarray(x, float)
        return fe.Parameters(eta=x[0] * MPA_S, c=x[1] * N_S_PER_MM, F=float(self.F_of(x)[0]),
                             k_s=x[3] * N_PER_MM)

    def to_si(self, X) -> dict:
        """{name: array} in SI for the public parameters and P_eff."""
        X = np.atleast_2d(np.asarray(X, float))
        return {"eta": X[:, 0] * MPA_S, "c": X[:, 1] * N_S_PER_MM, "F": self.F_of(X),
                "k_s": X[:, 3] * N_PER_MM, "P_eff": X[:, 2]}

    def sample_prior(self, n: int, seed=None) -> np.ndarray:
        """``n`` internal points drawn from the prior (uniform in (eta, c, F, k_s))."""
        rng = np.random.default_rng(seed)
        lo = np.array([self.eta[0], self.c[0], self.F[0], self.k_s[0]])
        hi = np.array([self.eta[1], self.c[1], self.F[1], self.k_s[1]])
        U = lo + (hi - lo) * rng.random((int(n), 4))
        P = U[:, 2] * self.kb / (self.kb + U[:, 3])
        return np.column_stack([U[:, 0], U[:, 1], P, U[:, 3]])

    def to_dict(self) -> dict:
        return {"eta_MPa_s": list(self.eta), "c_N_s_per_mm": list(self.c), "F_N": list(self.F),
                "k_s_N_per_mm": list(self.k_s)}

    # -- the interface the generic pipeline uses (bayes_update.core.ParameterSet has the same) --
    coordinate_names = NAMES                        # internal coordinates
    units = UNITS                                   # paper units (also of F)
    public_names = ("eta", "c", "F", "k_s")         # the declared parameters, in paper units
    report_units = SI_UNITS                         # posterior.nc and summary values (SI) ...
    display = {n: (UNITS[n], TO_SI[n]) for n in SI_UNITS}   # ... and their paper units, factor to SI
    has_ridge = True                                # the linear-only posterior and the ridge plot

    def ridge_posterior(self, res, pool, seed, cache_dir, progress, log, reused=None) -> dict:
        """The linear-only posterior on the (F, k_s) ridge (:mod:`bayes_update.models.beam.ridge`)."""
        from bayes_update.models.beam.ridge import linear_only_posterior

        return linear_only_posterior(res, pool, seed, cache_dir, progress, log, reused)

    def report(self, X) -> dict:
        """Variables of posterior.nc and the summary: the parameters and P_eff, SI."""
        return self.to_si(X)

    def describe(self, params: fe.Parameters) -> dict:
        """A point in paper units, with P_eff (JSON)."""
        return {"eta_MPa_s": params.eta / MPA_S, "c_N_s_per_mm": params.c / N_S_PER_MM,
                "F_N": params.F, "k_s_N_per_mm": params.k_s / N_PER_MM,
                "P_eff_N": params.effective_preload(self.rig)}

    def public_box(self) -> np.ndarray:
        """(4, 2) prior box of the declared parameters (eta, c, F, k_s), paper units."""
        return np.array([self.eta, self.c, self.F, self.k_s], float)

    def public_to_parameters(self, u) -> fe.Parameters:
        u = np.asarray(u, float)
        return fe.Parameters(eta=u[0] * MPA_S, c=u[1] * N_S_PER_MM, F=u[2], k_s=u[3] * N_PER_MM)

    def extra_starts(self, x, n: int = 3) -> list:
        """Points on the (c, k_s) band at the (eta, P_eff) of ``x``: an n x n grid
        over the prior's c and k_s ranges, kept where F stays inside its range
        (the low level pins eta and P_eff; along the band the nonlinear misfit
        can have more than one valley)."""
        out = []
        for c in self.c[0] + (self.c[1] - self.c[0]) * (np.arange(n) + 0.5) / n:
            for ks in self.k_s[0] + (self.k_s[1] - self.k_s[0]) * (np.arange(n) + 0.5) / n:
                p = np.array([x[0], c, x[2], ks])
                if np.isfinite(self.log_prior(p)[0]):
                    out.append(p)
        return out


def refined_model(model):
    """A finer version of ``model`` for the model-error term.

    ``fe.BeamModel``: 3x the elements and 4x the substeps; ``fe.ModalROM``:
    the full FE at those settings (the ROM's truncation and its integration are
    the error).  Anything else: ``model.refined()`` if it has one, else None."""
    if hasattr(model, "refined"):
        return model.refined()
    if isinstance(model, fe.BeamModel):
        import dataclasses
        return dataclasses.replace(model, n_elements=3 * model.n_elements, substeps=4 * model.substeps)
    if isinstance(model, fe.ModalROM):
        return fe.BeamModel(rig=model.rig, n_elements=3 * fe.model.DEFAULT_ELEMENTS,
                            substeps=4 * fe.model.DEFAULT_SUBSTEPS, effects=model.effects)
    return None     # no finer model known: the model-error term is zero (the report says so)
