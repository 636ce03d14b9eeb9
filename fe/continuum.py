"""3D continuum reference of the preloaded strip (scikit-fem): linear modes and buckling.

A linear-elastic hexahedral model of the rig's strip (length x width x
thickness along x, y, z), linearised about a uniform axial prestress
sigma_xx = -P / A (compression P > 0) with its geometric stiffness on all three
displacement components.  Boundary conditions ("variant B" of
``docs/mesh_locking_study.md``): the bottom face x = 0 is fully fixed; on the
top face x = L every node has u_y = u_z = 0 and all top-face u_x are tied to one
value, i.e. a rigid plate that slides along the axis without rotating: the
boundary of :class:`fe.BeamModel` (transversally clamped at both ends, the top
free axially; buckling load 4 pi^2 EI / L^2).

Two discretizations:

``"hex2"``
    triquadratic (27-node) Lagrange hexahedra, 3 x 3 x 3 Gauss points (exact
    on the box elements used here): the locking-free continuum.  Two layers
    through the thickness are enough.
``"hex1_sri"``
    the paper's element: trilinear hexahedra, deviatoric part with 2 x 2 x 2
    Gauss points, pressure (volumetric part) constant per element from one
    central point.  On the paper's mesh 300 x 8 x 4 it shear-locks.
``"hex1"``
    trilinear hexahedra, everything with 2 x 2 x 2 points (for comparison).

Mass and geometric stiffness are consistent and integrated with the
element's full rule.  The continuum uses E and nu of the rig and ignores
``rig.bending_stiffness_factor`` (that factor belongs to beam models).

A mode (or buckling mode) is *through-thickness bending* when more than half
of its kinetic energy (its M-norm) is in u_z; f1 is the lowest such mode.

Units at the interface are SI (m in the rig and in node arrays, N, Hz);
internally the model works in mm, N, t (tonne), s.

The assembled strip and its eigensolvers are in :mod:`fe.continuum_strip`;
this module checks the inputs, caches a strip per mesh and asks it the questions.

Example (a few seconds each)::

    import fe, fe.continuum as fc
    fc.strip_modes(fe.Rig(), (300, 8, 4), "hex1_sri", preload_n=74.0)[0]  # 37.12 Hz
    fc.buckling_load(fe.Rig(), (300, 8, 4), "hex1_sri")                     # 160.7 N
    fc.load_for_frequency(fe.Rig(), (300, 8, 4), "hex1_sri", 37.0)          # 74.6 N
    fc.effective_bending_factor(fe.Rig())          # 1.241 / 1.237 / 1.239 (f0 / Pcr / f74)
    fc.strip_modes(fe.Rig(), (80, 4, 2), "hex2")[0]                          # 45.37 Hz
"""

from __future__ import annotations

import dataclasses
import functools
import math
from typing import NamedTuple

import numpy as np
import scipy.optimize

from .continuum_strip import UZ_FRACTION, Strip
from .rig import Rig

try:  # optional: present with scikit-learn; without it the default BLAS threading is used
    from threadpoolctl import threadpool_limits
except ImportError:  # pragma: no cover
    threadpool_limits = None

ELEMENTS = ("hex2", "hex1_sri", "hex1")
PAPER_MESH = (300, 8, 4)
"""The paper's mesh: elements along the length, the width and the thickness."""
PAPER_ELEMENT = "hex1_sri"


def _single_threaded(func):
    """Run with one BLAS thread.

    The banded Cholesky factorizations are not faster on two threads, and on a
    shared machine a multithreaded OpenBLAS slows them (and the assembly) down by
    up to 10x.  Needs threadpoolctl; without it this is a no-op.
    """

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        if threadpool_limits is None:
            return func(*args, **kwargs)
        with threadpool_limits(limits=1, user_api="blas"):
            return func(*args, **kwargs)

    return wrapper


def _normalise_mesh(rig: Rig, mesh) -> tuple:
    """(nx, ny, nz) -> uniform node arrays [m]; or three node arrays [m] as given."""
    if len(mesh) != 3:
        raise ValueError(f"mesh must be (nx, ny, nz) or three node arrays, got {mesh!r}")
    dims = (rig.length_m, rig.width_m, rig.thickness_m)
    out = []
    for m, d, name in zip(mesh, dims, "xyz"):
        if np.ndim(m) == 0:
            if int(m) != m or m < 1:
                raise ValueError(f"number of elements along {name} must be a positive integer, got {m}")
            out.append(tuple(np.linspace(0.0, d, int(m) + 1)))
        else:
            a = np.asarray(m, float)
            if a.ndim != 1 or a.size < 2 or np.any(np.diff(a) <= 0):
                raise ValueError(f"nodes along {name} must increase strictly")
            if abs(a[0]) > 1e-12 * d or abs(a[-1] - d) > 1e-9 * d:
                raise ValueError(f"nodes along {name} must span 0 .. {d} m, got {a[0]} .. {a[-1]}")
            out.append(tuple(a))
    return tuple(out)


