"""Regressor matrix of a Kautz-basis Volterra model (paper eq. 16-18).

For order n with J_n functions the regressors are products of filtered inputs
over ordered index tuples ``i1 <= i2 <= ... <= in`` (0-based here)::

    y1(k) = sum_i         B1[i]       l_i(k)
    y2(k) = sum_{i<=j}    B2[i,j]     l_i(k) l_j(k)
    y3(k) = sum_{i<=j<=m} B3[i,j,m]   l_i(k) l_j(k) l_m(k)

giving ``comb(J_n + n - 1, n)`` columns per order: J1 + J2 (J2+1)/2 +
J3 (J3+1)(J3+2)/6 in all.  Columns are ordered by order, then
lexicographically by index tuple (``itertools.combinations_with_replacement``).
"""

from __future__ import annotations

import math
from collections import Counter
from functools import lru_cache
from itertools import combinations_with_replacement

import numpy as np

__all__ = ["index_tuples", "multiplicity", "n_terms", "regressor_block", "regressor_matrix", "regressor_rows"]


@lru_cache(maxsize=None)
def _index_tuples(order: int, n_functions: int) -> np.ndarray:
    idx = np.array(list(combinations_with_replacement(range(n_functions), order)), dtype=np.intp)
    idx = idx.reshape(-1, order)
    idx.setflags(write=False)
    return idx


def index_tuples(order: int, n_functions: int) -> np.ndarray:
    """Ordered index tuples (0-based, non-decreasing) of one order: an int array
    of shape (n_terms(order, J), order)."""
    if order < 1:
        raise ValueError(f"order must be >= 1, got {order}")
    return _index_tuples(int(order), int(n_functions))


def n_terms(order: int, n_functions: int) -> int:
    """Number of regressors of one order: ``comb(J + n - 1, n)``."""
    return math.comb(int(n_functions) + int(order) - 1, int(order))


def multiplicity(index_tuple) -> int:
    """Number of distinct orderings of an index tuple: 1 / 2 for (i,i) / (i,j);
    1 / 3 / 6 for (i,i,i) / (i,i,j) / (i,j,m)."""
    t = tuple(int(i) for i in index_tuple)
    m = math.factorial(len(t))
    for cnt in Counter(t).values():
        m //= math.factorial(cnt)
    return m


def regressor_block(filtered: np.ndarray, order: int) -> np.ndarray:
    """Regressors of one order from filtered inputs ``filtered`` (shape (..., N, J)):
    returns shape (..., N, n_terms(order, J))."""
    filtered = np.asarray(filtered)
    idx = index_tuples(order, filtered.shape[-1])
    block = filtered[..., idx[:, 0]]
    for k in range(1, order):
        block = block * filtered[..., idx[:, k]]
    return block


def regressor_matrix(filtered: dict, orders) -> np.ndarray:
    """Stack the regressor blocks of ``orders`` (ascending) side by side.

    ``filtered[n]`` holds the inputs filtered by the Kautz functions of order n,
    shape (..., N, J_n).  Returns shape (..., N, P).
    """
    blocks = [regressor_block(filtered[n], n) for n in orders]
    return np.concatenate(blocks, axis=-1)


def _block_rows(LT: np.ndarray, order: int, out: np.ndarray) -> None:
    """Write the order-``order`` regressors of ``LT`` (shape (J, N)) into ``out``
    (shape (n_terms, N)), one vectorised product per index prefix."""
    J = LT.shape[0]
    if order == 1:
        out[:] = LT
        return
    k = 0
    for prefix in index_tuples(order - 1, J):
        p = LT[prefix[0]]
        for i in prefix[1:]:
            p = p * LT[i]
        last = int(prefix[-1])
        n = J - last
        np.multiply(p, LT[last:], out=out[k : k + n])
        k += n


def regressor_rows(filtered_rows: dict, orders, out: np.ndarray | None = None) -> np.ndarray:
    """Transposed regressor matrix Gamma^T (shape (P, N)) of ONE record.

    ``filtered_rows[n]`` holds the filtered inputs of order n with the function
    index first, shape (J_n, N).  Writes into ``out`` if given (any (P, N)
    array view, e.g. a slice of a larger stacked matrix).
    """
    P = sum(n_terms(n, filtered_rows[n].shape[0]) for n in orders)
    N = next(iter(filtered_rows.values())).shape[-1]
    if out is None:
        out = np.empty((P, N))
    k = 0
    for n in orders:
        p = n_terms(n, filtered_rows[n].shape[0])
        _block_rows(filtered_rows[n], n, out[k : k + p])
        k += p
    return out
