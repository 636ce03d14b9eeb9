"""The discrete 3D strip behind :mod:`fe.continuum`: the assembled, reduced
matrices of one mesh (:class:`Strip`: stiffness, mass and the geometric
stiffness of a unit compression, with the boundary conditions of
:mod:`fe.continuum`'s docstring) and the eigensolvers on them, built from
hexahedral quadrature and scalar basis products (scikit-fem).

Apart from :mod:`fe.continuum`, which checks the inputs, caches one strip per
mesh and turns the strip's eigenvalues into frequencies, loads and bending
factors: this module is the discretization, that one the questions asked of it.
Internal units mm, N, t (tonne), s.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.optimize
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import reverse_cuthill_mckee

from .rig import Rig

UZ_FRACTION = 0.5
"""A mode is through-thickness bending when more than this share of its M-norm is in u_z."""


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
class Strip:
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
