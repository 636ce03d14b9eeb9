"""KautzBasis: the Kautz functions used for each kernel order of a Volterra model.

A basis is fixed once per data set (poles and numbers of functions J per
order) and reused for every record that has to be compared: the reference
(measured) response and each model response are expanded in the same basis,
so that their components y1, y2, y3 are comparable.

Default numbers of functions, ``DEFAULT_N_FUNCTIONS = (2, 2, 6)``
------------------------------------------------------------------
Chosen from the measured trade-off (``docs/kautz_basis_study.md``):

* J1 = 2 when the pole is accurate (within about 0.1 zeta fn of the linearised
  mode: the FE modal analysis of the model itself, or a pole refined on a
  low-level record).  H1 error near resonance 0.3-0.7 %.  Crucially, a small
  J1 keeps the amplitude-dependent (cubic) frequency shift out of y1: on a
  chirp with y3/y1 = 10 % the H1 error is 0.3 % at J = (2, 6) but 4.9 % at
  (4, 4) and 12 % at (8, 4), because a rich linear basis fits part of the
  nonlinear response with a linear kernel.
* J1 = 2 is fragile when the pole is off: a pole frequency off by
  0.25 zeta fn costs 13-17 % on H1 (J1 = 4: 2-2.5 %, J1 = 8: 0.3-0.4 %).
  If the pole is uncertain and the record is linear (low level), use J1 = 8
  (``ROBUST_LINEAR_N_FUNCTIONS``) and check the residual, or refine the pole
  with :func:`volterra.refine_pole`.
* J2 = 2: H2 of a quadratic oscillator at (f, -f) near resonance within
  0.5-3 %; J2 = 4 gained nothing there and made H2 at (fn, fn) worse
  (27 % against 8 %).
* J3 = 6: the order-3 component of a Duffing chirp response (y3/y1 = 10 %) is
  within 9 % of the perturbation hierarchy (J3 = 4: 17-28 %, and H1 from a
  single 10 % record degrades from 0.3 % to 2.7 %); condition numbers about
  2e3 on a chirp (J3 = 4: ~20; J3 = 8: 1e6 and more, avoid).

Numbers from ``tests/test_volterra_oscillators.py`` and the planning study
(fn = 30 Hz, zeta = 0.01, chirp 20-50 Hz + free decay, 40 dB noise).
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from .kautz import (
    KautzPole,
    _check_n_functions,
    _kautz_filter_rows,
    kautz_frequency_response,
    kautz_impulse_responses,
)
from .regressors import index_tuples, n_terms, regressor_matrix, regressor_rows

__all__ = ["KautzBasis", "DEFAULT_N_FUNCTIONS", "ROBUST_LINEAR_N_FUNCTIONS", "MAX_ORDER"]

#: Default J per order (orders 1, 2, 3); see the module docstring for why.
DEFAULT_N_FUNCTIONS = (2, 2, 6)
#: J for a linear-only fit when the pole is not accurately known.
ROBUST_LINEAR_N_FUNCTIONS = (8,)
#: Highest kernel order supported.
MAX_ORDER = 3


def _normalise_n_functions(n_functions) -> dict:
    if isinstance(n_functions, Mapping):
        items = list(n_functions.items())
    elif isinstance(n_functions, (int, np.integer)) and not isinstance(n_functions, bool):
        items = [(1, n_functions)]
    elif isinstance(n_functions, Sequence) and not isinstance(n_functions, str):
        items = list(enumerate(n_functions, start=1))
    else:
        raise ValueError(
            "n_functions must be a tuple (J1, J2, J3), a dict {order: J} or an int (order 1 only); "
            f"got {n_functions!r}"
        )
    out = {}
    for order, J in items:
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or not 1 <= order <= MAX_ORDER:
            raise ValueError(f"kernel orders must be integers 1..{MAX_ORDER}, got {order!r}")
        if J is None or (not isinstance(J, bool) and isinstance(J, (int, np.integer)) and J == 0):
            continue  # order omitted
        try:
            out[int(order)] = _check_n_functions(J)
        except ValueError as exc:
            raise ValueError(f"order {order}: {exc}") from None
    if not out:
        raise ValueError(f"no kernel order selected by n_functions = {n_functions!r}")
    return dict(sorted(out.items()))


def _per_order(value, orders, name):
    """Spread a scalar / sequence (aligned with orders 1..) / dict over ``orders``."""
    if isinstance(value, np.ndarray):
        value = value.item() if value.ndim == 0 else list(value)
    if isinstance(value, Mapping):
        missing = [n for n in orders if n not in value]
        if missing:
            raise ValueError(f"{name}: no entry for order(s) {missing}")
        return {n: value[n] for n in orders}
    if isinstance(value, Sequence) and not isinstance(value, str):
        if len(value) < max(orders):
            raise ValueError(
                f"{name}: a sequence must give one entry per order 1..{max(orders)}, got {len(value)}"
            )
        return {n: value[n - 1] for n in orders}
    return {n: value for n in orders}


class KautzBasis:
    """Kautz functions per kernel order: a pole and an (even) number J each.

    Parameters
    ----------
    poles : KautzPole, dict {order: KautzPole} or sequence aligned with orders 1..3
        One pole for all orders, or a separate pole per order.
    n_functions : tuple (J1, J2, J3), dict {order: J} or int
        Number of Kautz functions per order; each J must be even.  A zero or
        ``None`` entry omits that order (``(2, 0, 6)`` selects orders 1 and 3);
        an int selects order 1 only.

    Examples
    --------
    >>> basis = KautzBasis.from_modal(freq_hz=37.0, damping_ratio=0.01, fs=1024.0,
    ...                               n_functions=(2, 2, 6))
    >>> basis.orders, basis.n_params
    ((1, 2, 3), 61)
    """

    def __init__(self, poles, n_functions=DEFAULT_N_FUNCTIONS):
        nf = _normalise_n_functions(n_functions)
        orders = tuple(nf)
        if isinstance(poles, KautzPole):
            pole_map = {n: poles for n in orders}
        else:
            pole_map = _per_order(poles, orders, "poles")
        for n, p in pole_map.items():
            if not isinstance(p, KautzPole):
                raise ValueError(
                    f"pole for order {n} must be a KautzPole (use KautzPole.from_modal / from_z), got {p!r}"
                )
        fs_set = {p.fs for p in pole_map.values()}
        if len(fs_set) != 1:
            raise ValueError(f"all poles must share one sampling rate, got {sorted(fs_set)} Hz")
        self._n_functions = nf
        self._poles = pole_map
        self._fs = fs_set.pop()

    # ----------------------------------------------------------- constructors
    @classmethod
    def from_modal(cls, freq_hz, damping_ratio, fs: float, n_functions=DEFAULT_N_FUNCTIONS) -> "KautzBasis":
        """Basis from modal data.

        ``freq_hz`` [Hz] and ``damping_ratio`` [-] are scalars (one pole for
        every order) or per-order sequences (aligned with orders 1..3) or dicts
        {order: value}; ``fs`` is the sampling rate [Hz].
        """
        nf = _normalise_n_functions(n_functions)
        orders = tuple(nf)
        fr = _per_order(freq_hz, orders, "freq_hz")
        zr = _per_order(damping_ratio, orders, "damping_ratio")
        poles = {n: KautzPole.from_modal(fr[n], zr[n], fs) for n in orders}
        return cls(poles, nf)

    @classmethod
    def from_pole(cls, pole: KautzPole, n_functions=DEFAULT_N_FUNCTIONS) -> "KautzBasis":
        """Basis with the same pole for every order."""
        return cls(pole, n_functions)

    @classmethod
    def from_data(cls, u, y, fs: float, n_functions=DEFAULT_N_FUNCTIONS, f_range=None,
                  refine: bool = True) -> "KautzBasis":
        """Basis whose (common) pole is estimated from a low-level record.

        The pole comes from the peak and half-power width of an averaged H1
        FRF estimate (:func:`volterra.pole_from_frf`; records' means removed,
        peak searched in ``f_range``, default the band where ``u`` has energy,
        on coherent lines), then, if ``refine``, from minimising the residual
        of a linear fit with J1 = 2 inside a neighbourhood of that start
        (:func:`volterra.refine_pole`).  Use a record whose response is
        essentially linear.  Raises :class:`volterra.PoleEstimationError`
        rather than return a pole at DC or Nyquist, at a damping bound, or one
        whose linear fit explains too little of the record.
        """
        from .poles import pole_from_frf, refine_pole

        pole = pole_from_frf(u, y, fs, f_range=f_range)
        if refine:
            pole = refine_pole(u, y, pole, n_functions=(2,))
        return cls(pole, n_functions)

    # ------------------------------------------------------------- properties
    @property
    def orders(self) -> tuple:
        """Kernel orders of the basis, ascending."""
        return tuple(self._n_functions)

    @property
    def n_functions(self) -> dict:
        """{order: J}."""
        return dict(self._n_functions)

    @property
    def poles(self) -> dict:
        """{order: KautzPole}."""
        return dict(self._poles)

    @property
    def fs(self) -> float:
        """Sampling rate [Hz]."""
        return self._fs

    def pole(self, order: int) -> KautzPole:
        self._check_order(order)
        return self._poles[order]

    def n_terms(self, order: int) -> int:
        """Number of coefficients of one order."""
        self._check_order(order)
        return n_terms(order, self._n_functions[order])

    @property
    def n_params(self) -> int:
        """Total number of coefficients (regressors)."""
        return sum(self.n_terms(n) for n in self.orders)

    def labels(self, orders=None) -> list:
        """(order, index tuple) for each regressor column (0-based indices)."""
        orders = self._check_orders(orders)
        return [(n, tuple(int(i) for i in t)) for n in orders
                for t in index_tuples(n, self._n_functions[n])]

    def subset(self, orders) -> "KautzBasis":
        """The same basis restricted to some orders."""
        orders = self._check_orders(orders)
        return KautzBasis({n: self._poles[n] for n in orders},
                          {n: self._n_functions[n] for n in orders})

    # ------------------------------------------------------------- operations
    def filter(self, u, orders=None) -> dict:
        """Filter ``u`` (shape (..., N), samples at ``fs``) by the Kautz functions
        of each order: returns {order: array (..., N, J_order)}.  Orders sharing a
        pole are filtered once."""
        rows = self._filter_rows(u, orders)
        return {n: np.swapaxes(r, -1, -2) for n, r in rows.items()}

    def _filter_rows(self, u, orders=None) -> dict:
        """As :meth:`filter` with the function index before time: (..., J, N)."""
        orders = self._check_orders(orders)
        u = np.asarray(u, dtype=float)
        groups: dict = {}
        for n in orders:
            p = self._poles[n]
            groups.setdefault((p.z, p.fs), []).append(n)
        out = {}
        for members in groups.values():
            J = max(self._n_functions[n] for n in members)
            filtered = _kautz_filter_rows(u, self._poles[members[0]], J)
            for n in members:
                out[n] = filtered[..., : self._n_functions[n], :]
        return out

    def regressors(self, u, orders=None) -> np.ndarray:
        """Regressor matrix Gamma of ``u`` (shape (..., N)): (..., N, P)."""
        orders = self._check_orders(orders)
        u = np.asarray(u, dtype=float)
        if u.ndim == 1:
            return regressor_rows(self._filter_rows(u, orders), orders).T
        return regressor_matrix(self.filter(u, orders), orders)

    def regressor_rows(self, u, orders=None, out=None) -> np.ndarray:
        """Transposed regressor matrix Gamma^T (P, N) of one 1-D record ``u``
        (fast path used by the fit; writes into ``out`` if given)."""
        orders = self._check_orders(orders)
        return regressor_rows(self._filter_rows(u, orders), orders, out=out)

    def impulse_responses(self, order: int, n_samples: int) -> np.ndarray:
        """psi_i(n) of one order, n = 0 .. n_samples-1 [samples]: shape (n_samples, J)."""
        self._check_order(order)
        return kautz_impulse_responses(self._poles[order], self._n_functions[order], n_samples)

    def frequency_response(self, order: int, f_hz) -> np.ndarray:
        """Psi_i(f) of one order at frequencies ``f_hz`` [Hz]: shape f.shape + (J,)."""
        self._check_order(order)
        return kautz_frequency_response(self._poles[order], self._n_functions[order], f_hz)

    # ---------------------------------------------------------------- helpers
    def _check_order(self, order):
        if order not in self._n_functions:
            raise ValueError(f"order {order!r} is not in this basis (orders {self.orders})")

    def _check_orders(self, orders):
        if orders is None:
            return self.orders
        if isinstance(orders, (int, np.integer)):
            orders = (orders,)
        orders = tuple(sorted(set(int(n) for n in orders)))
        if not orders:
            raise ValueError("select at least one order")
        for n in orders:
            self._check_order(n)
        return orders

    def __eq__(self, other):
        if not isinstance(other, KautzBasis):
            return NotImplemented
        return self._n_functions == other._n_functions and self._poles == other._poles

    def __hash__(self):
        return hash((tuple(self._n_functions.items()), tuple(self._poles.items())))

    def describe(self) -> str:
        lines = [f"Kautz basis, fs = {self._fs:g} Hz, {self.n_params} regressors"]
        for n in self.orders:
            p = self._poles[n]
            lines.append(
                f"  order {n}: J = {self._n_functions[n]:2d} ({self.n_terms(n)} terms), pole "
                f"f = {p.freq_hz:.4f} Hz, zeta = {p.damping_ratio:.5f}, |Z| = {p.radius:.6f}"
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        parts = ", ".join(
            f"{n}: (J={self._n_functions[n]}, f={self._poles[n].freq_hz:.4g} Hz, "
            f"zeta={self._poles[n].damping_ratio:.4g})" for n in self.orders
        )
        return f"KautzBasis(fs={self._fs:g} Hz, {{{parts}}})"

    def settling_samples(self, tol: float = 1e-12) -> int:
        """Largest :meth:`KautzPole.settling_samples` over the orders' poles."""
        return max(p.settling_samples(tol) for p in self._poles.values())