@functools.lru_cache(maxsize=2)
def _strip_cached(rig: Rig, nodes: tuple, element: str) -> Strip:
    return Strip(rig, nodes, element)


def _strip(rig: Rig, mesh, element: str) -> Strip:
    if not isinstance(rig, Rig):
        raise TypeError("rig must be an fe.Rig")
    if element not in ELEMENTS:
        raise ValueError(f"element must be one of {ELEMENTS}, got {element!r}")
    # the continuum ignores the beam's bending-stiffness factor: one cache entry for all
    rig = dataclasses.replace(rig, bending_stiffness_factor=1.0)
    return _strip_cached(rig, _normalise_mesh(rig, mesh), element)


def graded_nodes(length: float, n: int, strength: float = 0.75) -> np.ndarray:
    """Nodes on [0, length] refined symmetrically toward both ends.

    x(s) = length (s - strength sin(2 pi s) / (2 pi)), s uniform: the end
    elements are about (1 - strength) times the uniform size, the middle ones
    (1 + strength) times.  ``strength = 0`` gives a uniform mesh.
    """
    if not 0.0 <= strength < 1.0:
        raise ValueError(f"strength must lie in [0, 1), got {strength}")
    s = np.linspace(0.0, 1.0, int(n) + 1)
    return length * (s - strength * np.sin(2 * np.pi * s) / (2 * np.pi))


# --------------------------------------------------------------------------- public API
@_single_threaded
def n_dofs(rig: Rig, mesh, element: str = "hex2") -> int:
    """Number of unknowns after the boundary conditions."""
    return _strip(rig, mesh, element).n_dof


@_single_threaded
def strip_modes(
    rig: Rig, mesh=PAPER_MESH, element: str = PAPER_ELEMENT, preload_n: float = 0.0, n_modes: int = 1
) -> np.ndarray:
    """Frequencies [Hz] of the lowest through-thickness bending modes under axial load.

    Parameters
    ----------
    rig : geometry and material (E, nu, rho; ``bending_stiffness_factor`` is ignored).
    mesh : (nx, ny, nz) elements along length, width, thickness (uniform), or three
        increasing node arrays [m] spanning the strip.
    element : "hex2", "hex1_sri" (the paper's) or "hex1".
    preload_n : axial compression P [N] (negative = tension) of the uniform prestress.
    n_modes : how many bending modes to return (lowest first).

    Raises ValueError when the preload is at or beyond buckling (a bending mode with
    imaginary frequency).
    """
    if int(n_modes) != n_modes or n_modes < 1:
        raise ValueError(f"n_modes must be a positive integer, got {n_modes}")
    st = _strip(rig, mesh, element)
    A = st.K - float(preload_n) * st.Kg
    try:
        w2, _, _, _ = st.bending(A, st.M, int(n_modes), "modes")
    except np.linalg.LinAlgError:  # K - P K_g not positive definite
        raise ValueError(f"preload {preload_n} N is at or beyond the buckling load of this model") from None
    return np.sqrt(w2) / (2 * np.pi)


@_single_threaded
def buckling_load(rig: Rig, mesh=PAPER_MESH, element: str = PAPER_ELEMENT) -> float:
    """Linear buckling load [N] (lowest through-thickness bending buckling mode).

    Solves K phi = P K_g phi, K_g the geometric stiffness of a unit compression.
    """
    st = _strip(rig, mesh, element)
    p, _, p_all, z = st.bending(st.K, st.Kg, 1, "buckling modes")
    if not z[0]:
        raise RuntimeError(f"the lowest buckling mode ({p_all[0]:.4g} N) is not through-thickness bending")
    return float(p[0])


