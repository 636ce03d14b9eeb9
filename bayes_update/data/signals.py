"""Excitation signals of the paper's tests (force in N, sampled at fs Hz) and
measurement noise.

* :func:`chirp`: linear sweep 20 -> 50 Hz during the first 2 s, zero afterwards
  (free decay), 4 s in all: the paper's chirp tests.
* :func:`sine`: stationary sine, 35 Hz in the paper; :func:`sine_near_resonance`
  places it relative to a first natural frequency instead (the paper's 35 Hz
  is 0.94 f1 on the paper-equivalent rig).
* :func:`test_signal`: either of the two by name, as listed in a data set.
* :func:`add_noise`: white Gaussian noise at a given SNR (dB, relative to the
  channel's RMS over the record), from a caller-owned numpy Generator.

Every signal starts at zero (sin 0) so that a record starting at rest is
consistent.
"""

from __future__ import annotations

import numpy as np

PAPER_FS = 1024.0  # Hz
PAPER_DURATION = 4.0  # s
PAPER_CHIRP = {"f_start": 20.0, "f_end": 50.0, "sweep_time": 2.0}  # Hz, Hz, s
PAPER_SINE_HZ = 35.0
SIGNALS = ("chirp", "sine")


def _time(duration: float, fs: float) -> np.ndarray:
    if not (fs > 0 and duration > 0):
        raise ValueError(f"fs and duration must be positive, got fs={fs}, duration={duration}")
    return np.arange(int(round(duration * fs))) / fs


def chirp(
    amplitude: float,
    f_start: float = 20.0,
    f_end: float = 50.0,
    sweep_time: float = 2.0,
    duration: float = PAPER_DURATION,
    fs: float = PAPER_FS,
) -> np.ndarray:
    """Linear sine sweep f_start -> f_end [Hz] of ``amplitude`` [N] during
    ``sweep_time`` [s], zero afterwards (free decay), as in the paper."""
    t = _time(duration, fs)
    phase = 2 * np.pi * (f_start * t + 0.5 * (f_end - f_start) / sweep_time * t**2)
    return np.where(t < sweep_time, amplitude * np.sin(phase), 0.0)


def sine(
    amplitude: float, frequency: float = PAPER_SINE_HZ, duration: float = PAPER_DURATION, fs: float = PAPER_FS
) -> np.ndarray:
    """Stationary sine of ``amplitude`` [N] at ``frequency`` [Hz] (the paper's 35 Hz test)."""
    t = _time(duration, fs)
    return amplitude * np.sin(2 * np.pi * frequency * t)


def sine_near_resonance(
    amplitude: float, f1_hz: float, ratio: float = 0.95, duration: float = PAPER_DURATION, fs: float = PAPER_FS
) -> np.ndarray:
    """Sine of ``amplitude`` [N] at ``ratio * f1_hz`` [Hz]: the paper's 35 Hz
    test placed relative to a rig's first mode (just below it, ratio 0.95)."""
    if not (f1_hz > 0 and ratio > 0):
        raise ValueError(f"f1_hz and ratio must be positive, got {f1_hz}, {ratio}")
    return sine(amplitude, ratio * f1_hz, duration, fs)


def test_signal(
    kind: str, amplitude: float, fs: float = PAPER_FS, duration: float = PAPER_DURATION, **options
) -> np.ndarray:
    """The paper's excitation ``kind`` ('chirp' or 'sine') of ``amplitude`` [N]
    at ``fs`` [Hz] for ``duration`` [s]; ``options`` go to :func:`chirp` or :func:`sine`."""
    if kind == "chirp":
        return chirp(amplitude, duration=duration, fs=fs, **options)
    if kind == "sine":
        return sine(amplitude, duration=duration, fs=fs, **options)
    raise ValueError(f"unknown signal {kind!r}; signals are {SIGNALS}")


test_signal.__test__ = False  # not a pytest test


def rms(x) -> float:
    """Root mean square over the whole record."""
    x = np.asarray(x, dtype=float)
    return float(np.sqrt(np.mean(x * x)))


def noise_std(x, snr_db: float) -> float:
    """Standard deviation of white noise giving ``snr_db`` relative to the RMS of ``x``."""
    if not np.isfinite(snr_db):
        raise ValueError(f"snr_db must be finite, got {snr_db}")
    return rms(x) * 10.0 ** (-snr_db / 20.0)


def add_noise(x, snr_db: float | None, rng: np.random.Generator) -> np.ndarray:
    """``x`` plus white Gaussian noise of RMS ``rms(x) * 10**(-snr_db / 20)``.

    ``snr_db=None`` returns a copy of ``x`` without drawing.  The caller owns
    ``rng`` (a :class:`numpy.random.Generator`): same generator state, same
    noise, bit for bit.
    """
    x = np.asarray(x, dtype=float)
    if snr_db is None:
        return x.copy()
    return x + noise_std(x, snr_db) * rng.standard_normal(x.size)
