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
import scipy.linalg
import scipy.optimize
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import reverse_cuthill_mckee

from .rig import Rig

try:  # optional: present with scikit-learn; without it the default BLAS threading is used
    from threadpoolctl import threadpool_limits
except ImportError:  # pragma: no cover
    threadpool_limits = None

ELEMENTS = ("hex2", "hex1_sri", "hex1")
PAPER_MESH = (300, 8, 4)
"""The paper's mesh: elements along the length, the width and the thickness."""
PAPER_ELEMENT = "hex1_sri"
UZ_FRACTION = 0.5
"""A mode is through-thickness bending when more than this share of its M-norm is in u_z."""


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


# --------------------------------------------------------------------------- quadrature
def _gauss_hex(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Tensor Gauss-Legendre rule with n points per direction on the unit cube [0, 1]^3."""
    if n == 1:
        # scikit-fem's ``intorder=1`` gives 2 x 2 x 2 points on hexahedra: pass the rule.
        return np.array([[0.5], [0.5], [0.5]]), np.array([1.0])
    t, w = np.polynomial.legendre.leggauss(n)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    gx, gy, gz = np.meshgrid(t, t, t, indexing="ij")
    wx, wy, wz = np.meshgrid(w, w, w, indexing="ij")
    return np.vstack([gx.ravel(), gy.ravel(), gz.ravel()]), (wx * wy * wz).ravel()


def _scalar_basis(mesh, element, n_points: int):
    from skfem import Basis

    basis = Basis(mesh, element, quadrature=_gauss_hex(n_points))
    if basis.X.shape[1] != n_points**3:  # guard against scikit-fem changing the rule
        raise RuntimeError(f"expected {n_points**3} quadrature points, got {basis.X.shape[1]}")
    return basis


def _gradient_products(basis, chunk: int = 2048) -> dict:
    """Scalar matrices S_kl[a, b] = int d_k phi_a d_l phi_b dV (k <= l) and M = int phi_a phi_b."""
    dofs = basis.element_dofs  # (n_local, n_elements)
    n_local, n_el = dofs.shape
    grads = np.array([b[0].grad for b in basis.basis])  # (n_local, 3, n_el, n_qp)
    values = np.array([np.asarray(b[0]) for b in basis.basis])  # (n_local, n_el, n_qp)
    dx = basis.dx  # (n_el, n_qp)
    rows = np.repeat(dofs[:, None, :], n_local, axis=1)  # (a, b, e) -> dof of a
    cols = np.repeat(dofs[None, :, :], n_local, axis=0)
    rows, cols = rows.transpose(2, 0, 1).ravel(), cols.transpose(2, 0, 1).ravel()
    n = basis.N
    pairs = [(k, l) for k in range(3) for l in range(k, 3)]
    data = {p: np.empty((n_el, n_local, n_local)) for p in pairs}
    data["mass"] = np.empty((n_el, n_local, n_local))
    for s in range(0, n_el, chunk):
        e = slice(s, min(s + chunk, n_el))
        g, d = grads[:, :, e, :], dx[e]
        for k, l in pairs:
            data[(k, l)][e] = np.einsum("aeq,beq,eq->eab", g[:, k], g[:, l], d, optimize=True)
        data["mass"][e] = np.einsum("aeq,beq,eq->eab", values[:, e], values[:, e], d, optimize=True)
    out = {}
    for key, v in data.items():
        out[key] = sp.coo_matrix((v.ravel(), (rows, cols)), shape=(n, n)).tocsr()
    return out


# --------------------------------------------------------------------------- the system
class _Strip:
    """Assembled, reduced matrices of one mesh (internal units mm, N, t, s)."""

    def __init__(self, rig: Rig, nodes: tuple, element: str):
        from skfem import ElementHex1, ElementHex2, MeshHex

        L, W, H = (1e3 * v for v in (rig.length_m, rig.width_m, rig.thickness_m))
        E, nu, rho = rig.youngs_modulus_pa * 1e-6, rig.poisson_ratio, rig.density_kg_m3 * 1e-12
        self.area = W * H
        mesh = MeshHex.init_tensor(*(1e3 * np.asarray(x, float) for x in nodes))
        mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
        kappa = lam + 2 * mu / 3
        if element == "hex2":
            basis = _scalar_basis(mesh, ElementHex2(), 3)
            full = _gradient_products(basis)
            vol, vol_factor = full, lam
            dev_shift = 0.0
        else:
            basis = _scalar_basis(mesh, ElementHex1(), 2)
            full = _gradient_products(basis)
            if element == "hex1_sri":
                # 2 mu dev(e):dev(e) at 2x2x2 + kappa tr(e)^2 at the centre
                vol, vol_factor = _gradient_products(_scalar_basis(mesh, ElementHex1(), 1)), kappa
                dev_shift = -2 * mu / 3
            else:
                vol, vol_factor, dev_shift = full, lam, 0.0
        n = full["mass"].shape[0]

        def s(store, k, l):
            return store[(k, l)] if k <= l else store[(l, k)].T

        lap = full[(0, 0)] + full[(1, 1)] + full[(2, 2)]
        blocks = [[None] * 3 for _ in range(3)]
        for i in range(3):
            for j in range(3):
                # 2 mu e(u):e(v) -> mu (delta_ij S_kk + S_ji); tr tr -> S_ij
                b = mu * s(full, j, i) + dev_shift * s(full, i, j) + vol_factor * s(vol, i, j)
                if i == j:
                    b = b + mu * lap
                blocks[i][j] = b
        K = sp.bmat(blocks, format="csr")
        M = sp.block_diag([rho * full["mass"]] * 3, format="csr")
        Kg = sp.block_diag([full[(0, 0)] / self.area] * 3, format="csr")  # per newton of compression

        # boundary conditions: reduction u_full = T u_red
        x = mesh.p[0]
        xd = basis.doflocs[0]
        tol = 1e-9 * L
        bottom, top = np.abs(xd) < tol, np.abs(xd - L) < tol
        if not (bottom.any() and top.any() and abs(x.max() - L) < tol and abs(x.min()) < tol):
            raise ValueError("the mesh nodes must span 0 .. rig.length_m along x")
        keep = np.ones(3 * n, dtype=bool)
        keep[np.r_[np.flatnonzero(bottom), n + np.flatnonzero(bottom | top), 2 * n + np.flatnonzero(bottom | top)]] = (
            False
        )
        tied = np.flatnonzero(top)  # u_x of the top face -> one master dof
        keep[tied] = False
        free = np.flatnonzero(keep)
        n_red = free.size + 1
        rows = np.r_[free, tied]
        cols = np.r_[np.arange(free.size), np.full(tied.size, free.size)]
        T = sp.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(3 * n, n_red))
        self.T, self.n_scalar = T, n
        self.K = (T.T @ K @ T).tocsc()
        self.M = (T.T @ M @ T).tocsc()
        self.Kg = (T.T @ Kg @ T).tocsc()
        self.Ms = rho * full["mass"]
        self.n_dof = n_red
        self._perm = reverse_cuthill_mckee(self.K.tocsr(), symmetric_mode=True)

    # ----------------------------------------------------------------- helpers
    def uz_fraction(self, phi: np.ndarray) -> np.ndarray:
        """Share of each column's M-norm in u_z."""
        u = self.T @ phi
        n = self.n_scalar
        parts = [np.einsum("ij,ij->j", u[c * n : (c + 1) * n], self.Ms @ u[c * n : (c + 1) * n]) for c in range(3)]
        return parts[2] / (parts[0] + parts[1] + parts[2])

    def _factor(self, A):
        """Solver for A x = b by banded Cholesky in the reverse Cuthill-McKee order.

        The strip is slender, so the band is narrow (a few hundred) and this is much
        faster than a general sparse LU.  Raises numpy.linalg.LinAlgError when A is
        not positive definite.
        """
        p = self._perm
        Ap = A.tocsr()[p][:, p].tocoo()
        upper = Ap.row <= Ap.col
        bw = int((Ap.col - Ap.row)[upper].max())
        ab = np.zeros((bw + 1, A.shape[0]))
        ab[bw + Ap.row[upper] - Ap.col[upper], Ap.col[upper]] = Ap.data[upper]
        chol = scipy.linalg.cholesky_banded(ab, lower=False, overwrite_ab=True, check_finite=False)
        inv = np.argsort(p)

        def solve(b):
            b = np.asarray(b, float).reshape(A.shape[0], -1)
            x = scipy.linalg.cho_solve_banded((chol, False), b[p], check_finite=False)[inv]
            return x if x.shape[1] > 1 else x[:, 0]

        return spla.LinearOperator(A.shape, matvec=solve, matmat=solve, dtype=float)

    def eig_near_zero(self, A, B, k: int):
        """Generalised eigenpairs of A x = lam B x with the k smallest lam (A positive definite)."""
        k = min(k, self.n_dof - 2)
        lam, phi = spla.eigsh(A, k=k, M=B, sigma=0.0, which="LM", OPinv=self._factor(A), tol=1e-10)
        order = np.argsort(lam)
        return lam[order], phi[:, order]

    def bending(self, A, B, n: int, what: str):
        """The n lowest eigenpairs (from 0 upwards) that are through-thickness bending."""
        k = n + 4
        while True:
            lam, phi = self.eig_near_zero(A, B, k)
            z = self.uz_fraction(phi) > UZ_FRACTION
            if z.sum() >= n or k >= self.n_dof - 2:
                break
            k *= 2
        if z.sum() < n:
            raise RuntimeError(f"found only {z.sum()} through-thickness bending {what}")
        return lam[z][:n], phi[:, z][:, :n], lam, z


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
def _strip_cached(rig: Rig, nodes: tuple, element: str) -> _Strip:
    return _Strip(rig, nodes, element)


def _strip(rig: Rig, mesh, element: str) -> _Strip:
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
