"""Poles of the Kautz functions: a complex pair (:class:`KautzPole`) or a real pole (:class:`RealPole`).

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
not zero (a one-sample advance with respect to Wahlberg's form): 2 functions
span ``(a + b z^-1) / D``, not every proper second-order system; the basis
with the feed-through (:mod:`volterra.gobf`) does.

This module holds the poles (:class:`KautzPole`, a complex pair, and
:class:`RealPole`); the filters, for one pole or a sequence of poles of
several modes, are in :mod:`volterra.gobf` (exact recursive filtering,
``scipy.signal.lfilter``, zero initial state, never a truncated convolution).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["KautzPole", "RealPole"]


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
        return float(-(abs(self.z) ** 2))

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


@dataclass(frozen=True)
class RealPole:
    """A real discrete pole ``a`` (0 < a < 1): an overdamped / first-order mode.

    Contributes one function per repeat of a pole sequence (a complex pair
    contributes two); see :mod:`volterra.gobf`.  ``fs`` in Hz.
    """

    a: float
    fs: float

    def __post_init__(self):
        fs = float(self.fs)
        if not np.isfinite(fs) or fs <= 0:
            raise ValueError(f"sampling rate fs must be a positive number of Hz, got {self.fs!r}")
        a = float(self.a)
        if not 0.0 < a < 1.0:
            raise ValueError(f"a real pole needs 0 < a < 1 (stable, not at Nyquist), got a = {self.a!r}")
        object.__setattr__(self, "a", a)
        object.__setattr__(self, "fs", fs)

    @classmethod
    def from_s(cls, s: float, fs: float) -> "RealPole":
        """From a continuous real pole ``s`` < 0 [rad/s]: ``a = exp(s / fs)``."""
        s = float(s)
        if not s < 0:
            raise ValueError(f"unstable real pole: s = {s:g} rad/s must be negative")
        return cls(math.exp(s / float(fs)), fs)

    @property
    def z(self) -> float:
        """The discrete pole (dimensionless)."""
        return self.a

    @property
    def s(self) -> float:
        """Continuous pole ``fs log a`` [rad/s] (negative)."""
        return math.log(self.a) * self.fs

    @property
    def freq_hz(self) -> float:
        """Corner frequency ``|s| / 2 pi`` [Hz]."""
        return abs(self.s) / (2.0 * math.pi)

    @property
    def damping_ratio(self) -> float:
        """1 (a real pole is not oscillatory) [-]."""
        return 1.0

    @property
    def radius(self) -> float:
        """Pole modulus (decay factor per sample)."""
        return self.a

    def settling_samples(self, tol: float = 1e-12) -> int:
        """Number of samples after which ``a^n < tol``."""
        return int(math.ceil(math.log(tol) / math.log(self.a)))

    def __str__(self) -> str:
        return f"RealPole(a = {self.a:.8f}, corner {self.freq_hz:.4f} Hz, fs = {self.fs:g} Hz)"


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
