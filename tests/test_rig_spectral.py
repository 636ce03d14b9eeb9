"""Spectral estimators against exact answers (a discrete SDOF oscillator)."""

import numpy as np
import pytest
from scipy import signal as ss

from bayes_update.data import spectral
from bayes_update.data.signals import add_noise, chirp, rms, sine

FS = 1024.0


def sdof(fn=37.0, zeta=0.013):
    """A discrete SDOF velocity response filter (bilinear) and its exact FRF."""
    wn = 2 * np.pi * fn
    b, a = ss.bilinear([1.0, 0.0], [1.0, 2 * zeta * wn, wn**2], fs=FS)

    def frf(f):
        return ss.freqz(b, a, worN=np.asarray(f), fs=FS)[1]

    return b, a, frf


def test_welch_h1_and_coherence_on_random_excitation():
    b, a, frf = sdof()
    rng = np.random.default_rng(1)
    u = rng.standard_normal(64 * 8192)
    y = ss.lfilter(b, a, u)
    est = spectral.frf_h1(u, y, FS, nperseg=16384)
    band = est.band(30, 45)
    err = np.abs(est.h1[band] - frf(est.f[band])) / np.abs(frf(est.f[band]))
    assert err.max() < 0.02
    assert est.coherence[band].min() > 0.99
    # output noise lowers the coherence where the response is small, not H1
    yn = add_noise(y, 20.0, rng)
    noisy = spectral.frf_h1(u, yn, FS, nperseg=16384)
    assert noisy.coherence[noisy.band(100, 200)].mean() < 0.9
    err = np.abs(noisy.h1[band] - frf(noisy.f[band])) / np.abs(frf(noisy.f[band]))
    assert err.max() < 0.05


def test_transient_frf_is_exact_for_a_record_that_starts_and_ends_at_rest():
    b, a, frf = sdof()
    u = chirp(0.1)
    y = ss.lfilter(b, a, u)
    est = spectral.transient_frf(u, y, FS)
    band = est.band(25, 45)
    np.testing.assert_allclose(est.h1[band], frf(est.f[band]), rtol=2e-3)
    assert est.coherence[band].min() > 0.99
    assert est.f[1] == pytest.approx(0.25)  # whole-record resolution


def test_short_welch_segments_bias_a_lightly_damped_transient():
    """Why transient_frf exists: 1 s Hann segments on a 4 s chirp are badly biased."""
    b, a, frf = sdof()
    u = chirp(0.1)
    y = ss.lfilter(b, a, u)
    est = spectral.frf_h1(u, y, FS, nperseg=1024)
    i = np.argmin(np.abs(est.f - 37.0))
    assert abs(est.h1[i]) < 0.8 * abs(frf([37.0])[0])


def test_psd_of_a_sine_integrates_to_its_power():
    x = sine(2.0, 35.0, duration=8.0)
    f, p = spectral.psd(x, FS)
    assert f[np.argmax(p)] == pytest.approx(35.0)
    assert np.sum(p) * (f[1] - f[0]) == pytest.approx(rms(x) ** 2, rel=1e-3)
    # a list of records averages
    f2, p2 = spectral.psd([x, x], FS)
    np.testing.assert_allclose(p2, p)


def test_estimators_reject_bad_input():
    with pytest.raises(ValueError, match="differ in length"):
        spectral.frf_h1(np.zeros(10), np.zeros(11), FS)
    with pytest.raises(ValueError, match="NaN or inf"):
        spectral.psd(np.array([0.0, np.nan, 1.0]), FS)
    with pytest.raises(ValueError, match="fs must be positive"):
        spectral.psd(np.zeros(8), 0.0)
