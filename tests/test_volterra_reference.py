"""Independent reference implementations for the volterra tests, and tests of
the references themselves.

Nothing here imports the package under test:

* ``kautz_ref_freq`` / ``kautz_ref_impulse``: the Kautz functions written
  directly from the formulas of ``docs/design.md`` ("Kautz basis: form and conventions"); impulse
  responses by an
  inverse FFT of the closed-form frequency response (time aliasing
  ``|Z|^M < 1e-17``), not by recursive filtering.
* ``volterra_forward_ref``: a Volterra model in that basis evaluated with
  direct convolutions (``np.convolve``) and explicit loops over index tuples.
* ``simulate``: RK4 (numba) of ``m x'' + c x' + k x + k2 x^2 + k3 x^3 = u``
  with the input linearly interpolated between samples, integrated together
  with the perturbation hierarchy x1, x2, x3 (x1: linear; m x2'' + c x2' +
  k x2 = -k2 x1^2; m x3'' + ... = -k3 x1^3 - 2 k2 x1 x2), sampled at fs.
* harmonic probing formulas (Worden and Tomlinson 2001, ch. 8), with the
  discrete-time factor prod sinc^2(f_i T) of a linearly interpolated input.

Other test modules import it (``sys.path`` gets the tests folder).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit
from scipy.signal import lsim

# ------------------------------------------------------------------ Kautz ref


def kautz_ref_pole(fn, zeta, fs):
    w = 2 * math.pi * fn
    Z = np.exp(complex(-zeta * w, w * math.sqrt(1 - zeta**2)) / fs)
    return Z


def kautz_ref_freq(f_hz, fn, zeta, fs, J):
    """Psi_i(exp(j 2 pi f / fs)), i = 1..J, straight from the notes' formulas."""
    Z = kautz_ref_pole(fn, zeta, fs)
    b = (Z + Z.conjugate()).real / (1 + abs(Z) ** 2)
    c = -(abs(Z) ** 2)
    z = np.exp(2j * np.pi * np.asarray(f_hz, float) / fs)
    D = z**2 + b * (c - 1) * z - c
    A = (-c * z**2 + b * (c - 1) * z + 1) / D
    cols = []
    for g in range(1, J // 2 + 1):
        psi_even = np.sqrt((1 - c**2) * (1 - b**2)) * z / D * A ** (g - 1)
        psi_odd = (z - b) / np.sqrt(1 - b**2) * psi_even
        cols += [psi_odd, psi_even]
    return np.stack(cols, axis=-1)


def kautz_ref_impulse(fn, zeta, fs, J, n, M=1 << 17):
    """psi_i(k), k < n, by inverse FFT of the closed form on M points."""
    Z = kautz_ref_pole(fn, zeta, fs)
    assert abs(Z) ** M < 1e-15, "FFT length too short for this pole"
    f = np.arange(M) * fs / M
    psi = np.fft.ifft(kautz_ref_freq(f, fn, zeta, fs, J), axis=0)
    assert np.abs(psi.imag).max() < 1e-12
    return psi.real[:n]


def volterra_forward_ref(u, psi_by_order, coef_by_order):
    """y_n(k) = sum over ordered tuples B[t] prod l_{t_i}(k), l = psi * u (direct convolution).

    psi_by_order: {order: (n, J) impulse responses}; coef_by_order: {order: {tuple: value}}.
    Returns {order: y_n}."""
    N = u.size
    out = {}
    for order, coefs in coef_by_order.items():
        psi = psi_by_order[order]
        l = [np.convolve(u, psi[:N, i])[:N] for i in range(psi.shape[1])]
        y = np.zeros(N)
        for t, b in coefs.items():
            term = np.full(N, b)
            for i in t:
                term = term * l[i]
            y += term
        out[order] = y
    return out


# ------------------------------------------------------------ oscillator ref


@njit(cache=False)
def _rhs(s, uf, m, c, k, k2, k3, out):
    x, v, x1, v1, x2, v2, x3, v3 = s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7]
    out[0] = v
    out[1] = (uf - c * v - k * x - k2 * x * x - k3 * x * x * x) / m
    out[2] = v1
    out[3] = (uf - c * v1 - k * x1) / m
    out[4] = v2
    out[5] = (-c * v2 - k * x2 - k2 * x1 * x1) / m
    out[6] = v3
    out[7] = (-c * v3 - k * x3 - k3 * x1 * x1 * x1 - 2.0 * k2 * x1 * x2) / m


