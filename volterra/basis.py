"""KautzBasis: the orthonormal functions used for each kernel order of a Volterra model.

A basis is fixed once per data set (modes and numbers of functions J per
order) and reused for every record that has to be compared: the reference
(measured) response and each model response are expanded in the same basis,
so that their components y1, y2, y3 are comparable.

Each order has a sequence of modes (one :class:`~volterra.KautzPole` per
mode, a :class:`~volterra.RealPole` allowed) and J functions per mode
(:mod:`volterra.gobf`): the modes' sequence is repeated J / 2 times.  With
``feedthrough=True`` (default) the input itself is function 0 of every order,
so 1 + J1 M functions of order 1 span every proper rational transfer function
with those M modes' poles (numerator degree up to J1 M); orders 2 and 3 are
products of their order's functions, feed-through included.  With
``feedthrough=False`` and one mode the functions are exactly the Kautz
functions of :func:`volterra.kautz_filter` (with their one-sample advance).

Orders 2 and 3 usually take only the mode(s) that the nonlinear test excites
(:meth:`KautzBasis.from_modes` ``nonlinear_modes``; :meth:`from_data` keeps the
one with the largest response energy): C(J + n - 1, n) regressors per order
grow fast with the number of functions.

Default numbers of functions, ``DEFAULT_N_FUNCTIONS = (2, 2, 6)``
------------------------------------------------------------------
Chosen from the measured trade-off (``docs/kautz_basis_study.md``, numbers there):
J1 = 2 keeps the amplitude-dependent (cubic) frequency shift out of y1 when the
pole is accurate (a low-level record's, refined), and is fragile when it is off
(use ``ROBUST_LINEAR_N_FUNCTIONS`` on an uncertain pole and a linear record, or
refine it with :func:`volterra.refine_pole`); J2 = 2 gives H2 near resonance
within a few %, more made it worse; J3 = 6 follows a Duffing chirp's order-3
component within 9 % at condition numbers about 2e3 (J3 = 8: 1e6, avoid).  The
feed-through adds one function per order (93 regressors at (2, 2, 6) instead of
61): it helps H1 from stacked levels and hurts it from ONE constant-amplitude
chirp, where u^3 = 3/4 A^2 u + (third harmonic) nearly repeats the order-1
regressor: fit two or three levels jointly (as the framework does), or
``feedthrough=False``.
"""

from __future__ import annotations

import numpy as np

from ._validation import MAX_ORDER, _modes_of, _normalise_n_functions, _per_order
from .gobf import gobf_filter_rows, gobf_frequency_response, n_sequence_functions, pole_sequence
from .kautz import KautzPole, RealPole
from .modes import estimate_modes
from .polish import polish
from .regressors import index_tuples, n_terms, regressor_matrix, regressor_rows

__all__ = ["KautzBasis", "DEFAULT_N_FUNCTIONS", "ROBUST_LINEAR_N_FUNCTIONS", "MAX_ORDER"]

#: Default J per order (orders 1, 2, 3), per mode; see the module docstring for why.
DEFAULT_N_FUNCTIONS = (2, 2, 6)
#: J for a linear-only fit when the pole is not accurately known.
ROBUST_LINEAR_N_FUNCTIONS = (8,)
_POLE_TYPES = (KautzPole, RealPole)


