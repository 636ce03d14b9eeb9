"""Validation of an updated model on the tests it was not updated on (paper
section 4.4): the medium chirp in the time domain, the sines by their PSDs.

Numbers, not only plots:

* ``rel_l2``: ||v_data - v_model|| / ||v_data|| of the sensor velocity
  (the record's noise alone gives about 10^(-SNR/20), 1 % at 40 dB);
* for sines, ``harmonics_db``: model minus data PSD level [dB] at 1x, 2x, 3x
  the excitation frequency (None where the data's harmonic does not rise
  10 dB above the PSD's median floor, i.e. is not measured), and ``psd_db_rms``: RMS of the dB
  difference of the two PSDs over the bins of 1-140 Hz where the data stand
  10 dB above their floor.
"""

from __future__ import annotations

import numpy as np

from bayes_update.core.metrics import relative_error
from bayes_update.data.dataset import Dataset
from bayes_update.data.spectral import psd

PSD_BAND_HZ = (1.0, 140.0)


def _harmonic_level(f, p, f0, k, half_width_hz=1.5):
    sel = np.abs(f - k * f0) <= half_width_hz
    return float(p[sel].max()) if sel.any() else float("nan")


def sine_frequency(test) -> float:
    """Excitation frequency of a sine test [Hz]: ``frequency_hz`` from the
    data set, else the force PSD's peak."""
    if "frequency_hz" in test.meta:
        return float(test.meta["frequency_hz"])
    f, p = psd(test.force, test.sampling_rate_hz)
    return float(f[np.argmax(p)])


def compare_test(test, simulated_velocity, fs: float) -> dict:
    """Agreement numbers of one test (see the module docstring)."""
    out = {
        "test": test.name,
        "signal": test.signal,
        "level": test.level,
        "rel_l2": relative_error(test.velocity, simulated_velocity),
    }
    if test.signal == "sine":
        f0 = sine_frequency(test)
        f, p_data = psd(test.velocity, fs)
        _, p_mod = psd(simulated_velocity, fs)
        floor = float(np.median(p_data[(f >= PSD_BAND_HZ[0]) & (f <= PSD_BAND_HZ[1])]))
        harm = {}
        for k in (1, 2, 3):
            d = _harmonic_level(f, p_data, f0, k)
            m = _harmonic_level(f, p_mod, f0, k)
            harm[f"{k}x"] = float(10 * np.log10(m / d)) if d > 10 * floor else None
        sel = (f >= PSD_BAND_HZ[0]) & (f <= PSD_BAND_HZ[1]) & (p_data > 10 * floor)
        diff = 10 * np.log10(p_mod[sel] / p_data[sel])
        out.update(frequency_hz=f0, harmonics_db=harm, psd_db_rms=float(np.sqrt(np.mean(diff**2))))
    return out


def validate(dataset: Dataset, beam, theta: dict, roles=("validation",)) -> dict:
    """Simulate each test whose role is in ``roles`` with ``beam`` (a model of the
    contract) at ``theta`` and compare it with the data.

    Returns ``{test name: numbers}`` plus the simulated velocities under
    ``"_velocity"`` (for plots).
    """
    fs = dataset.sampling_rate_hz
    out = {"_velocity": {}}
    for t in dataset.tests:
        if t.role in roles:
            v = np.asarray(beam.simulate(theta, t.force, fs), float)
            out[t.name] = compare_test(t, v, fs)
            out["_velocity"][t.name] = v
    return out
