"""Banded matrix helpers (numba).

Storage: ``ab[i, kd + j - i] = A[i, j]`` for ``|i - j| <= kd`` (row-wise band,
``ab`` has shape (n, 2 kd + 1)).  The LU factorisation has no pivoting: the
matrices factored here (mass-dominated Newton matrices of the dynamic step and
the positive-definite tangent of a stable equilibrium) are diagonally strong.
A zero or tiny pivot is reported, never divided by.

No fastmath anywhere in ``fe``: with reassociation and contraction allowed,
a fresh compile and a cache load gave results differing in the last bits
(amplified to 1e-10 by a 4 s transient), which breaks the bit-for-bit
regeneration of the default data set; strict IEEE costs no measurable time.
"""

import numpy as np
from numba import njit


@njit(cache=True)
def band_lu(ab, kd):
    """In-place LU (Doolittle, no pivoting) of a banded matrix; the diagonal of
    the result holds the reciprocals of the pivots.  Returns the index of the
    first bad pivot, or -1 on success."""
    n = ab.shape[0]
    for k in range(n):
        piv = ab[k, kd]
        if not (abs(piv) > 1e-300) or not np.isfinite(piv):
            return k
        iend = min(n, k + kd + 1)
        for i in range(k + 1, iend):
            l = ab[i, kd + k - i] / piv
            ab[i, kd + k - i] = l
            if l != 0.0:
                for j in range(k + 1, iend):
                    ab[i, kd + j - i] -= l * ab[k, kd + j - k]
        ab[k, kd] = 1.0 / piv
    return -1


@njit(cache=True, error_model="numpy")
def band_solve(ab, kd, b):
    """Solve in place with the factors from :func:`band_lu`."""
    n = ab.shape[0]
    for i in range(n):
        s = b[i]
        for k in range(max(0, i - kd), i):
            s -= ab[i, kd + k - i] * b[k]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, min(n, i + kd + 1)):
            s -= ab[i, kd + j - i] * b[j]
        b[i] = s * ab[i, kd]


@njit(cache=True, error_model="numpy")
def band_matvec(ab, kd, x, out):
    """out = A x for a banded A."""
    n = ab.shape[0]
    for i in range(n):
        s = 0.0
        for j in range(max(0, i - kd), min(n, i + kd + 1)):
            s += ab[i, kd + j - i] * x[j]
        out[i] = s


def band_to_dense(ab, kd):
    """Dense copy of a banded matrix (for tests and modal analysis)."""
    n = ab.shape[0]
    a = np.zeros((n, n))
    for i in range(n):
        for j in range(max(0, i - kd), min(n, i + kd + 1)):
            a[i, j] = ab[i, kd + j - i]
    return a
