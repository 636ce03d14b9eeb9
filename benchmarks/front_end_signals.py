"""Excitations, acquisition and measurement noise for the front-end corpus.

Every excitation is built on the generator's fine grid (``R`` times the
record's rate) as the continuous input the structure sees (piecewise linear
between fine samples), with unit rms over its excited part:

* :func:`periodic_multisine`: random phases, flat amplitudes on the lines of
  a band, one period from an inverse FFT (exact samples of the sum of
  cosines), repeated; optional quiet lead-in and tail;
* :func:`random_noise`: Gaussian band-limited noise, a random-phase
  multisine with Rayleigh amplitudes whose period is twice the record (it
  never repeats inside it);
* :func:`sweep`: a linear or logarithmic chirp over the band, cosine-tapered
  ends, then zero force (the free decay);
* :func:`bursts`: frames of band-limited noise switched off for the rest of
  each frame (burst random with free decays).

:func:`acquire` is the data acquisition: the same anti-alias FIR and
decimation (``scipy.signal.resample_poly``) on every channel.
:func:`measurement_noise` draws white or coloured noise of an exact sd;
:func:`drift` a slow trend.  Every draw takes the caller's
``numpy.random.Generator``.
"""

from __future__ import annotations

import numpy as np
from scipy import signal


def _lines(band, n_period, fs):
    lo, hi = band
    k = np.arange(int(np.ceil(lo * n_period / fs)), int(np.floor(hi * n_period / fs)) + 1)
    return k[k > 0]


def _from_lines(rng, k, n_fine, amplitude):
    spec = np.zeros(n_fine // 2 + 1, complex)
    spec[k] = amplitude * np.exp(2j * np.pi * rng.uniform(size=k.size))
    x = np.fft.irfft(spec, n_fine)
    return x / np.std(x)


def periodic_multisine(rng, fs, R, band, period, n_periods, lead=0, tail=0):
    """(u_fine, period [record samples]) of ``n_periods`` periods of ``period`` samples, with
    ``lead`` and ``tail`` record samples of zero force before and after."""
    k = _lines(band, period, fs)
    one = _from_lines(rng, k, period * R, 1.0)
    u = np.concatenate([np.zeros(lead * R), np.tile(one, n_periods), np.zeros(tail * R)])
    return u, period


def random_noise(rng, fs, R, band, n):
    """Gaussian band-limited noise of ``n`` record samples (period 2 n: no repetition)."""
    k = _lines(band, 2 * n, fs)
    amp = rng.rayleigh(size=k.size)
    return _from_lines(rng, k, 2 * n * R, amp)[: n * R]


def _taper(n_on, n_edge):
    w = np.ones(n_on)
    e = 0.5 - 0.5 * np.cos(np.pi * np.arange(n_edge) / n_edge)
    w[:n_edge], w[-n_edge:] = e, e[::-1]
    return w


def sweep(rng, fs, R, band, n, on_fraction, log):
    """A chirp through ``band`` over ``on_fraction`` of ``n`` record samples, then zero force."""
    n_on = int(on_fraction * n) * R
    t = np.arange(n_on) / (fs * R)
    T = t[-1]
    lo, hi = band
    phase0 = rng.uniform(0, 2 * np.pi)
    if log:
        k = np.log(hi / lo) / T
        ph = 2 * np.pi * lo * (np.exp(k * t) - 1) / k
    else:
        ph = 2 * np.pi * (lo * t + 0.5 * (hi - lo) * t * t / T)
    x = np.sin(ph + phase0) * _taper(n_on, max(8, n_on // 50))
    x /= np.std(x)
    return np.concatenate([x, np.zeros(n * R - n_on)])


def bursts(rng, fs, R, band, n, n_frames, on_fraction):
    """``n_frames`` frames of ``n // n_frames`` samples, band-limited noise over the first
    ``on_fraction`` of each (tapered), zero force after."""
    frame = n // n_frames
    n_on = int(on_fraction * frame) * R
    out = []
    for _ in range(n_frames):
        x = random_noise(rng, fs, R, band, n_on // R + 1)[:n_on] * _taper(n_on, max(8, n_on // 20))
        out += [x, np.zeros(frame * R - n_on)]
    u = np.concatenate(out)
    u = np.concatenate([u, np.zeros(n * R - u.size)])
    return u / np.std(u[u != 0])


def acquire(x_fine, R):
    """The acquisition: anti-alias FIR and R:1 decimation of every column (same filter on all)."""
    return signal.resample_poly(np.asarray(x_fine, float), 1, R, axis=0)


NOISE_COLOURS = ("white", "ar1", "lowpass", "pink")


def measurement_noise(rng, n, sd, colour):
    """``n`` samples of noise of sd exactly ``sd`` (the realised sd): white, AR(1) with a pole
    in 0.3-0.9, second-order low-pass (corner 5-30 % of fs) or pink (1/f above 0.2 % of fs)."""
    w = rng.standard_normal(n + 2048)
    if colour == "white":
        x = w
    elif colour == "ar1":
        x = signal.lfilter([1.0], [1.0, -rng.uniform(0.3, 0.9)], w)
    elif colour == "lowpass":
        sos = signal.butter(2, rng.uniform(0.1, 0.6), output="sos")
        x = signal.sosfilt(sos, w)
    elif colour == "pink":
        W = np.fft.rfft(w)
        f = np.fft.rfftfreq(w.size)
        W /= np.sqrt(np.maximum(f, 0.002))
        x = np.fft.irfft(W, w.size)
    else:
        raise ValueError(colour)
    x = x[2048:]
    x = x - x.mean()
    return sd * x / np.std(x)


def drift(rng, n, amplitude):
    """A slow trend of peak ``amplitude``: a ramp and half a cosine cycle over the record."""
    t = np.linspace(0, 1, n)
    a, b = rng.uniform(-1, 1, 2)
    x = a * (t - 0.5) + b * np.cos(np.pi * t + rng.uniform(0, np.pi))
    return amplitude * x / max(np.max(np.abs(x)), 1e-12)
