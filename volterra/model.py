"""VolterraModel: a Volterra model of orders 1-3 in a Kautz basis (fitted by :mod:`volterra.fit`).

Conventions (see ``docs/design.md``, section "Kautz basis: form and conventions"):

* ``y(k) = h0 + y1(k) + y2(k) + y3(k)``, y_n with NO 1/n! factor; h0 is the
  zeroth-order term, a constant [y unit] (e.g. an offset of the output
  sensor), fitted by default and kept out of the components.  The mean that an
  even-order term puts in the output (``a2 E[x^2]`` for ``y = x + a2 x^2``)
  belongs to y2, not to h0.
* Coefficients are stored per ordered index tuple (``i1 <= i2 <= i3``,
  0-based): ``B2[i, j]`` multiplies ``l_i l_j``, ``B3[i, j, m]`` multiplies
  ``l_i l_j l_m``.
* Symmetric kernels are averages over argument permutations: the symmetric
  coefficient of any ordering p of an index tuple is ``B[sorted p] / mult``
  with mult = 1 / 2 for (i,i) / (i,j) and 1 / 3 / 6 for (i,i,i) / (i,i,j) /
  (i,j,m).  Then ``h2(n1, n2) = sum_ij C2[i,j] psi_i(n1) psi_j(n2)`` and
  ``H2(f1, f2) = sum_ij C2[i,j] Psi_i(f1) Psi_j(f2)``, with
  ``H(f) = sum_n h(n) exp(-j 2 pi f n / fs)`` (f in Hz, n in samples).

What this model can and cannot represent
----------------------------------------
Sums of products of one-variable Kautz functions are separable.  The true
third-order kernel of a Duffing oscillator, ``-k3 H1(f1) H1(f2) H1(f3)
H1(f1 + f2 + f3)``, has a resonant ridge on the plane ``f1 + f2 + f3 = +-fn``;
in time its diagonal decays like ``|Z|^n`` while every product of three Kautz
functions decays like ``|Z|^(3n)``.  The ridge is NOT representable.  Measured
(fn = 30 Hz, zeta = 0.01; ``benchmarks/bench_volterra.py``, test module
``tests/test_volterra_oscillators.py``):

* even the l2-optimal approximation of the exact kernel (no data, no noise)
  misses H3 at (fn-2, fn+2, -fn) and (fn-5, fn+5, -fn) by 73-88 % for every
  J3 from 4 to 16, and captures only 77 / 88 / 92 / 97 % of the kernel energy
  at J3 = 4 / 6 / 8 / 16 (it does converge at the triple peak (fn, fn, -fn));
* identified from chirp records (J = (2, 2, 6), y3/y1 = 10 %, 40 dB), H3 on
  the ridge is off by 63 % to 4200 %, although y3 in the time domain matches
  the order-3 term of the perturbation hierarchy to 9 %;
* likewise H2 at pairs with f1 + f2 = fn (quadratic oscillator) is off by
  ~100 %.

What IS reliable: H1 (0.2-0.3 % near resonance); H2 at (f, -f) (sum near DC,
0.5-3 %); H2/H3 of systems whose kernels are products of in-span filters
(Wiener systems, < 0.3 %); the time-domain components y1 and y3 at moderate
nonlinearity (y3 within ~10 % of the hierarchy at y3/y1 <= 10 %).  For a
strongly nonlinear record (orders above 3 are 8-18 % of y3 already at
y3/y1 = 10 % and 25-55 % at 30 %), y2 and y3 are "the order-2 and order-3 parts
of a truncated fit in this basis", NOT the true Volterra components: compare
like with like (same basis, orders and input for reference and model), and
do not read pointwise H2/H3 as physical kernels.
"""

from __future__ import annotations

import math
from itertools import permutations

import numpy as np

from ._validation import as_record_list, paired_records
from .basis import KautzBasis
from .regressors import _block_rows, index_tuples

__all__ = ["VolterraModel"]


def _finite(value, name: str) -> float:
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return value


def _coefficient_blocks(orders, basis):
    start = 0
    blocks = {}
    for n in orders:
        p = basis.n_terms(n)
        blocks[n] = slice(start, start + p)
        start += p
    return blocks


