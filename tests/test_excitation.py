"""The force between samples (fe.excitation)."""
import numpy as np
import pytest

from fe.excitation import interpolation_filter, upsample

FS = 1024.0


def sampled_sine(f, n=2048, factor=1):
    t = np.arange((n - 1) * factor + 1) / (FS * factor)
    return np.sin(2 * np.pi * f * t + 0.3)


@pytest.mark.parametrize("f", [5.0, 37.0, 150.0, 350.0])
def test_bandlimited_interpolation_recovers_the_sine_between_samples(f):
    fine = upsample(sampled_sine(f), 4)
    exact = sampled_sine(f, factor=4)
    mid = slice(4 * 200, -4 * 200)          # away from the record's ends
    assert np.max(np.abs(fine[mid] - exact[mid])) < 1e-4
    assert np.array_equal(upsample(sampled_sine(f), 4)[::4][200:-200], fine[::4][200:-200])


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
