"""The grids of the paper's two-stage updating and their coordinates: the grid
settings (:class:`CalibrationSettings`, paper units), a grid point from (eta, c,
k_s) and the preload P_eff the beam carries, a point's row of the tables, and
the preload at which the model's first mode sits at the data's Kautz pole (the
centre of the P_eff window).  Apart from :mod:`bayes_update.models.beam.calibrate`, which walks the
grids, so that what a grid point is can be read on its own."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

import fe


@dataclass(frozen=True)
class CalibrationSettings:
    """Grids in the paper's units (c [N s/mm], k_s [N/mm], P_eff [N], eta [MPa s])."""

    c_values: tuple = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0)
    k_s_values: tuple = tuple(float(k) for k in range(0, 601, 60))
    p_eff_halfwidth: float = 3.0
    p_eff_step: float = 0.5
    eta_values: tuple = tuple(float(e) for e in np.round(np.arange(1.0, 6.001, 0.25), 2))
    refine_max_evaluations: int = 80

    def __post_init__(self):
        for name in ("c_values", "k_s_values", "eta_values"):
            v = np.asarray(getattr(self, name), float)
            if v.ndim != 1 or v.size == 0 or not np.all(np.isfinite(v)) or np.any(v < 0):
                raise ValueError(f"{name} must be a non-empty list of non-negative numbers")
        if len(self.eta_values) < 3:
            raise ValueError("eta_values needs at least 3 values (a parabola is fitted)")
        if not (self.p_eff_step > 0 and self.p_eff_halfwidth >= self.p_eff_step):
            raise ValueError("need p_eff_step > 0 and p_eff_halfwidth >= p_eff_step")

    @classmethod
    def quick(cls) -> "CalibrationSettings":
        """Coarse grids for tests and a first look (about 1/10 of the runs)."""
        return cls(
            c_values=(5.0, 15.0, 25.0),
            k_s_values=(0.0, 200.0, 400.0, 600.0),
            p_eff_halfwidth=1.0,
            p_eff_step=0.5,
            eta_values=(2.0, 2.5, 3.0, 3.5, 4.0, 4.5),
            refine_max_evaluations=40,
        )


def parameters_from(beam, eta_mpa_s: float, c_n_s_per_mm: float, k_s_n_per_mm: float, p_eff_n: float) -> dict:
    """theta (paper units) from (eta, c, k_s) and the preload P_eff [N] carried
    by the beam: F = P_eff (K_b + k_s) / K_b."""
    return beam.from_internal([eta_mpa_s, c_n_s_per_mm, p_eff_n, k_s_n_per_mm])


def paper_units(theta: dict, beam) -> dict:
    """A point's row of the tables: the parameters and P_eff, paper units."""
    return {
        "eta_MPa_s": theta["eta"],
        "c_N_s_per_mm": theta["c"],
        "F_N": theta["F"],
        "k_s_N_per_mm": theta["k_s"],
        "P_eff_N": float(beam.to_internal(theta)[2]),
    }


def preload_for_frequency(model, freq_hz: float, eta: float = 0.0) -> float:
    """P_eff [N] at which the model's linearised first mode is ``freq_hz``
    (k_s = c = 0 so that F = P_eff)."""
    p_cr = model.buckling_load()

    def f1(p):
        return model.modal_analysis(fe.Parameters(eta=eta, c=0.0, F=p, k_s=0.0), n_modes=1).frequencies_hz[0]

    lo, hi = 0.0, 0.995 * p_cr
    if not f1(hi) < freq_hz < f1(lo):
        raise ValueError(
            f"no preload between 0 and {hi:.1f} N gives a first mode at {freq_hz:.2f} Hz "
            f"(model: {f1(lo):.2f} Hz unloaded, {f1(hi):.2f} Hz near buckling); "
            "check the rig (length, thickness, modulus, bending_stiffness_factor)"
        )
    # Brent's method to 1e-9 of the buckling load: some ten modal analyses against the 50 of a
    # bisection to machine precision (0.2 s each on the default rig)
    return float(brentq(lambda p: f1(p) - freq_hz, lo, hi, xtol=1e-9 * p_cr))
