"""The model-form error's draws (bayes_update.core.model_form), against closed forms:
what they leave of noise alone, the power they keep of a residual beyond the noise,
and the variance their projections carry, which a random-phase process has in
closed form."""

import numpy as np

from bayes_update.core.model_form import BAND_BINS, THRESHOLD_SD, excess_gain, form_draws, periodogram

N = 4096


def _band_signal(rng, n=N, lo=300, hi=340, amplitude=1.0):
    """A deterministic narrow-band signal: cosines on bins lo..hi, random phases."""
    X = np.zeros(n // 2 + 1, complex)
    X[lo:hi] = amplitude * np.exp(2j * np.pi * rng.random(hi - lo))
    return np.fft.irfft(X, n) * np.sqrt(n)


def test_periodogram_is_the_power_by_parseval():
    x = np.random.default_rng(0).standard_normal(N)
    P = periodogram(x)
    # rfft's one-sided bins: twice every bin but DC and Nyquist
    total = (P[0] + 2 * P[1:-1].sum() + P[-1]) / N
    assert np.isclose(total, np.mean(x**2), rtol=1e-12)


def test_noise_alone_leaves_almost_nothing():
    rng = np.random.default_rng(1)
    sd = 0.3
    noise_spectrum = np.full(N // 2 + 1, sd**2)  # white noise's periodogram mean
    kept = []
    for _ in range(20):
        r = sd * rng.standard_normal(N)
        draws, excess = form_draws(r, noise_spectrum, 4, rng)
        kept.append(np.mean(excess**2) / sd**2)
    # a band counts only beyond THRESHOLD_SD (2) sd of its 16-bin average: chance leaves < 1 %
    assert THRESHOLD_SD == 2.0 and BAND_BINS == 16
    assert np.mean(kept) < 0.01, np.mean(kept)


def test_a_residual_beyond_the_noise_keeps_its_power_and_its_spectrum():
    rng = np.random.default_rng(2)
    sd = 0.05
    signal = _band_signal(rng)  # rms about 0.14, 8x the noise's power in band
    r = signal + sd * rng.standard_normal(N)
    draws, excess = form_draws(r, np.full(N // 2 + 1, sd**2), 8, rng)
    # the excess is the signal's power within a few % (the noise in its band is taken off, and the
    # soft threshold costs 2 / sqrt(16) of the noise's power there)
    assert abs(np.mean(excess**2) / np.mean(signal**2) - 1) < 0.06
    # every draw has the excess's periodogram exactly (random phases, the same amplitudes)
    P = periodogram(excess)
    for d in draws:
        assert np.allclose(periodogram(d)[1:-1], P[1:-1], rtol=1e-8, atol=1e-12 * P.max())
    # and outside the signal's band, the noise's chance excess only (on average under 2 % of its power)
    outside = np.r_[1:250, 400 : N // 2]
    assert P[outside].mean() < 0.02 * sd**2


def test_draws_keep_the_sensors_cross_spectrum():
    rng = np.random.default_rng(3)
    s = _band_signal(rng)
    r = np.column_stack([s, -2.0 * s]) + 1e-4 * rng.standard_normal((N, 2))
    draws, _ = form_draws(r, np.full((N // 2 + 1, 2), 1e-8), 6, rng)
    for d in draws:  # the same phase at a frequency for both sensors
        assert np.allclose(d[:, 1], -2.0 * d[:, 0], rtol=0, atol=2e-3 * np.abs(d).max())


def test_projection_variance_is_the_random_phase_closed_form():
    rng = np.random.default_rng(4)
    r = _band_signal(rng, lo=100, hi=900) * np.linspace(0.2, 1.0, N) ** 0  # broad band
    q = rng.standard_normal(N)
    q /= np.linalg.norm(q)
    draws, excess = form_draws(r, np.full(N // 2 + 1, 1e-12), 4000, rng)
    A, Q = np.fft.rfft(excess), np.fft.rfft(q)
    # q . delta = (2 / N) sum_f Re(A_f conj(Q_f) e^{i phi_f}) over the bins 1..N/2-1 (no DC, Nyquist
    # zero here): independent uniform phases give the variance (2 / N^2) sum |A_f|^2 |Q_f|^2
    closed = 2.0 / N**2 * np.sum(np.abs(A[1:-1]) ** 2 * np.abs(Q[1:-1]) ** 2)
    mc = np.var(draws @ q)
    assert abs(mc / closed - 1) < 0.1, (mc, closed)


def test_excess_gain_is_between_zero_and_one():
    rng = np.random.default_rng(5)
    P = periodogram(rng.standard_normal((N, 3)))
    g = excess_gain(P, 0.5 * np.ones_like(P))
    assert g.shape == P.shape and np.all((g >= 0) & (g <= 1))
