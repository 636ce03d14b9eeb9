"""Two rules of the mode finder met on the front-end corpus (issue 40): two overlapping modes of one
shape are read as one (``volterra.selection.overlapped``), and a pseudo pole inside the band does
not fence a mode's refinement in (``volterra.selection.refine_modes``).

* A weakly nonlinear record: a single-degree-of-freedom oscillator with a cubic spring
  (fn = 36.3 Hz, zeta = 0.021, m = 0.8 kg; the cubic term stiffens the resonance's peak by
  0.3 %), solved by scipy's DOP853, swept 15 -> 90 Hz in 6 s, acceleration at 55 dB and
  force at 50 dB.  Without the rule, noise seed 500 gave a second "mode" at 36.644 Hz
  inside the true mode's half-power band (its misfit); the rule keeps one.  Not solved: the
  same records still give a "mode" near 34.3 Hz (2.7 half-power half-widths below, 1e-6
  of the energy), outside the rule's reach; this test does not ask about it.
* Two modes the rule must keep: 30.0 and 30.31 Hz at zeta = 0.0107 (closer than their
  half-power half-widths, 0.645 Hz), shapes (1, 0.8) and (0.9, -1.1) on two sensors, a
  periodic multisine's exact steady state, 1 % noise.
* A fence: an exact acceleration FRF of three modes (241 Hz at 2.6 %, 271.5 Hz at 5.5 %,
  297.3 Hz at 0.68 %; 0.1 % complex noise), refined from starts where the corpus's seed 187
  (a chain swept 39-714 Hz) left them: the middle mode's start at 288 Hz and a broad pseudo
  pole at 269.5 Hz (24 %) beside it.  When every pole's box was cut halfway to its
  neighbours, the pseudo pole took the 271.5 Hz mode and the start stuck at 292 Hz.

Constants of this module only.
"""

import numpy as np
from scipy.integrate import solve_ivp

import volterra
from volterra import lsfd
from volterra.selection import refine_modes


def _cubic_sweep(seed, peak_stiffening=0.003):
    fn, zeta, m, fs = 36.3, 0.021, 0.8, 1100.0
    w = 2 * np.pi * fn
    k, c = m * w * w, 2 * zeta * m * w
    t = np.arange(int(7.0 * fs)) / fs
    u = np.sin(2 * np.pi * (15.0 * t + 75.0 * t**2 / 12.0)) * np.clip(t / 0.2, 0, 1) * (t < 6.0)
    x_peak = 1.0 / (c * w)  # the linear response's amplitude at resonance (unit force)
    k3 = peak_stiffening * k / (0.75 * x_peak**2)

    def rhs(tt, s):
        return [s[1], (np.interp(tt, t, u) - c * s[1] - k * s[0] - k3 * s[0] ** 3) / m]

    sol = solve_ivp(rhs, (0, t[-1]), [0, 0], t_eval=t, method="DOP853", rtol=1e-10, atol=1e-14, max_step=0.25 / fs)
    x, v = sol.y
    a = (u - c * v - k * x - k3 * x**3) / m
    rng = np.random.default_rng(seed)
    a = a + np.std(a) * 10 ** (-55 / 20) * rng.standard_normal(a.size)
    u = u + np.std(u) * 10 ** (-50 / 20) * rng.standard_normal(u.size)
    return u, a, fs, fn, zeta


def test_a_weakly_nonlinear_sweep_gives_no_mode_inside_another():
    for seed in (500, 501):
        u, a, fs, fn, zeta = _cubic_sweep(seed)
        modes = [(p.freq_hz, p.damping_ratio) for p in volterra.estimate_modes(u, a, fs).poles]
        main = min(modes, key=lambda m: abs(m[0] - fn))
        assert abs(main[0] / fn - 1) < 0.005 and abs(main[1] / zeta - 1) < 0.15, modes
        for fa, za in modes:
            for fb, zb in modes:
                assert fa == fb or abs(fa - fb) >= za * fa + zb * fb, (seed, modes)


def test_an_overlapping_pair_of_two_shapes_is_kept():
    fs, period, f1, f2, zeta = 256.0, 8192, 30.0, 30.31, 0.0107
    rng = np.random.default_rng(31)
    f = np.fft.rfftfreq(period, 1 / fs)
    excited = (f > 10) & (f < 60)
    U = np.zeros(f.size, complex)
    U[excited] = np.exp(2j * np.pi * rng.uniform(size=excited.sum()))

    def mode(fr):
        w, s = 2 * np.pi * fr, 2j * np.pi * f
        return 1 / (w * w + 2 * zeta * w * s + s * s)

    shapes = np.array([[1.0, 0.8], [0.9, -1.1]])
    Y = np.stack([shapes[0, s] * mode(f1) + shapes[1, s] * mode(f2) for s in range(2)], 1) * U[:, None]
    u = np.tile(np.fft.irfft(U, period), 4)
    y = np.tile(np.fft.irfft(Y, period, axis=0), (4, 1))
    u = u + 0.01 * np.std(u) * rng.standard_normal(u.size)
    y = y + 0.01 * np.std(y, axis=0) * rng.standard_normal(y.shape)
    found = sorted((p.freq_hz, p.damping_ratio) for p in volterra.estimate_modes(u, y, fs).poles)
    assert len(found) == 2, found
    for (fr, z), true in zip(found, (f1, f2)):
        # measured: within 2e-5 in frequency and 0.1 % in damping
        assert abs(fr / true - 1) < 1e-4 and abs(z / zeta - 1) < 0.01, found


def test_a_pseudo_pole_inside_the_band_does_not_fence_a_mode_in():
    true = [(241.0, 0.026), (271.5, 0.055), (297.3, 0.0068)]
    f = np.arange(150.0, 400.0, 0.25)
    s = 2j * np.pi * f
    H = sum(1.0 / ((2 * np.pi * fr) ** 2 + 2 * z * (2 * np.pi * fr) * s + s * s) for fr, z in true) * s**2
    rng = np.random.default_rng(3)
    sd = 1e-3 * np.median(np.abs(H))
    H = H[:, None] + sd * (rng.standard_normal((f.size, 1)) + 1j * rng.standard_normal((f.size, 1))) / np.sqrt(2)
    lines = lsfd.FitLines(f, H, np.full(H.shape, 1 / sd))
    starts = [(240.0, 0.02), (288.0, 0.044), (297.0, 0.007)]
    modes, _, stuck = refine_modes(lines, starts, [(269.5, 0.24)], (150.0, 400.0), 0.25)
    assert not stuck
    for (fr, z), (f0, z0) in zip(modes, true):
        # measured: within 1.1e-5 in frequency and 0.04 % in damping
        assert abs(fr / f0 - 1) < 1e-4 and abs(z / z0 - 1) < 0.005, modes