class VolterraModel:
    """A discrete-time Volterra model of orders 1..3 in a Kautz basis.

    ``y = h0 + y1 + y2 + y3`` with ``y_n = H_n[u - input_offset]``.
    Usually obtained from :func:`fit_volterra`; can also be built directly from
    coefficients (flat vector in the column order of
    :meth:`KautzBasis.labels`).

    Parameters
    ----------
    basis : KautzBasis
    coefficients : array_like, shape (P,)
    orders : iterable of int, optional
        Orders the coefficients belong to (default: all orders of ``basis``).
    info : volterra.FitInfo, optional
        Fit diagnostics (set by :func:`volterra.fit_volterra`).
    h0 : float
        Zeroth-order term [y unit], default 0.
    input_offset : float
        Subtracted from every input before filtering [u unit], default 0.

    See the module docstring for what the kernels of this model can and cannot
    represent.
    """

    def __init__(
        self, basis: KautzBasis, coefficients, orders=None, info=None, h0: float = 0.0, input_offset: float = 0.0
    ):
        if not isinstance(basis, KautzBasis):
            raise ValueError(f"basis must be a KautzBasis, got {type(basis).__name__}")
        self.orders = basis._check_orders(orders)
        self.basis = basis.subset(self.orders)
        coef = np.asarray(coefficients, dtype=float).ravel()
        if coef.size != self.basis.n_params:
            raise ValueError(
                f"expected {self.basis.n_params} coefficients for orders {self.orders} "
                f"(J = {self.basis.n_functions} per mode), got {coef.size}"
            )
        self.coefficients = coef
        self.info = info
        self.h0 = _finite(h0, "h0")
        self.input_offset = _finite(input_offset, "input_offset")
        self._blocks = _coefficient_blocks(self.orders, self.basis)
        self._sym_cache = {}

    # ----------------------------------------------------------- coefficients
    @property
    def fs(self) -> float:
        """Sampling rate [Hz]."""
        return self.basis.fs

    @property
    def labels(self) -> list:
        """(order, index tuple) of each coefficient."""
        return self.basis.labels()

    def coefficients_of(self, order: int) -> np.ndarray:
        """Flat coefficients of one order (index tuples in lexicographic order)."""
        if order not in self._blocks:
            raise ValueError(f"order {order} was not fitted (orders {self.orders})")
        return self.coefficients[self._blocks[order]]

    def stderr_of(self, order: int) -> np.ndarray:
        """Standard errors of the coefficients of one order (needs a fit)."""
        if self.info is None:
            raise ValueError("this model was not fitted: no standard errors")
        if order not in self._blocks:
            raise ValueError(f"order {order} was not fitted (orders {self.orders})")
        return self.info.stderr[self._blocks[order]]

    def _dense(self, order: int) -> np.ndarray | None:
        if order not in self._blocks:
            return None
        J = self.basis.dim(order)
        out = np.zeros((J,) * order)
        idx = index_tuples(order, J)
        out[tuple(idx.T)] = self.coefficients_of(order)
        return out

    @property
    def B1(self):
        """Order-1 coefficients, shape (J1,), or None if order 1 was not fitted."""
        return self._dense(1)

    @property
    def B2(self):
        """Order-2 coefficients, shape (J2, J2), upper triangular (``B2[i, j]``,
        i <= j, multiplies ``l_i l_j``); None if order 2 was not fitted."""
        return self._dense(2)

    @property
    def B3(self):
        """Order-3 coefficients, shape (J3, J3, J3), non-zero only for
        i <= j <= m; None if order 3 was not fitted."""
        return self._dense(3)

    def symmetric_coefficients(self, order: int) -> np.ndarray:
        """Symmetric coefficient tensor C_n (shape (J,)*n): ``C[p] = B[sorted p] / mult``."""
        if order not in self._blocks:
            raise ValueError(f"order {order} was not fitted (orders {self.orders})")
        if order not in self._sym_cache:
            J = self.basis.dim(order)
            C = np.zeros((J,) * order)
            for t, b in zip(index_tuples(order, J), self.coefficients_of(order)):
                perms = set(permutations(tuple(int(i) for i in t)))
                for p in perms:
                    C[p] = b / len(perms)
            self._sym_cache[order] = C
        return self._sym_cache[order]

    # -------------------------------------------------------------- responses
    def _components_one(self, u: np.ndarray) -> tuple:
        rows = self.basis._filter_rows(u - self.input_offset)
        out = []
        for n in (1, 2, 3):
            if n in self._blocks:
                block = np.empty((self._blocks[n].stop - self._blocks[n].start, u.shape[-1]))
                _block_rows(rows[n], n, block)
                out.append(self.coefficients_of(n) @ block)
            else:
                out.append(np.zeros(u.shape[-1]))
        return tuple(out)

    def components(self, u, include_h0: bool = False):
        """Components ``(y1, y2, y3)`` of the response to input ``u``.

        ``u``: 1-D array (N samples at ``fs`` Hz, starting at rest) -> tuple of
        three arrays of N samples (zeros for an order not in the model); a list
        of records -> list of such tuples.  With ``include_h0`` the tuples are
        ``(y0, y1, y2, y3)``, ``y0`` the constant h0 on N samples.
        """
        records, single = as_record_list(u, "u")
        comps = [self._components_one(r) for r in records]
        if include_h0:
            comps = [(np.full(r.size, self.h0),) + c for r, c in zip(records, comps)]
        return comps[0] if single else comps

    def _predict_one(self, u: np.ndarray) -> np.ndarray:
        return self.h0 + sum(self._components_one(u))

    def predict(self, u):
        """Model output ``h0 + y1 + y2 + y3`` for input ``u`` (1-D array or list of records)."""
        records, single = as_record_list(u, "u")
        out = [self._predict_one(r) for r in records]
        return out[0] if single else out

    def relative_error(self, u, y) -> float:
        """``||y - predict(u)|| / ||y||`` over all records."""
        us, ys, _ = paired_records(u, y)
        num = sum(float(np.sum((yy - self._predict_one(uu)) ** 2)) for uu, yy in zip(us, ys))
        den = sum(float(np.sum(yy**2)) for yy in ys)
        return math.sqrt(num / den)

    # -------------------------------------------------- time-domain kernels
    def h1(self, n_samples: int) -> np.ndarray:
        """First-order kernel ``h1(n)``, n = 0 .. n_samples-1 [samples]."""
        psi = self.basis.impulse_responses(1, n_samples)
        return psi @ self.coefficients_of(1)

    def h2(self, n_samples: int) -> np.ndarray:
        """Symmetric second-order kernel ``h2(n1, n2)``: shape (n_samples, n_samples)."""
        psi = self.basis.impulse_responses(2, n_samples)
        return psi @ self.symmetric_coefficients(2) @ psi.T

    def h3_slice(self, n3: int, n_samples: int) -> np.ndarray:
        """Slice ``h3(n1, n2, n3)`` of the symmetric third-order kernel at fixed
        lag ``n3`` [samples]: shape (n_samples, n_samples)."""
        n3 = int(n3)
        if n3 < 0:
            raise ValueError(f"lag n3 must be >= 0, got {n3}")
        psi = self.basis.impulse_responses(3, max(n_samples, n3 + 1))
        C = self.symmetric_coefficients(3)
        p = psi[:n_samples]
        return np.einsum("ijk,ai,bj,k->ab", C, p, p, psi[n3], optimize=True)

    def h3(self, n_samples: int) -> np.ndarray:
        """Full symmetric third-order kernel, shape (n_samples,)*3 (keep n_samples small)."""
        psi = self.basis.impulse_responses(3, n_samples)
        return np.einsum("ijk,ai,bj,ck->abc", self.symmetric_coefficients(3), psi, psi, psi, optimize=True)

    # --------------------------------------------- frequency-domain kernels
    def H1(self, f_hz):
        """``H1(f) = sum_n h1(n) exp(-j 2 pi f n / fs)``, f in Hz (array ok)."""
        return self.basis.frequency_response(1, f_hz) @ self.coefficients_of(1)

    def H2(self, f1_hz, f2_hz):
        """Symmetric ``H2(f1, f2)`` [Hz arguments, broadcast together].

        Reliable at (f, -f) (sum near DC); not near f1 + f2 = +-fn of a
        resonant system (see the module docstring)."""
        f1, f2 = np.broadcast_arrays(np.asarray(f1_hz, float), np.asarray(f2_hz, float))
        P1 = self.basis.frequency_response(2, f1)
        P2 = self.basis.frequency_response(2, f2)
        return np.einsum("...i,...j,ij->...", P1, P2, self.symmetric_coefficients(2))

    def H3(self, f1_hz, f2_hz, f3_hz):
        """Symmetric ``H3(f1, f2, f3)`` [Hz arguments, broadcast together].

        Not a reliable pointwise estimate near the ridge f1 + f2 + f3 = +-fn of
        a resonant system: the basis cannot represent it (errors of 50 % to
        several 100 % measured; see the module docstring)."""
        f1, f2, f3 = np.broadcast_arrays(*(np.asarray(f, float) for f in (f1_hz, f2_hz, f3_hz)))
        P1, P2, P3 = (self.basis.frequency_response(3, f) for f in (f1, f2, f3))
        return np.einsum("...i,...j,...k,ijk->...", P1, P2, P3, self.symmetric_coefficients(3), optimize=True)

    # ----------------------------------------------------------------- report
    def summary(self, max_terms: int = 8) -> str:
        """A readable text summary: basis, h0, fit diagnostics, component shares,
        H1 peak and the largest coefficients of each order."""
        info = self.info
        lines = ["Volterra model in a Kautz basis (y = h0 + y1 + y2 + y3, no 1/n! factor)"]
        lines.append(f"  sampling rate {self.fs:g} Hz, orders {self.orders}, {self.basis.n_params} coefficients")
        h0 = f"  h0 = {self.h0:.6e}"
        if info is not None and np.isfinite(info.h0_stderr):
            h0 += f"  +- {info.h0_stderr:.2e}"
        elif info is not None:
            h0 += " (not fitted)"
        lines.append(h0)
        if self.input_offset:
            lines.append(f"  input offset {self.input_offset:.6e} subtracted from u")
        for n in self.orders:
            ft = ", feed-through" if self.basis.has_feedthrough(n) else ""
            poles = "; ".join(f"f = {p.freq_hz:.4f} Hz, zeta = {p.damping_ratio:.5f}" for p in self.basis.modes(n))
            lines.append(
                f"  order {n}: J = {self.basis.n_functions[n]}{ft}, {self.basis.n_terms(n)} terms, pole {poles}"
            )
        if info is not None:
            lines.append(
                f"  fit: {info.n_records} record(s), {info.n_samples} samples, rank {info.rank}/"
                f"{info.n_params}, condition number {info.condition_number:.3g} (column-normalised), "
                f"ridge {info.ridge:g}"
            )
            lines.append(
                f"  residual: rms {info.residual_rms:.4g}, relative {100 * info.relative_residual:.3f} % of ||y||"
            )
            shares = ", ".join(f"||y{n}||/||y|| = {100 * s:.3g} %" for n, s in info.component_shares.items())
            lines.append(f"  components on the fitted data: {shares}")
        if 1 in self.orders:
            f = np.linspace(0.0, self.fs / 2, 8193)
            H = np.abs(self.H1(f))
            k = int(np.argmax(H))
            lines.append(f"  |H1| peak {H[k]:.4g} at {f[k]:.3f} Hz")
        for n in self.orders:
            b = self.coefficients_of(n)
            se = self.stderr_of(n) if info is not None else None
            idx = index_tuples(n, self.basis.dim(n))
            order_idx = np.argsort(-np.abs(b))[:max_terms]
            more = f", largest {len(order_idx)}" if b.size > max_terms else ""
            lines.append(f"  B{n} ({b.size} terms{more}):")
            for k in order_idx:
                name = f"B{n}[{','.join(str(int(i)) for i in idx[k])}]"
                s = f"    {name:<12s} = {b[k]: .6e}"
                if se is not None:
                    s += f"  +- {se[k]:.2e}"
                lines.append(s)
        if any(n > 1 for n in self.orders):
            lines.append(
                "  note: y2, y3 are the order-2/3 parts of a truncated fit in this basis; H2/H3 near "
                "f1+f2(+f3) = fn are not representable (see volterra.model docs)."
            )
        return "\n".join(lines)

    def __repr__(self):
        return f"VolterraModel(orders={self.orders}, n_functions={self.basis.n_functions}, fs={self.fs:g} Hz)"