@_single_threaded
def load_for_frequency(rig: Rig, mesh=PAPER_MESH, element: str = PAPER_ELEMENT, f_target: float = 37.0) -> float:
    """Axial compression [N] at which the model's first mode has frequency f_target [Hz].

    Exact, without iteration: the lowest P with (K - P K_g - omega_t^2 M) singular, i.e.
    the smallest eigenvalue of (K - omega_t^2 M) phi = P K_g phi.  f_target must lie
    below the unloaded first frequency (a compressive answer); otherwise ValueError.
    """
    if not (math.isfinite(f_target) and f_target > 0):
        raise ValueError(f"f_target must be a positive frequency in Hz, got {f_target}")
    st = _strip(rig, mesh, element)
    w2 = (2 * np.pi * f_target) ** 2
    try:
        lam, phi = st.eig_near_zero((st.K - w2 * st.M).tocsc(), st.Kg, 4)
    except np.linalg.LinAlgError:  # K - omega_t^2 M not positive definite
        raise ValueError(
            f"f_target = {f_target} Hz is not below the unloaded first frequency: reaching it needs tension"
        ) from None
    if st.uz_fraction(phi[:, :1])[0] <= UZ_FRACTION:
        raise RuntimeError("the mode reaching f_target is not through-thickness bending")
    return float(lam[0])


class BendingFactor(NamedTuple):
    """Effective bending-stiffness factor EI_eff / EI of a 3D model against the Euler-Bernoulli beam.

    The 3D figures (Hz, N) and the factor a beam (fe.BeamModel, E of the rig) needs to
    reproduce each: from the unloaded f1, from the buckling load and from f1 at
    ``preload_n``.
    """

    f0_hz: float
    f_loaded_hz: float
    buckling_load_n: float
    preload_n: float
    from_unloaded: float
    from_buckling: float
    from_loaded: float


def _beam(rig: Rig, factor: float = 1.0, n_elements: int = 64):
    from .model import BeamModel

    return BeamModel(rig=dataclasses.replace(rig, bending_stiffness_factor=factor), n_elements=n_elements)


@_single_threaded
def beam_frequency(rig: Rig, preload_n: float = 0.0, factor: float = 1.0, n_elements: int = 64) -> float:
    """f1 [Hz] of the Euler-Bernoulli reference (fe.BeamModel, no damping) at axial load P [N]."""
    from .rig import Parameters

    params = Parameters(eta=0.0, c=0.0, F=float(preload_n), k_s=0.0)
    return float(_beam(rig, factor, n_elements).modal_analysis(params, n_modes=1).frequencies_hz[0])


@_single_threaded
def effective_bending_factor(
    rig: Rig, mesh=PAPER_MESH, element: str = PAPER_ELEMENT, preload_n: float = 74.0, n_beam_elements: int = 64
) -> BendingFactor:
    """EI_eff / EI that fe.BeamModel needs to reproduce this 3D model (three estimates).

    from_unloaded = (f0_3D / f0_beam)^2; from_buckling = Pcr_3D / Pcr_beam; from_loaded
    solves f1_beam(factor, preload_n) = f1_3D(preload_n) for the factor.  They agree when
    the 3D model bends like a beam with a scaled EI (no other difference).
    """
    f0 = strip_modes(rig, mesh, element, 0.0)[0]
    fp = strip_modes(rig, mesh, element, preload_n)[0]
    pcr = buckling_load(rig, mesh, element)
    f0_beam = beam_frequency(rig, 0.0, 1.0, n_beam_elements)
    pcr_beam = _beam(rig, 1.0, n_beam_elements).buckling_load()
    c_f0 = (f0 / f0_beam) ** 2
    c_lo, c_hi = 0.5 * c_f0, 2.0 * c_f0
    c_lo = max(c_lo, 1.01 * preload_n / pcr_beam)  # the beam must not buckle at preload_n
    c_loaded = scipy.optimize.brentq(
        lambda c: beam_frequency(rig, preload_n, c, n_beam_elements) - fp, c_lo, c_hi, xtol=1e-7
    )
    return BendingFactor(
        f0_hz=float(f0),
        f_loaded_hz=float(fp),
        buckling_load_n=pcr,
        preload_n=float(preload_n),
        from_unloaded=float(c_f0),
        from_buckling=float(pcr / pcr_beam),
        from_loaded=float(c_loaded),
    )


def shear_locking_estimate(rig: Rig, element_length_m: float) -> float:
    """Parasitic-shear stiffening of linear hexahedra in bending, 1 + 2 a^2 / ((1 + nu) h^2).

    a = half the element length, h = thickness; EI_eff / EI of a fully integrated
    (deviatoric part) trilinear mesh, independent of the number of layers.
    """
    a = 0.5 * element_length_m
    return 1.0 + 2.0 * a**2 / ((1.0 + rig.poisson_ratio) * rig.thickness_m**2)
