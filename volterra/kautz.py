"""Kautz orthonormal functions: poles, exact recursive filtering, frequency responses.

Two-parameter Kautz functions (Kautz 1954; Wahlberg, IEEE TAC 39(6), 1994;
the paper's eq. 14-15 as repaired in ``docs/design.md#kautz-basis-form-and-conventions``).  One pair of
complex-conjugate discrete poles ``(Z, conj Z)`` generates ``J`` (even)
functions::

    Z = exp(S / fs),  S = -zeta w + j w sqrt(1 - zeta^2)     (w in rad/s)
    b = (Z + conj Z) / (1 + Z conj Z),   c = -Z conj Z        (real, |b|, |c| < 1)
    D(z) = z^2 + b (c - 1) z - c  = (z - Z)(z - conj Z)
    A(z) = (-c z^2 + b (c - 1) z + 1) / D(z)                  (all-pass)

    Psi_{2g}(z)   = sqrt((1 - c^2)(1 - b^2)) z / D(z) * A(z)^(g-1)
    Psi_{2g-1}(z) = (z - b) / sqrt(1 - b^2) * Psi_{2g}(z),     g = 1 .. J/2

Function ``i`` (1-based in the formulas, 0-based in arrays) has the sampled
impulse response ``psi_i(n)``, n = 0, 1, ... samples; the set is orthonormal in
l2: ``sum_n psi_i(n) psi_j(n) = delta_ij`` (over a horizon long enough for
``|Z|^n`` to vanish; see :meth:`KautzPole.settling_samples`).  ``psi_1(0)`` is
not zero (a one-sample advance with respect to Wahlberg's form), which carries
the feed-through of a sampled system with a linearly interpolated input.

Inputs are filtered by the exact recursive filters (``scipy.signal.lfilter``,
zero initial state: every record is assumed to start at rest), never by a
truncated convolution.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
from scipy.signal import lfilter

__all__ = [
    "KautzPole",
    "kautz_impulse_responses",
    "kautz_filter",
    "kautz_frequency_response",
]


@dataclass(frozen=True)
class KautzPole:
    """A pair of complex-conjugate discrete poles ``(Z, conj Z)``.

    Parameters
    ----------
    z : complex
        Discrete pole (dimensionless), ``0 < |z| < 1``, not real.  The one in
        the lower half plane is replaced by its conjugate.
    fs : float
        Sampling rate in Hz (samples per second).

    Use :meth:`from_modal` (natural frequency in Hz, damping ratio) or
    :meth:`from_s` (continuous pole in rad/s) to build one from modal data.
    """

    z: complex
    fs: float

    def __post_init__(self):
        fs = float(self.fs)
        if not np.isfinite(fs) or fs <= 0:
            raise ValueError(f"sampling rate fs must be a positive number of Hz, got {self.fs!r}")
        z = complex(self.z)
        if not (np.isfinite(z.real) and np.isfinite(z.imag)):
            raise ValueError(f"pole z must be finite, got {self.z!r}")
        r = abs(z)
        if r >= 1.0:
            raise ValueError(
                f"unstable Kautz pole: |Z| = {r:.6g} >= 1 (Z = {z:.6g}); the Kautz filters "
                "would diverge. Use a pole inside the unit circle, i.e. a positive damping ratio."
            )
        if r == 0.0:
            raise ValueError("Kautz pole Z = 0 is not allowed: give a pole with 0 < |Z| < 1")
        if z.imag == 0.0:
            raise ValueError(
                f"real Kautz pole Z = {z.real:.6g}: this basis needs a complex-conjugate pair; "
                "use 0 < damping_ratio < 1 and 0 < frequency < fs/2"
            )
        if z.imag < 0:
            z = z.conjugate()
        object.__setattr__(self, "z", z)
        object.__setattr__(self, "fs", fs)

    # ----------------------------------------------------------- constructors
    @classmethod
    def from_modal(cls, freq_hz: float, damping_ratio: float, fs: float) -> "KautzPole":
        """Pole of a mode with natural frequency ``freq_hz`` [Hz] and damping ratio
        ``damping_ratio`` [-], sampled at ``fs`` [Hz]: ``Z = exp(S / fs)``,
        ``S = -zeta w + j w sqrt(1 - zeta^2)``, ``w = 2 pi freq_hz``."""
        f = float(freq_hz)
        zeta = float(damping_ratio)
        fs_ = float(fs)
        if not np.isfinite(fs_) or fs_ <= 0:
            raise ValueError(f"sampling rate fs must be a positive number of Hz, got {fs!r}")
        if not np.isfinite(f) or f <= 0:
            raise ValueError(f"pole frequency must be a positive number of Hz, got {freq_hz!r}")
        if not np.isfinite(zeta):
            raise ValueError(f"damping ratio must be finite, got {damping_ratio!r}")
        if zeta <= 0:
            raise ValueError(
                f"unstable Kautz pole: damping ratio {zeta:g} <= 0 puts the pole on or outside "
                "the unit circle; give a damping ratio in (0, 1), e.g. 0.01"
            )
        if zeta >= 1:
            raise ValueError(
                f"damping ratio {zeta:g} >= 1 gives real poles; the Kautz basis needs an "
                "underdamped pole (0 < damping_ratio < 1)"
            )
        w = 2.0 * math.pi * f
        wd = w * math.sqrt(1.0 - zeta * zeta)
        if wd / fs_ >= math.pi:
            raise ValueError(
                f"pole frequency {f:g} Hz is at or above the Nyquist frequency fs/2 = {fs_ / 2:g} Hz; "
                "raise the sampling rate or lower the pole frequency"
            )
        s = complex(-zeta * w, wd)
        return cls(np.exp(s / fs_), fs_)

    @classmethod
    def from_s(cls, s: complex, fs: float) -> "KautzPole":
        """Pole from a continuous pole ``s`` [rad/s]: ``Z = exp(s / fs)``."""
        s = complex(s)
        if s.real >= 0:
            raise ValueError(
                f"unstable Kautz pole: continuous pole s = {s:.6g} rad/s has Re(s) >= 0; "
                "give a pole with negative real part"
            )
        if abs(s.imag) / float(fs) >= math.pi:
            raise ValueError("continuous pole frequency above Nyquist: |Im s| / fs must be < pi")
        return cls(np.exp(s / float(fs)), fs)

    @classmethod
    def from_z(cls, z: complex, fs: float) -> "KautzPole":
        """Pole from a discrete pole ``z`` (dimensionless, ``|z| < 1``)."""
        return cls(z, fs)

    # ------------------------------------------------------------- properties
    @property
    def s(self) -> complex:
        """Continuous pole ``S = fs log Z`` [rad/s] (upper half plane)."""
        return complex(np.log(self.z) * self.fs)

    @property
    def freq_hz(self) -> float:
        """Undamped natural frequency ``|S| / 2 pi`` [Hz]."""
        return abs(self.s) / (2.0 * math.pi)

    @property
    def damping_ratio(self) -> float:
        """Damping ratio ``-Re(S) / |S|`` [-]."""
        s = self.s
        return -s.real / abs(s)

    @property
    def b(self) -> float:
        """Kautz parameter ``b = (Z + conj Z) / (1 + Z conj Z)`` (real, ``|b| < 1``)."""
        z = self.z
        return float((2.0 * z.real) / (1.0 + abs(z) ** 2))

    @property
    def c(self) -> float:
        """Kautz parameter ``c = -Z conj Z`` (the paper's d; real, -1 < c < 0)."""
        return float(-abs(self.z) ** 2)

    @property
    def radius(self) -> float:
        """Pole modulus ``|Z|`` (decay factor per sample)."""
        return abs(self.z)

    def settling_samples(self, tol: float = 1e-12) -> int:
        """Number of samples after which ``|Z|^n < tol`` (a horizon for the
        impulse responses; multiply by ~1.5 for J = 8 because of the
        polynomial growth of the higher functions)."""
        return int(math.ceil(math.log(tol) / math.log(self.radius)))

    def denominator(self) -> np.ndarray:
        """Coefficients of ``D`` in powers of ``z^-1``: ``[1, b (c - 1), -c]``."""
        b, c = self.b, self.c
        return np.array([1.0, b * (c - 1.0), -c])

    def allpass_numerator(self) -> np.ndarray:
        """Numerator of the all-pass ``A`` in powers of ``z^-1``: ``[-c, b (c - 1), 1]``."""
        b, c = self.b, self.c
        return np.array([-c, b * (c - 1.0), 1.0])

    def __str__(self) -> str:
        return (
            f"KautzPole(f = {self.freq_hz:.4f} Hz, zeta = {self.damping_ratio:.5f}, "
            f"fs = {self.fs:g} Hz, |Z| = {self.radius:.8f})"
        )


def _check_n_functions(n_functions: int) -> int:
    if isinstance(n_functions, bool) or not isinstance(n_functions, (int, np.integer)):
        raise ValueError(f"number of Kautz functions must be an even integer, got {n_functions!r}")
    J = int(n_functions)
    if J <= 0 or J % 2:
        raise ValueError(
            f"number of Kautz functions J = {J} must be even and positive (the functions come in "
            "pairs, one pair per power of the all-pass); use e.g. 2, 4, 6 or 8"
        )
    return J


def _kautz_filter_rows(u, pole: KautzPole, J: int) -> np.ndarray:
    """Filtered inputs with the function index before time: shape (..., J, N)."""
    u = np.asarray(u, dtype=float)
    b, c = pole.b, pole.c
    den = pole.denominator()
    num_a = pole.allpass_numerator()
    k_odd = math.sqrt(1.0 - c * c)
    k_even = math.sqrt((1.0 - c * c) * (1.0 - b * b))
    out = np.empty(u.shape[:-1] + (J, u.shape[-1]))
    r = lfilter([1.0], den, u, axis=-1)          # (1 / D) u, D in powers of z^-1
    for g in range(J // 2):
        if g:
            r = lfilter(num_a, den, r, axis=-1)  # one more all-pass section A
        odd = out[..., 2 * g, :]
        even = out[..., 2 * g + 1, :]
        # Psi_{2g}:   sqrt((1-c^2)(1-b^2)) z^-1 / D A^(g-1)
        even[..., 0] = 0.0
        np.multiply(r[..., :-1], k_even, out=even[..., 1:])
        # Psi_{2g-1}: sqrt(1-c^2) (1 - b z^-1) / D A^(g-1)
        np.multiply(r, k_odd, out=odd)
        odd[..., 1:] -= (b * k_odd) * r[..., :-1]
    return out


def kautz_filter(u, pole: KautzPole, n_functions: int) -> np.ndarray:
    """Filter ``u`` by the first ``n_functions`` Kautz functions of ``pole``.

    Exact recursive filtering (``scipy.signal.lfilter``) from a zero initial
    state, along the last axis of ``u``.

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
    """Sampled impulse responses ``psi_i(n)``, n = 0 .. n_samples-1.

    Returns an array of shape (n_samples, J).
    """
    n = int(n_samples)
    if n <= 0:
        raise ValueError(f"n_samples must be positive, got {n_samples!r}")
    d = np.zeros(n)
    d[0] = 1.0
    return kautz_filter(d, pole, n_functions)


def kautz_frequency_response(pole: KautzPole, n_functions: int, f_hz) -> np.ndarray:
    """Frequency responses ``Psi_i(exp(j 2 pi f / fs))`` of the Kautz functions.

    Convention: ``Psi_i(f) = sum_n psi_i(n) exp(-j 2 pi f n / fs)`` with f in
    Hz (negative frequencies allowed, ``Psi(-f) = conj Psi(f)``).

    Returns a complex array of shape ``np.shape(f_hz) + (J,)``.
    """
    J = _check_n_functions(n_functions)
    f = np.asarray(f_hz, dtype=float)
    z = np.exp(2j * np.pi * f / pole.fs)
    b, c = pole.b, pole.c
    D = z * z + b * (c - 1.0) * z - c
    A = (-c * z * z + b * (c - 1.0) * z + 1.0) / D
    even = math.sqrt((1.0 - c * c) * (1.0 - b * b)) * z / D
    odd_factor = (z - b) / math.sqrt(1.0 - b * b)
    out = np.empty(f.shape + (J,), dtype=complex)
    for g in range(J // 2):
        out[..., 2 * g + 1] = even
        out[..., 2 * g] = odd_factor * even
        even = even * A
    return out