@njit(cache=False)
def _rk4(u, T, m, c, k, k2, k3, nsub):
    N = u.size
    out = np.zeros((N, 5))
    s = np.zeros(8)
    a1 = np.zeros(8)
    a2 = np.zeros(8)
    a3 = np.zeros(8)
    a4 = np.zeros(8)
    tmp = np.zeros(8)
    h = T / nsub
    for n in range(N - 1):
        u0 = u[n]
        du = u[n + 1] - u[n]
        for j in range(nsub):
            ta = j / nsub
            tm = (j + 0.5) / nsub
            tb = (j + 1.0) / nsub
            _rhs(s, u0 + du * ta, m, c, k, k2, k3, a1)
            for i in range(8):
                tmp[i] = s[i] + 0.5 * h * a1[i]
            _rhs(tmp, u0 + du * tm, m, c, k, k2, k3, a2)
            for i in range(8):
                tmp[i] = s[i] + 0.5 * h * a2[i]
            _rhs(tmp, u0 + du * tm, m, c, k, k2, k3, a3)
            for i in range(8):
                tmp[i] = s[i] + h * a3[i]
            _rhs(tmp, u0 + du * tb, m, c, k, k2, k3, a4)
            for i in range(8):
                s[i] += h / 6.0 * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4[i])
        out[n + 1, 0] = s[0]
        out[n + 1, 1] = s[2]
        out[n + 1, 2] = s[4]
        out[n + 1, 3] = s[6]
        out[n + 1, 4] = s[1]
    return out


class Oscillator:
    """m x'' + c x' + k x + k2 x^2 + k3 x^3 = u (SI units: kg, N s/m, N/m, N/m^2, N/m^3)."""

    def __init__(self, fn=30.0, zeta=0.01, m=0.02, k2=0.0, k3=0.0):
        self.fn, self.zeta, self.m = fn, zeta, m
        w = 2 * math.pi * fn
        self.k = m * w * w
        self.c = 2 * zeta * m * w
        self.k2, self.k3 = k2, k3

    def simulate(self, u, fs, nsub=16):
        """Sampled response to u (u[0] should be 0: the system starts at rest).
        Returns dict x (full), x1, x2, x3 (hierarchy), v (velocity of x)."""
        u = np.ascontiguousarray(u, dtype=float)
        o = _rk4(u, 1.0 / fs, self.m, self.c, self.k, self.k2, self.k3, nsub)
        return dict(x=o[:, 0], x1=o[:, 1], x2=o[:, 2], x3=o[:, 3], v=o[:, 4])

    def H1(self, f_hz):
        w = 2 * np.pi * np.asarray(f_hz, float)
        return 1.0 / (self.k - self.m * w**2 + 1j * self.c * w)

    def H2(self, f1, f2):
        """Harmonic probing, symmetric, no 1/n!."""
        return -self.k2 * self.H1(f1) * self.H1(f2) * self.H1(np.add(f1, f2))

    def H3(self, f1, f2, f3):
        H1 = self.H1
        s = np.add(np.add(f1, f2), f3)
        return -H1(s) * (
            self.k3 * H1(f1) * H1(f2) * H1(f3)
            + (2 * self.k2 / 3) * (H1(f1) * self.H2(f2, f3) + H1(f2) * self.H2(f1, f3) + H1(f3) * self.H2(f1, f2))
        )


def sinc2(f_hz, fs):
    """Discrete/continuous kernel factor of one argument for a linearly
    interpolated input and a sampled output."""
    return np.sinc(np.asarray(f_hz, float) / fs) ** 2


