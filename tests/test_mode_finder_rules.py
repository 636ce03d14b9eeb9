"""Rules of the mode finder met on the front-end corpus (issue 40): two overlapping modes of one
shape are read as one (``volterra.selection.overlapped``), a pseudo pole inside the band does
not fence a mode's refinement in (``volterra.selection.refine_modes``), and a sweep's lines are
weighted with the force noise's share of their error (``volterra.lines``) and its band read to its
ends (``volterra.excited_band``).

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
* The force's noise on a sweep: two modes (23.7 Hz at 1.9 %, 61.3 Hz at 2.7 %, a displacement
  sensor) discretised exactly for a force linear between samples (scipy's cont2discrete,
  "foh"), swept 10 -> 90 Hz in 10 s at 1500 Hz, 20 dB of white noise on the force and
  60 dB on the response.  The weights are 1 / the sd of each line's H: at the true poles the
  weighted residual's squares should have the median of a chi-square of 2 degrees over 2
  (0.693).  Without the force noise's share (the local polynomials of a sweep take G U into
  the transient and leave it out) they were 2.26-2.42 within three half-power half-widths of
  the 23.7 Hz mode; with it 0.46-0.71.
* A sweep's band: a linear sweep 4.3 -> 41 Hz of 30 s at 400 Hz with a 0.3 s fade-in.
  Welch's Hann segments alone read (5.33, 40.0) Hz, the sweep's first 4 s weighing little;
  with the whole record's periodogram (4.6, 40.9) Hz.

Constants of this module only.
"""

import numpy as np
from scipy import stats
from scipy.integrate import solve_ivp
from scipy.signal import cont2discrete, dlsim

import volterra
from volterra import excited_band, lsfd
from volterra.lines import record_lines
from volterra.selection import refine_modes, weights


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


def test_a_sweeps_weights_hold_the_force_noise():
    fs, modes = 1500.0, [(23.7, 0.019, 1.0), (61.3, 0.027, 0.6)]
    A, B, C = np.zeros((4, 4)), np.zeros((4, 1)), np.zeros((1, 4))
    for i, (fr, z, c) in enumerate(modes):
        w = 2 * np.pi * fr
        A[2 * i, 2 * i + 1], A[2 * i + 1, 2 * i], A[2 * i + 1, 2 * i + 1] = 1.0, -w * w, -2 * z * w
        B[2 * i + 1, 0], C[0, 2 * i] = 1.0, c
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, np.zeros((1, 1))), 1 / fs, method="foh")
    t = np.arange(int(12.0 * fs)) / fs
    u = np.sin(2 * np.pi * (10 * t + 4.0 * t**2)) * (t < 10.0) * np.clip(t / 0.1, 0, 1)
    y = dlsim((Ad, Bd, Cd, Dd, 1 / fs), u)[1][:, 0]
    for seed in (900, 901, 902):
        rng = np.random.default_rng(seed)
        un = u + 0.1 * np.std(u) * rng.standard_normal(u.size)
        yn = y + 1e-3 * np.std(y) * rng.standard_normal(y.size)
        lines = record_lines([un - un.mean()], [(yn - yn.mean())[:, None]], fs)
        W = weights(lines.var, lines.H, lines.u_power, lines.var_input)
        fit = lsfd.FitLines(lines.f, lines.H, W, fs, lines.inv_u, lines.record)
        _, resid, _ = lsfd.fit(fit, [(fr, z) for fr, z, _ in modes])
        near = np.abs(fit.f - 23.7) < 3 * 0.019 * 23.7
        ratio = np.median(np.abs(resid[near, 0]) ** 2) / (stats.chi2.median(2) / 2)
        assert 0.4 < ratio < 1.6, (seed, ratio)  # measured 0.66-1.02; without the force's share 3.3-3.5


def test_a_periodic_multisines_band_is_its_lines_not_the_whole_spectrum():
    """Nine periods of a random-phase multisine on the lines of 2-12 Hz at 400 Hz, white noise
    1/300 of its rms on the force: its power sits on every ninth line of the record's
    periodogram, a comb whose running median was the noise between its teeth, as low inside the
    band as outside it: the band was read as (0.5, 200) Hz, the whole spectrum."""
    fs, period = 400.0, 8192
    k = np.arange(1, period // 2)
    lines = k[(k * fs / period >= 2.0) & (k * fs / period <= 12.0)]
    rng = np.random.default_rng(57)
    t = np.arange(9 * period) / fs
    phases = 2 * np.pi * rng.random(lines.size)
    u = np.sum([np.cos(2 * np.pi * kk * fs / period * t + ph) for kk, ph in zip(lines, phases)], axis=0)
    u = u / np.std(u) + rng.standard_normal(t.size) / 300
    lo, hi = excited_band(u, fs)
    # measured (1.75, 12.25): Welch's 4 s Hann segments, 0.25 Hz apart, and the main lobe's half-width
    assert 1.5 <= lo <= 2.0 and 12.0 <= hi <= 12.5, (lo, hi)


def test_a_sweeps_band_reaches_its_ends():
    fs, duration, f0, f1 = 400.0, 30.0, 4.3, 41.0
    t = np.arange(int(duration * fs)) / fs
    u = np.sin(2 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2 * duration))) * np.clip(t / 0.3, 0, 1)
    lo, hi = excited_band(u, fs)
    # measured (4.6, 40.9): the fade-in's first lines below a quarter of the level, the top reached
    assert f0 - 0.5 < lo < f0 + 0.5 and f1 - 0.5 < hi < f1 + 1.0, (lo, hi)