class KautzBasis:
    """Orthonormal functions per kernel order: modes (poles), J per mode, feed-through.

    Parameters
    ----------
    poles : KautzPole, dict {order: pole(s)} or sequence aligned with orders 1..3
        One pole for all orders, or per order a pole or a sequence of poles
        (one per mode; a :class:`~volterra.RealPole` is allowed).  For the same
        modes at every order use :meth:`from_modes`.
    n_functions : tuple (J1, J2, J3), dict {order: J} or int
        Number of functions per mode and order; each J must be even (a
        mode's pair is repeated J / 2 times; a real pole gives J / 2
        functions).  A zero or ``None`` entry omits that order (``(2, 0, 6)``
        selects orders 1 and 3); an int selects order 1 only.
    feedthrough : bool or iterable of orders, default True
        Function 0 of every order (or of the orders listed, e.g. ``(1,)``) is
        the input itself and the others are delayed by one sample
        (:mod:`volterra.gobf`): any proper rational system with the modes'
        poles is in the order-1 span.  False: the advanced functions without
        it (today's Kautz functions for one mode).

    Examples
    --------
    >>> basis = KautzBasis.from_modal(freq_hz=37.0, damping_ratio=0.01, fs=1024.0,
    ...                               n_functions=(2, 2, 6))
    >>> basis.orders, basis.n_params
    ((1, 2, 3), 93)
    """

    def __init__(self, poles, n_functions=DEFAULT_N_FUNCTIONS, feedthrough=True):
        nf = _normalise_n_functions(n_functions)
        orders = tuple(nf)
        if isinstance(poles, _POLE_TYPES):
            pole_map = {n: poles for n in orders}
        else:
            pole_map = _per_order(poles, orders, "poles")
        pole_map = {n: _modes_of(p, n) for n, p in pole_map.items()}
        fs_set = {p.fs for modes in pole_map.values() for p in modes}
        if len(fs_set) != 1:
            raise ValueError(f"all poles must share one sampling rate, got {sorted(fs_set)} Hz")
        if isinstance(feedthrough, (bool, np.bool_)):
            ft_orders = set(orders) if feedthrough else set()
        else:
            try:
                ft_orders = {int(n) for n in feedthrough}
            except (TypeError, ValueError):
                raise ValueError(f"feedthrough must be True, False or orders, got {feedthrough!r}") from None
        self._n_functions = nf
        self._poles = pole_map
        self._fs = fs_set.pop()
        self._ft = {n: n in ft_orders for n in orders}

    # ----------------------------------------------------------- constructors
    @classmethod
    def from_modal(
        cls, freq_hz, damping_ratio, fs: float, n_functions=DEFAULT_N_FUNCTIONS, feedthrough=True
    ) -> "KautzBasis":
        """One-mode basis from modal data.

        ``freq_hz`` [Hz] and ``damping_ratio`` [-] are scalars (one pole for
        every order) or per-order sequences (aligned with orders 1..3) or dicts
        {order: value}; ``fs`` is the sampling rate [Hz].  Several modes:
        :meth:`from_modes` with ``KautzPole.from_modal`` poles.
        """
        nf = _normalise_n_functions(n_functions)
        orders = tuple(nf)
        fr = _per_order(freq_hz, orders, "freq_hz")
        zr = _per_order(damping_ratio, orders, "damping_ratio")
        poles = {n: KautzPole.from_modal(fr[n], zr[n], fs) for n in orders}
        return cls(poles, nf, feedthrough)

    @classmethod
    def from_pole(cls, pole, n_functions=DEFAULT_N_FUNCTIONS, feedthrough=True) -> "KautzBasis":
        """Basis with the same pole for every order."""
        return cls(pole, n_functions, feedthrough)

    @classmethod
    def from_modes(cls, modes, n_functions=DEFAULT_N_FUNCTIONS, feedthrough=True, nonlinear_modes=None) -> "KautzBasis":
        """Several modes: all of ``modes`` (a sequence of poles) at order 1.

        ``nonlinear_modes`` chooses the modes of orders 2 and 3: None (all),
        an int k (the first k of ``modes``: give them dominant first) or a
        sequence of indices into ``modes``.
        """
        modes = _modes_of(modes, 1)
        if nonlinear_modes is None:
            high = modes
        elif isinstance(nonlinear_modes, (int, np.integer)) and not isinstance(nonlinear_modes, bool):
            if not 1 <= nonlinear_modes <= len(modes):
                raise ValueError(f"nonlinear_modes = {nonlinear_modes} must be in 1..{len(modes)}")
            high = modes[: int(nonlinear_modes)]
        else:
            idx = [int(i) for i in nonlinear_modes]
            if not idx or any(not 0 <= i < len(modes) for i in idx):
                raise ValueError(f"nonlinear_modes {nonlinear_modes!r}: indices into {len(modes)} modes")
            high = tuple(modes[i] for i in idx)
        nf = _normalise_n_functions(n_functions)
        return cls({n: modes if n == 1 else high for n in nf}, nf, feedthrough)

    @classmethod
    def from_data(
        cls,
        u,
        y,
        fs: float,
        n_functions=DEFAULT_N_FUNCTIONS,
        f_range=None,
        refine: bool = True,
        *,
        n_modes=None,
        period_samples=None,
        feedthrough=True,
        nonlinear_modes=1,
        **options,
    ) -> "KautzBasis":
        """Basis of every mode :func:`volterra.estimate_modes` resolves in a
        low-level (essentially linear) record's excited, coherent band.

        LSCF fits of the FRF lines read on stabilisation diagrams, the modes
        that stand out of the noise kept, then (``refine``) the poles that
        minimise the residual of the modal fit (modes plus residual terms for
        those outside the band), then polished on the record's linear fit in
        the basis's own order-1 form (:mod:`volterra.polish`).  ``y``: (n,) or (n, n_sensors), the sensors
        share the poles; ``f_range`` [Hz] narrows the band; ``n_modes`` [-]
        overrides the count; ``period_samples`` [samples]: period of a periodic
        excitation (default: found in ``u`` when it repeats).  Modes
        come sorted by response energy, so :meth:`pole` is the dominant one;
        orders 2 and 3 get the first ``nonlinear_modes`` (default 1; None:
        all).  ``options`` go to :func:`volterra.estimate_modes`.  Raises
        :class:`volterra.PoleEstimationError` when no mode can be found.
        """
        est = estimate_modes(
            u, y, fs, f_range=f_range, n_modes=n_modes, refine=refine, period_samples=period_samples, **options
        )
        return cls.from_estimate(est, n_functions, feedthrough, nonlinear_modes, polished=refine)

    @classmethod
    def from_estimate(
        cls, estimate, n_functions=DEFAULT_N_FUNCTIONS, feedthrough=True, nonlinear_modes=1, polished: bool = True
    ) -> "KautzBasis":
        """Basis on the modes of a :class:`volterra.ModalEstimate` (what
        :meth:`from_data` builds once it has estimated them): the poles, then
        (``polished``) moved to those that serve the record's linear fit best in
        the basis's own order-1 form (:mod:`volterra.polish`); orders 2 and 3 on
        the first ``nonlinear_modes`` (None: all)."""
        poles = estimate.poles
        if polished:
            # the basis's own order-1 form: the poles it serves best, near the modal ones (volterra.polish)
            ft1 = bool(feedthrough) if isinstance(feedthrough, (bool, np.bool_)) else 1 in tuple(feedthrough)
            poles, _ = polish(estimate.lines, poles, ft1)
        return cls.from_modes(
            poles, n_functions, feedthrough, None if nonlinear_modes is None else min(nonlinear_modes, len(poles))
        )

    # ------------------------------------------------------------- properties
    @property
    def orders(self) -> tuple:
        """Kernel orders of the basis, ascending."""
        return tuple(self._n_functions)

    @property
    def n_functions(self) -> dict:
        """{order: J} as given (functions per mode, feed-through not counted);
        the number of functions of an order is :meth:`dim`."""
        return dict(self._n_functions)

    @property
    def poles(self) -> dict:
        """{order: tuple of poles}, one per mode (the dominant first when
        estimated by :meth:`from_data`)."""
        return dict(self._poles)

    @property
    def feedthrough(self):
        """True (function 0 of every order is the input itself), False (of
        none), or the tuple of orders that have it."""
        on = tuple(n for n, v in self._ft.items() if v)
        return True if len(on) == len(self._ft) else False if not on else on

    def has_feedthrough(self, order: int) -> bool:
        """Whether function 0 of ``order`` is the input itself."""
        self._check_order(order)
        return self._ft[order]

    @property
    def fs(self) -> float:
        """Sampling rate [Hz]."""
        return self._fs

    def pole(self, order: int):
        """The first pole of an order: the only one of a one-mode basis, the
        dominant mode of a basis from :meth:`from_data`."""
        self._check_order(order)
        return self._poles[order][0]

    def modes(self, order: int) -> tuple:
        """The poles of one order, one per mode."""
        self._check_order(order)
        return self._poles[order]

    def sequence(self, order: int) -> tuple:
        """The pole sequence of one order (its modes repeated J / 2 times)."""
        self._check_order(order)
        return pole_sequence(self._poles[order], self._n_functions[order])

    def dim(self, order: int) -> int:
        """Number of one-variable functions of an order [-] (feed-through included)."""
        return n_sequence_functions(self.sequence(order), self._ft[order])

    def n_terms(self, order: int) -> int:
        """Number of coefficients of one order: C(dim + n - 1, n)."""
        return n_terms(order, self.dim(order))

    @property
    def n_params(self) -> int:
        """Total number of coefficients (regressors)."""
        return sum(self.n_terms(n) for n in self.orders)

    def labels(self, orders=None) -> list:
        """(order, index tuple) for each regressor column (0-based function
        indices; with the feed-through, index 0 is the input itself)."""
        orders = self._check_orders(orders)
        return [(n, tuple(int(i) for i in t)) for n in orders for t in index_tuples(n, self.dim(n))]

    def subset(self, orders) -> "KautzBasis":
        """The same basis restricted to some orders."""
        orders = self._check_orders(orders)
        return KautzBasis(
            {n: self._poles[n] for n in orders},
            {n: self._n_functions[n] for n in orders},
            [n for n in orders if self._ft[n]],
        )

    # ------------------------------------------------------------- operations
    def filter(self, u, orders=None) -> dict:
        """Filter ``u`` (shape (..., N), samples at ``fs``) by the functions of
        each order: returns {order: array (..., N, dim(order))}.  Orders with
        the same modes are filtered once (a shorter sequence's functions are
        the first of a longer one's)."""
        rows = self._filter_rows(u, orders)
        return {n: np.swapaxes(r, -1, -2) for n, r in rows.items()}

    def _filter_rows(self, u, orders=None) -> dict:
        """As :meth:`filter` with the function index before time: (..., dim, N)."""
        orders = self._check_orders(orders)
        u = np.asarray(u, dtype=float)
        groups: dict = {}
        for n in orders:
            groups.setdefault((self._poles[n], self._ft[n]), []).append(n)
        out = {}
        for (modes, ft), members in groups.items():
            longest = max(members, key=lambda n: self._n_functions[n])
            filtered = gobf_filter_rows(u, self.sequence(longest), ft)
            for n in members:
                out[n] = filtered[..., : self.dim(n), :]
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
        """psi_i(n) of one order, n = 0 .. n_samples-1 [samples]: shape (n_samples, dim)."""
        n = int(n_samples)
        if n <= 0:
            raise ValueError(f"n_samples must be positive, got {n_samples!r}")
        d = np.zeros(n)
        d[0] = 1.0
        return gobf_filter_rows(d, self.sequence(order), self._ft[order]).T

    def frequency_response(self, order: int, f_hz) -> np.ndarray:
        """Psi_i(f) of one order at frequencies ``f_hz`` [Hz]: shape f.shape + (dim,)."""
        return gobf_frequency_response(self.sequence(order), f_hz, self._fs, self._ft[order])

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
        return self._n_functions == other._n_functions and self._poles == other._poles and self._ft == other._ft

    def __hash__(self):
        return hash((tuple(self._n_functions.items()), tuple(self._poles.items()), tuple(self._ft.items())))

    def describe(self) -> str:
        lines = [f"Kautz basis, fs = {self._fs:g} Hz, {self.n_params} regressors, feed-through {self.feedthrough}"]
        for n in self.orders:
            poles = ", ".join(f"f = {p.freq_hz:.4f} Hz, zeta = {p.damping_ratio:.5f}" for p in self._poles[n])
            lines.append(
                f"  order {n}: J = {self._n_functions[n]:2d} per mode, {self.dim(n)} functions "
                f"({self.n_terms(n)} terms), poles {poles}"
            )
        return "\n".join(lines)

    def __repr__(self) -> str:
        parts = ", ".join(
            f"{n}: (J={self._n_functions[n]}, "
            + "; ".join(f"f={p.freq_hz:.4g} Hz, zeta={p.damping_ratio:.4g}" for p in self._poles[n])
            + ")"
            for n in self.orders
        )
        return f"KautzBasis(fs={self._fs:g} Hz, feedthrough={self.feedthrough}, {{{parts}}})"

    def settling_samples(self, tol: float = 1e-12) -> int:
        """Largest ``settling_samples`` over the poles of every order [samples]."""
        return max(p.settling_samples(tol) for modes in self._poles.values() for p in modes)