def chirp(amp, fs=1024.0, n=4096, f0=20.0, f1=50.0, duration=2.0):
    """Linear chirp f0 -> f1 Hz during ``duration`` s, then zero (free decay)."""
    t = np.arange(n) / fs
    u = amp * np.sin(2 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2 * duration)))
    u[t >= duration] = 0.0
    return u


# ------------------------------------------------- tests of the references

FS = 1024.0


def test_reference_kautz_is_orthonormal_by_parseval():
    # Gram matrix from the frequency-domain formula (Parseval, 2^16 points)
    J = 6
    f = np.arange(1 << 16) * FS / (1 << 16)
    P = kautz_ref_freq(f, 30.0, 0.02, FS, J)
    gram = (P.conj().T @ P).real / f.size
    assert np.abs(gram - np.eye(J)).max() < 1e-12


def test_rk4_linear_part_matches_exact_first_order_hold():
    osc = Oscillator(k3=6.6e5)
    u = chirp(0.1)
    t = np.arange(u.size) / FS
    # lsim with interp=True integrates a piecewise-linear input exactly
    _, x_exact, _ = lsim(([1.0], [osc.m, osc.c, osc.k]), u, t, interp=True)
    err = [np.linalg.norm(osc.simulate(u, FS, ns)["x1"] - x_exact) / np.linalg.norm(x_exact) for ns in (16, 32)]
    assert err[0] < 2e-8  # measured 1.06e-8 at T/16
    assert err[0] / err[1] > 12  # fourth-order convergence (16x per halving)


def test_rk4_converged_in_substeps():
    osc = Oscillator(k2=5e3, k3=6.6e5)
    u = chirp(0.1)
    a, b = osc.simulate(u, FS, 16), osc.simulate(u, FS, 32)
    for key in ("x", "x2", "x3"):
        assert np.linalg.norm(a[key] - b[key]) / np.linalg.norm(b[key]) < 1e-7


def test_harmonic_probing_matches_integrated_hierarchy():
    # steady-state response of the hierarchy to a sampled cosine (13 Hz, off resonance):
    # x2 = 1/2 Re[H2(f,f) e^{j2wt}] + 1/2 H2(f,-f);  x3 at 3f: 1/4 Re[H3(f,f,f) e^{j3wt}],
    # at f: 3/4 Re[H3(f,f,-f) e^{jwt}]; each H_n times prod sinc^2(f_i T).
    osc = Oscillator(k2=3e4, k3=1e7)
    f = 13.0
    n = int(14 * FS)
    t = np.arange(n) / FS
    u = np.cos(2 * np.pi * f * t)
    u[0] = 0.0  # start at rest; the transient dies out (tau = 0.53 s)
    r = osc.simulate(u, FS)
    seg = slice(n - 1024, n)  # the last second: 13 whole periods of 13 Hz
    tt = t[seg]

    def phasor(x, fr):
        E = np.column_stack(
            [np.ones_like(tt)] + [g(2 * np.pi * q * f * tt) for q in (1, 2, 3) for g in (np.cos, np.sin)]
        )
        coef = np.linalg.lstsq(E, x[seg], rcond=None)[0]
        q = int(round(fr / f))
        return coef[0] if q == 0 else coef[2 * q - 1] - 1j * coef[2 * q]

    s = lambda *fr: np.prod([sinc2(x, FS) for x in fr], axis=0)  # noqa: E731
    H2ff = osc.H2(f, f) * s(f, f)
    H2fm = osc.H2(f, -f) * s(f, -f)
    H3fff = osc.H3(f, f, f) * s(f, f, f)
    H3ffm = osc.H3(f, f, -f) * s(f, f, -f)
    assert abs(phasor(r["x2"], 2 * f) - 0.5 * H2ff) < 1e-5 * abs(H2ff)
    assert abs(phasor(r["x2"], 0.0) - 0.5 * H2fm) < 1e-5 * abs(H2fm)
    assert abs(phasor(r["x3"], 3 * f) - 0.25 * H3fff) < 1e-5 * abs(H3fff)
    assert abs(phasor(r["x3"], f) - 0.75 * H3ffm) < 1e-5 * abs(H3ffm)


if __name__ == "__main__":  # pragma: no cover
    pytest.main([__file__, "-q"])
