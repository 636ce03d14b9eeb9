"""Independent reference for the multi-mode tests: a spring-mass chain with a
cubic spring, integrated in continuous time (nothing here imports volterra).

* ``Chain``: masses m_i [kg], springs k_i [N/m] (k_1 to the ground, k_i
  between masses i-1 and i), Rayleigh damping C = a M + b K, a cubic spring
  k3 x_1^3 [N/m^3] from mass 1 to the ground, force on mass 1.  Exact poles
  (eigenvalues of the state matrix) and exact FRFs (accelerations / force,
  ``-w^2 (K - w^2 M + j w C)^-1``).
* ``multisine``: a periodic multisine, flat amplitude, random phases (seeded),
  evaluated analytically at any time.
* ``simulate``: fixed-step RK4 (numba) at 16 steps per output sample with the
  force evaluated analytically at every stage, sampled at 4 fs, an anti-alias
  FIR (the same on force and accelerations, so the linear relation between
  them is untouched) and decimation to fs.  No discrete model of the
  package is used to make the data (no inverse crime).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.linalg import eig
from scipy.signal import firwin, lfilter


class Chain:
    def __init__(self, m, k, a_damp, b_damp, k3=0.0):
        self.m = np.asarray(m, float)
        self.k = np.asarray(k, float)
        n = self.m.size
        K = np.zeros((n, n))
        for i, ki in enumerate(self.k):
            K[i, i] += ki
            if i:
                K[i - 1, i - 1] += ki
                K[i - 1, i] -= ki
                K[i, i - 1] -= ki
        self.M, self.K = np.diag(self.m), K
        self.C = a_damp * self.M + b_damp * K
        self.k3 = float(k3)

    def state_matrix(self):
        n = self.m.size
        Minv = np.diag(1.0 / self.m)
        return np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ self.K, -Minv @ self.C]])

    def modes(self):
        """(frequencies [Hz], damping ratios [-]) of the linear chain, ascending."""
        s = eig(self.state_matrix(), right=False)
        s = s[s.imag > 0]
        s = s[np.argsort(np.abs(s))]
        return np.abs(s) / (2 * np.pi), -s.real / np.abs(s)

    def frf_acc(self, f_hz):
        """Accelerations of all masses per unit force on mass 1: (len(f), n)."""
        out = []
        for f in np.atleast_1d(f_hz):
            w = 2 * np.pi * f
            x = np.linalg.solve(self.K - w * w * self.M + 1j * w * self.C, np.eye(self.m.size)[:, 0])
            out.append(-w * w * x)
        return np.array(out)


def multisine(f_lines, amp, seed):
    """(phases, function of time t [s] -> force [N])."""
    phases = np.random.default_rng(seed).uniform(0, 2 * np.pi, len(f_lines))
    return phases, lambda t: amp * np.cos(2 * np.pi * np.outer(t, f_lines) + phases).sum(axis=1)


@njit(cache=False)
def _force(t, f_lines, phases, amp):
    s = 0.0
    for i in range(f_lines.size):
        s += math.cos(2 * math.pi * f_lines[i] * t + phases[i])
    return amp * s


@njit(cache=False)
def _acc(x, v, t, m, K, C, k3, f_lines, phases, amp, out):
    n = m.size
    for i in range(n):
        s = 0.0
        for j in range(n):
            s -= K[i, j] * x[j] + C[i, j] * v[j]
        out[i] = s / m[i]
    out[0] += (_force(t, f_lines, phases, amp) - k3 * x[0] ** 3) / m[0]


@njit(cache=False)
def _rk4(n_out, h, steps_per_out, m, K, C, k3, f_lines, phases, amp):
    n = m.size
    acc = np.zeros((n_out, n))
    force = np.zeros(n_out)
    x = np.zeros(n)
    v = np.zeros(n)
    a1, a2, a3, a4 = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
    xt, vt = np.zeros(n), np.zeros(n)
    t = 0.0
    for k in range(n_out):
        _acc(x, v, t, m, K, C, k3, f_lines, phases, amp, a1)
        for i in range(n):
            acc[k, i] = a1[i]
        force[k] = _force(t, f_lines, phases, amp)
        for _ in range(steps_per_out):
            _acc(x, v, t, m, K, C, k3, f_lines, phases, amp, a1)
            k1x, k1v = v.copy(), a1.copy()
            for i in range(n):
                xt[i] = x[i] + 0.5 * h * k1x[i]
                vt[i] = v[i] + 0.5 * h * k1v[i]
            _acc(xt, vt, t + 0.5 * h, m, K, C, k3, f_lines, phases, amp, a2)
            k2x, k2v = vt.copy(), a2.copy()
            for i in range(n):
                xt[i] = x[i] + 0.5 * h * k2x[i]
                vt[i] = v[i] + 0.5 * h * k2v[i]
            _acc(xt, vt, t + 0.5 * h, m, K, C, k3, f_lines, phases, amp, a3)
            k3x, k3v = vt.copy(), a3.copy()
            for i in range(n):
                xt[i] = x[i] + h * k3x[i]
                vt[i] = v[i] + h * k3v[i]
            _acc(xt, vt, t + h, m, K, C, k3, f_lines, phases, amp, a4)
            for i in range(n):
                x[i] += h / 6.0 * (k1x[i] + 2 * k2x[i] + 2 * k3x[i] + vt[i])
                v[i] += h / 6.0 * (k1v[i] + 2 * k2v[i] + 2 * k3v[i] + a4[i])
            t += h
    return force, acc


def simulate(chain, f_lines, amp, phases, fs, n_samples, oversample=4, steps=4, numtaps=121):
    """(force (n,), accelerations (n, n_masses)) sampled at fs, starting at rest.

    RK4 at ``oversample * steps`` steps per output sample, sampled at
    ``oversample * fs``, anti-alias FIR (cut-off 0.45 fs) on every channel,
    every ``oversample``-th sample kept."""
    fs_hi = oversample * fs
    n_hi = n_samples * oversample + numtaps
    force, acc = _rk4(
        n_hi,
        1.0 / (fs_hi * steps),
        steps,
        chain.m,
        chain.K,
        chain.C,
        chain.k3,
        np.asarray(f_lines, float),
        np.asarray(phases, float),
        float(amp),
    )
    taps = firwin(numtaps, 0.45 * fs, fs=fs_hi)
    force = lfilter(taps, 1.0, force)[::oversample][:n_samples]
    acc = lfilter(taps, 1.0, acc, axis=0)[::oversample][:n_samples]
    return force, acc
