"""Generalized orthonormal basis functions (GOBF) over a sequence of poles.

Takenaka-Malmquist construction for real impulse responses (Ninness &
Gustafsson, IEEE TAC 42(4), 1997; Heuberger, Van den Hof & Wahlberg 2005):
the k-th pole of the sequence contributes its own one- or two-parameter
Kautz functions, multiplied by the all-pass factors of every pole before it::

    complex pair (Z, conj Z), Kautz parameters b_k, c_k (volterra.kautz):
        P_k(z)     = prod_{i<k} A_i(z)
        Psi_even   = sqrt((1 - c^2)(1 - b^2)) z / D_k(z) * P_k(z)
        Psi_odd    = (z - b) / sqrt(1 - b^2) * Psi_even
        A_k(z)     = (-c z^2 + b (c - 1) z + 1) / D_k(z)
    real pole a (0 < a < 1):
        Psi        = sqrt(1 - a^2) z / (z - a) * P_k(z)
        A_k(z)     = (1 - a z) / (z - a)

The functions of every pole are orthonormal among themselves and, through
the all-pass product, to those of every other pole of the sequence (l2 over
n = 0 .. infinity).  A pole may be repeated: repeating the whole sequence R
times gives R pairs per mode (the "more functions per pole" of the paper);
with a single repeated pole the set is exactly the two-parameter Kautz basis
of :mod:`volterra.kautz`.

Two forms, both orthonormal:

* ``feedthrough=False``: the functions above, which carry a one-sample
  advance (``psi(0) != 0``; today's Kautz convention).  2 functions per pair
  span ``(a + b z^-1) / D(z)``: NOT every proper second-order system.
* ``feedthrough=True`` (default of :class:`volterra.KautzBasis`): function 0
  is the unit impulse (the input itself, "feed-through"), followed by the
  functions above delayed by one sample (Wahlberg's strictly proper form,
  IEEE TAC 39(6), 1994).  1 + 2 K functions over K pairs span every proper
  ``(b0 + b1 z^-1 + ... + b_2K z^-2K) / prod D_k``, e.g. a second-order
  system sampled behind a zero-order hold ``(b1 z^-1 + b2 z^-2) / D`` or a
  linearly interpolated one ``(b0 + b1 z^-1 + b2 z^-2) / D``, exactly.  The
  impulse is orthogonal to the delayed functions (they vanish at n = 0).

Filtering is exact and recursive (``scipy.signal.lfilter``, zero initial
state: records start at rest); one second-order recursion per pair, never a
truncated convolution.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from .kautz import KautzPole, RealPole, _check_n_functions

__all__ = [
    "pole_sequence",
    "n_sequence_functions",
    "gobf_filter_rows",
    "gobf_frequency_response",
    "kautz_filter",
    "kautz_impulse_responses",
    "kautz_frequency_response",
]


def pole_sequence(modes, n_functions: int) -> tuple:
    """The pole sequence of ``n_functions`` (J, even) per mode: ``modes``
    repeated J / 2 times (a complex pair gives J functions, a real pole J / 2)."""
    modes = tuple(modes)
    return modes * (int(n_functions) // 2)


def n_sequence_functions(sequence, feedthrough: bool) -> int:
    """Number of functions of a pole sequence: 2 per complex pair, 1 per real
    pole, plus 1 for the feed-through."""
    return int(bool(feedthrough)) + sum(1 if isinstance(p, RealPole) else 2 for p in sequence)


def _section(p):
    """(den, allpass numerator, [(gain, first-difference coefficient, delay)] per function) of one pole."""
    if isinstance(p, RealPole):
        a = p.a
        return np.array([1.0, -a]), np.array([-a, 1.0]), [(math.sqrt(1.0 - a * a), 0.0, 0)]
    b, c = p.b, p.c
    k_odd = math.sqrt(1.0 - c * c)
    k_even = math.sqrt((1.0 - c * c) * (1.0 - b * b))
    # odd:  sqrt(1-c^2) (1 - b z^-1) / D;  even: sqrt((1-c^2)(1-b^2)) z^-1 / D
    return p.denominator(), p.allpass_numerator(), [(k_odd, b, 0), (k_even, 0.0, 1)]


def gobf_filter_rows(u, sequence, feedthrough: bool = True) -> np.ndarray:
    """Filter ``u`` (shape (..., N), samples) by the GOBF of a pole sequence.

    Returns shape (..., M, N), M = :func:`n_sequence_functions`; row 0 is
    ``u`` itself when ``feedthrough``.  Poles of a sequence must share one
    sampling rate (not checked here: :class:`volterra.KautzBasis` does).
    """
    u = np.asarray(u, dtype=float)
    sequence = tuple(sequence)
    M = n_sequence_functions(sequence, feedthrough)
    N = u.shape[-1]
    out = np.empty(u.shape[:-1] + (M, N))
    lag = 1 if feedthrough else 0  # the strictly proper form is the advanced one delayed
    row = 0
    if feedthrough:
        out[..., 0, :] = u
        row = 1
    r = None
    prev_num = None
    for p in sequence:
        den, num_a, funcs = _section(p)
        if r is None:
            r = lfilter([1.0], den, u, axis=-1)  # 1 / D_1 u
        else:
            r = lfilter(prev_num, den, r, axis=-1)  # A_{k-1} / D_k ... (all-passes so far)
        for gain, diff, delay in funcs:
            d = delay + lag
            dst = out[..., row, :]
            if d:
                dst[..., :d] = 0.0
            np.multiply(r[..., : N - d], gain, out=dst[..., d:])
            if diff:
                dst[..., d + 1 :] -= (diff * gain) * r[..., : N - d - 1]
            row += 1
        prev_num = num_a
    return out


def gobf_frequency_response(sequence, f_hz, fs: float, feedthrough: bool = True) -> np.ndarray:
    """Frequency responses ``Psi_i(exp(j 2 pi f / fs))`` of the GOBF of a pole
    sequence, f in Hz (``Psi(f) = sum_n psi(n) exp(-j 2 pi f n / fs)``).

    Returns a complex array of shape ``np.shape(f_hz) + (M,)``.
    """
    f = np.asarray(f_hz, dtype=float)
    z = np.exp(2j * np.pi * f / float(fs))
    sequence = tuple(sequence)
    M = n_sequence_functions(sequence, feedthrough)
    out = np.empty(f.shape + (M,), dtype=complex)
    shift = 1.0 / z if feedthrough else 1.0
    row = 0
    if feedthrough:
        out[..., 0] = 1.0
        row = 1
    P = np.ones_like(z)
    for p in sequence:
        if isinstance(p, RealPole):
            a = p.a
            out[..., row] = shift * math.sqrt(1.0 - a * a) * z / (z - a) * P
            P = P * (1.0 - a * z) / (z - a)
            row += 1
            continue
        b, c = p.b, p.c
        D = z * z + b * (c - 1.0) * z - c
        even = math.sqrt((1.0 - c * c) * (1.0 - b * b)) * z / D * P
        out[..., row] = shift * (z - b) / math.sqrt(1.0 - b * b) * even
        out[..., row + 1] = shift * even
        P = P * (-c * z * z + b * (c - 1.0) * z + 1.0) / D
        row += 2
    return out


# ------------------------------------------------ one pole: today's Kautz functions
def _kautz_filter_rows(u, pole: KautzPole, J: int) -> np.ndarray:
    """Today's Kautz functions of one pole (advanced form): shape (..., J, N)."""
    return gobf_filter_rows(u, (pole,) * (J // 2), feedthrough=False)


def kautz_filter(u, pole: KautzPole, n_functions: int) -> np.ndarray:
    """Filter ``u`` by the first ``n_functions`` Kautz functions of ``pole``.

    The two-parameter Kautz functions of one pole (the GOBF of the sequence
    ``(pole,) * (J / 2)`` without feed-through, advanced form, see the module
    docstring).  Exact recursive filtering from a zero initial state, along
    the last axis of ``u``.

    Parameters
    ----------
    u : array_like, shape (..., N)
        Input samples (any unit); N samples at ``pole.fs`` Hz.
    pole : KautzPole
    n_functions : int
        J, even.

    Returns
    -------
    ndarray, shape (..., N, J)
        ``l_i(k) = sum_n psi_i(n) u(k - n)`` for i = 0 .. J-1.
    """
    J = _check_n_functions(n_functions)
    return np.swapaxes(_kautz_filter_rows(u, pole, J), -1, -2)


def kautz_impulse_responses(pole: KautzPole, n_functions: int, n_samples: int) -> np.ndarray:
    """Sampled impulse responses ``psi_i(n)``, n = 0 .. n_samples-1: shape (n_samples, J)."""
    n = int(n_samples)
    if n <= 0:
        raise ValueError(f"n_samples must be positive, got {n_samples!r}")
    d = np.zeros(n)
    d[0] = 1.0
    return kautz_filter(d, pole, n_functions)


def kautz_frequency_response(pole: KautzPole, n_functions: int, f_hz) -> np.ndarray:
    """Frequency responses ``Psi_i(exp(j 2 pi f / fs))`` of the Kautz functions of
    one pole, f in Hz (negative frequencies allowed, ``Psi(-f) = conj Psi(f)``):
    shape ``np.shape(f_hz) + (J,)``."""
    J = _check_n_functions(n_functions)
    return gobf_frequency_response((pole,) * (J // 2), f_hz, pole.fs, feedthrough=False)
