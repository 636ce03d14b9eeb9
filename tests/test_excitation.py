"""The force between samples (fe.excitation)."""

import numpy as np
import pytest

from fe.excitation import interpolation_filter, upsample

FS = 1024.0


def sampled_sine(f, n=2048, factor=1):
    t = np.arange((n - 1) * factor + 1) / (FS * factor)
    return np.sin(2 * np.pi * f * t + 0.3)


@pytest.mark.parametrize("f", [5.0, 37.0, 150.0, 350.0, 399.0])
def test_bandlimited_interpolation_recovers_the_sine_between_samples(f):
    """The docstring's promise: flat to 2e-5 up to 0.39 fs (399 Hz), and sample
    j * factor of the result is sample j of the force to that accuracy.
    Measured max errors (away from the ends): between the samples 1.1e-6 /
    1.1e-6 / 1.6e-6 / 0.9e-6 / 5.2e-6, on the samples 0.9e-6 / 1.0e-6 /
    1.6e-6 / 2e-9 / 4.9e-6 at 5 / 37 / 150 / 350 / 399 Hz: the promised 2e-5
    is the tolerance (3.8x the worst)."""
    x = sampled_sine(f)
    fine = upsample(x, 4)
    exact = sampled_sine(f, factor=4)
    mid = slice(4 * 200, -4 * 200)  # away from the record's ends
    assert np.max(np.abs(fine[mid] - exact[mid])) < 2e-5
    # the input's own samples come back (the filter is not an exact Nyquist filter)
    assert np.max(np.abs(fine[::4][200:-200] - x[200:-200])) < 2e-5


@pytest.mark.parametrize("factor", [2, 4, 16])
def test_bandlimited_interpolation_is_the_documented_fir(factor):
    """Independent construction of what the docstring describes: zero-stuff the
    samples (zero before the first one), convolve with a Kaiser-windowed sinc
    (beta 10, 64 taps per phase, cutoff 0.45 fs, unit DC gain, gain ``factor``
    for the zeros), drop the filter's delay.  On a white record (which also
    holds content above the band, so nothing is recovered by accident):
    measured 2.2e-15 / 2.2e-15 / 2.7e-15 of a unit-variance input; 1e-12."""
    x = np.random.default_rng(1).standard_normal(500)
    n_taps = 2 * 64 * factor + 1
    k = np.arange(n_taps) - (n_taps - 1) / 2
    h = np.sinc(2 * 0.45 / factor * k) * np.kaiser(n_taps, 10.0)
    h /= h.sum()
    stuffed = np.zeros((x.size - 1) * factor + 1)
    stuffed[::factor] = x
    delay = (n_taps - 1) // 2
    reference = np.convolve(stuffed, factor * h)[delay : delay + stuffed.size]
    out = upsample(x, factor)
    assert out.shape == reference.shape
    assert np.max(np.abs(out - reference)) < 1e-12


def test_linear_interpolation_has_the_triangle_kernel_error():
    f = 37.0
    fine = upsample(sampled_sine(f), 4, "linear")
    exact = sampled_sine(f, factor=4)
    err = np.max(np.abs(fine - exact))
    # the largest gap between a chord and the arc: 1 - cos(pi f / fs) at mid-interval
    assert err == pytest.approx(1 - np.cos(np.pi * f / FS), rel=0.05)
    assert np.allclose(fine[::4], sampled_sine(f))


def test_filter_is_flat_in_the_band_and_rejects_images():
    from scipy.signal import freqz

    h = interpolation_filter(4)
    _, H = freqz(h, worN=np.array([0.0, 37.0, 300.0, 400.0, 512.0, 700.0]), fs=4 * FS)
    assert np.allclose(np.abs(H[:4]), 1.0, atol=2e-5)
    assert np.all(np.abs(H[4:]) < 1e-4)


def test_bad_method_is_rejected():
    with pytest.raises(ValueError, match="input_interpolation"):
        upsample(np.zeros(8), 2, "cubic")
