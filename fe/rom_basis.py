"""The modal ROM's basis: the transverse FE matrices of the rig
(:class:`RigMatrices`, assembled once per model from the cubic Hermite element)
and the reduced matrices at one preload (:class:`ReducedSystem`, cached per
P_eff), built for :class:`fe.ModalROM` by the mixin :class:`ROMBasis`.

Apart from :mod:`fe.rom` because building the Galerkin basis (the FE matrices,
the bow, the per-preload eigenproblem) is one job and integrating the modal
equations in it another; the method is in :mod:`fe.rom`'s docstring.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import scipy.linalg

from .mesh import hermite_weights
from .model import BeamModel
from .results import check_below_buckling
from .rig import Parameters

try:  # a declared dependency; without it the default BLAS threading is used
    from threadpoolctl import ThreadpoolController
except ImportError:  # pragma: no cover
    ThreadpoolController = None

BOW_REFINEMENT = 16  # grid of the bow, per element of the ROM's mesh
_CACHE_SIZE = 64


_BLAS = []  # the process's ThreadpoolController, made on first use (~1 ms)


def _one_blas_thread():
    """Context with one BLAS thread: the per-preload eigenproblem (~0.1 ms) is
    not faster on more, and on a shared machine a multithreaded OpenBLAS made it
    1.7x slower at 30 elements and up to 20x at 40.  Costs ~20 us."""
    if ThreadpoolController is None:
        return contextlib.nullcontext()
    if not _BLAS:
        _BLAS.append(ThreadpoolController())
    return _BLAS[0].limit(limits=1, user_api="blas")


# ----------------------------------------------------------------- FE matrices
def _element_matrices(le: np.ndarray, rho_a: float, ei: float):
    """Hermite element matrices on (w1, theta1, w2, theta2), one per element:
    consistent mass [kg], bending stiffness [N/m] and the shortening form
    int N_i' N_j' dx [1/m] (all exact for the cubic shapes)."""
    l = le[:, None, None]
    one = np.ones_like(l)
    m = (
        rho_a
        * l
        / 420.0
        * np.block(
            [
                [156 * one, 22 * l, 54 * one, -13 * l],
                [22 * l, 4 * l**2, 13 * l, -3 * l**2],
                [54 * one, 13 * l, 156 * one, -22 * l],
                [-13 * l, -3 * l**2, -22 * l, 4 * l**2],
            ]
        )
    )
    k = (
        ei
        / l**3
        * np.block(
            [
                [12 * one, 6 * l, -12 * one, 6 * l],
                [6 * l, 4 * l**2, -6 * l, 2 * l**2],
                [-12 * one, -6 * l, 12 * one, -6 * l],
                [6 * l, 2 * l**2, -6 * l, 4 * l**2],
            ]
        )
    )
    g = (
        1.0
        / (30.0 * l)
        * np.block(
            [
                [36 * one, 3 * l, -36 * one, 3 * l],
                [3 * l, 4 * l**2, -3 * l, -(l**2)],
                [-36 * one, -3 * l, 36 * one, -3 * l],
                [3 * l, -(l**2), -3 * l, 4 * l**2],
            ]
        )
    )
    return m, k, g


def _assemble(blocks: np.ndarray) -> np.ndarray:
    """Dense assembly of 4x4 element blocks on a chain of (w, theta) nodes."""
    ne = blocks.shape[0]
    out = np.zeros((2 * (ne + 1), 2 * (ne + 1)))
    for e in range(ne):
        out[2 * e : 2 * e + 4, 2 * e : 2 * e + 4] += blocks[e]
    return out


@dataclass(frozen=True)
class RigMatrices:
    """Transverse FE matrices on the free dofs (w, theta of the inner nodes),
    assembled once per model.

    mass [kg], bending [N/m] (EI with the rig's factor), geometric [1/m]
    (int N_i' N_j' dx: the tangent per newton of tension), chol_inv: L^-1 with
    mass = L L^T, bending_t / geometric_t: L^-1 (.) L^-T, shaker: load vector of
    a unit shaker force, bow [-]: int w0' N_j' dx, buckling_load [N].
    """

    node_x: np.ndarray
    mass: np.ndarray
    bending: np.ndarray
    geometric: np.ndarray
    chol_inv: np.ndarray
    bending_t: np.ndarray
    geometric_t: np.ndarray
    shaker: np.ndarray
    bow: np.ndarray
    buckling_load: float


@dataclass(frozen=True)
class ReducedSystem:
    """The ROM's matrices at one preload, in mass-normalised coordinates.

    p_eff [N]: static compression of the beam; stretch [-]: lam = 1 - P_eff/EA;
    omega [rad/s]: natural frequencies of the straight beam at p_eff (the first
    n_modes, ascending); shapes: (n_free, n_modes) basis on the free transverse
    dofs (w, theta of the inner nodes), spanning the first n_modes preloaded
    modes, rotated so that the bending stiffness is diagonal; kappa [1/s^2]:
    that diagonal; G [1/(kg m)]: int phi_i' phi_j' dx / lam; g0 [1/kg^0.5]:
    int w0' phi_i' dx / lam; b [1/kg^0.5]: phi_i(x_shaker); outputs: cache of
    output weights (rows phi_i(x)) per position set.
    """

    p_eff: float
    stretch: float
    omega: np.ndarray
    shapes: np.ndarray
    kappa: np.ndarray
    G: np.ndarray
    g0: np.ndarray
    b: np.ndarray
    outputs: dict = field(default_factory=dict, repr=False, compare=False)  # positions -> W


class ROMBasis:
    """The per-model and per-preload precomputation of :class:`fe.ModalROM` (mixed
    into it; uses the model's fields ``rig``, ``n_modes``, ``n_elements``,
    ``effects`` and ``_cache``)."""

    # ------------------------------------------------------ per-model precompute
    @cached_property
    def _fe_model(self) -> BeamModel:
        """The full FE model whose element, mesh and boundaries the ROM inherits.

        Checks each effect by applying it to a fresh description: the ROM
        carries an effect only if it changes nothing but ``node_y``."""
        model = BeamModel(rig=self.rig, n_elements=self.n_elements, effects=self.effects)
        params = Parameters()
        plain = model.describe(params, effects=False)
        for eff in self.effects:
            probe = model.describe(params, effects=False)
            eff.apply(probe, self.rig, params)
            changed = [
                name
                for name in ("node_x", "fixed", "f_const", "b_load")
                if not np.array_equal(getattr(probe, name), getattr(plain, name))
            ]
            if probe.point_masses != plain.point_masses:
                changed.append("point_masses")
            if probe.discrete != plain.discrete:
                changed.append("discrete elements")
            if changed:
                raise ValueError(
                    f"effect {eff.name!r} ({type(eff).__name__}) does not fit the modal ROM: it "
                    f"changes {', '.join(changed)} of the system, while the ROM carries only "
                    "effects that bow the reference geometry (node_y); use fe.BeamModel for it"
                )
        return model

    @cached_property
    def rig_matrices(self) -> RigMatrices:
        """The transverse FE matrices (assembled once per model)."""
        rig = self.rig
        model = self._fe_model
        x = model.node_x
        le = np.diff(x)
        m, k, g = (_assemble(a) for a in _element_matrices(le, rig.mass_per_length, rig.EI))
        free = slice(2, -2)  # clamp at the bottom; top transverse and rotation held
        m, k, g = (a[free, free] for a in (m, k, g))
        linv = scipy.linalg.solve_triangular(np.linalg.cholesky(m), np.eye(m.shape[0]), lower=True)
        kt = linv @ k @ linv.T
        gt = linv @ g @ linv.T
        # buckling: K / lam^2 = P G / lam with lam = 1 - P / EA, i.e. P lam = P0
        p0 = float(scipy.linalg.eigh(kt, gt, eigvals_only=True, subset_by_index=[0, 0])[0])
        p_cr = 2.0 * p0 / (1.0 + math.sqrt(1.0 - 4.0 * p0 / rig.EA))
        shaker = self._dof_weights(x, rig.shaker_position_m)
        return RigMatrices(
            node_x=x,
            mass=m,
            bending=k,
            geometric=g,
            chol_inv=linv,
            bending_t=kt,
            geometric_t=gt,
            shaker=shaker,
            bow=self._bow_vector(x),
            buckling_load=p_cr,
        )

    def _bow_vector(self, node_x: np.ndarray) -> np.ndarray:
        """g0_j = int w0' N_j' dx on the free transverse dofs (zeros without effects).

        w0 comes from the effects' reference geometry (``node_y``) on a mesh
        BOW_REFINEMENT times finer, taken piecewise linear there, so that
        int_k w0' N_j' dx = slope_k (N_j(x_k+1) - N_j(x_k)) is exact; the
        polygon's O(h^2) error is 256 times smaller on the fine grid than on the
        ROM's mesh, i.e. mesh-converged (the full FE carries the bow as cubics,
        O(h^4), and agrees: see tests/test_rom.py).
        """
        if not self.effects:
            return np.zeros(2 * node_x.size - 4)
        fine = BeamModel(rig=self.rig, n_elements=BOW_REFINEMENT * self.n_elements, effects=self.effects)
        xf = fine.node_x
        slope = np.diff(fine.describe(Parameters()).node_y) / np.diff(xf)
        values = np.array([self._dof_weights(node_x, xk) for xk in xf])  # N_j(x_k)
        return slope @ np.diff(values, axis=0)

    @staticmethod
    def _dof_weights(node_x: np.ndarray, position: float) -> np.ndarray:
        """Weights on the free transverse dofs giving w(position) (cubic Hermite)."""
        w = hermite_weights(node_x, float(position)).reshape(-1, 3)[:, 1:].ravel()
        return w[2:-2]

    @property
    def node_x(self) -> np.ndarray:
        """Node positions of the FE mesh the shapes live on [m]."""
        return self.rig_matrices.node_x

    def buckling_load(self) -> float:
        """Linear buckling load of the straight beam [N] (the tangent's, with the
        axis shortened by the load, as the full FE)."""
        return self.rig_matrices.buckling_load

    def modal_analysis(self, params: Parameters, n_modes: int | None = None):
        """Modes of the full FE the ROM is built on (its ``n_elements`` mesh),
        linearised about the preloaded state; ``n_modes`` defaults to the ROM's."""
        return self._fe_model.modal_analysis(params, self.n_modes if n_modes is None else n_modes)

    # ------------------------------------------------ per-parameter precompute
    def _check_params(self, params: Parameters) -> float:
        if not isinstance(params, Parameters):
            raise TypeError("params must be an fe.Parameters")
        return check_below_buckling(params, self.rig, self.buckling_load())

    def reduced(self, params: Parameters) -> ReducedSystem:
        """The reduced matrices at the preload of ``params`` (cached per P_eff)."""
        p_eff = self._check_params(params)
        hit = self._cache.get(p_eff)
        if hit is not None:
            return hit
        rm = self.rig_matrices
        n = self.n_modes
        lam = 1.0 - p_eff / self.rig.EA
        with _one_blas_thread():
            w2, y = scipy.linalg.eigh(rm.bending_t / lam**2 - p_eff / lam * rm.geometric_t, subset_by_index=[0, n - 1])
            phi = rm.chol_inv.T @ y  # mass-normalised preloaded modes
            kappa, rot = np.linalg.eigh(phi.T @ rm.bending @ phi / lam**2)
        phi = phi @ rot
        wdofs = phi[0::2]  # deterministic signs: largest transverse displacement positive
        phi = phi * np.sign(wdofs[np.argmax(np.abs(wdofs), axis=0), np.arange(n)])
        red = ReducedSystem(
            p_eff=p_eff,
            stretch=lam,
            omega=np.sqrt(np.maximum(w2, 0.0)),
            shapes=phi,
            kappa=kappa,
            G=phi.T @ rm.geometric @ phi / lam,
            g0=phi.T @ rm.bow / lam,
            b=phi.T @ rm.shaker,
        )
        if len(self._cache) >= _CACHE_SIZE:
            self._cache.pop(next(iter(self._cache)))
        self._cache[p_eff] = red
        return red

    def cache_clear(self) -> None:
        """Forget the per-preload precomputation (e.g. to time it)."""
        self._cache.clear()

    def _output_weights(self, red: ReducedSystem, positions: np.ndarray) -> np.ndarray:
        """Rows phi_i(x) of the output positions (cached with the basis)."""
        key = positions.tobytes()
        w = red.outputs.get(key)
        if w is None:
            w = np.array([self._dof_weights(self.node_x, p) for p in positions]) @ red.shapes
            w = red.outputs[key] = np.ascontiguousarray(w)
        return w
