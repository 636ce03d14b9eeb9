"""The modes a test shows, estimated once: what the first look reports and what
the calibration's basis is built on are one estimate.

A command reads a data set twice: its first look (``inspection.json``) and its
problem, whose Kautz basis takes the poles of the ``linear`` test.  Both call
:func:`linear_modes` on the same samples, prepared the same way
(:func:`without_offsets`), so :func:`volterra.estimate_modes` runs once per
record content (:data:`CACHED_RECORDS` kept, by a digest of the samples and
settings) and the modes the first look shows are the ones the basis starts from
(the basis then polishes them on the record's linear fit,
:meth:`volterra.KautzBasis.from_estimate`).

Frequencies Hz, damping ratios [-].
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

import volterra
from bayes_update.data.quiet import excited_band

__all__ = ["CACHED_RECORDS", "find_modes", "linear_modes", "without_offsets"]

#: the estimates of the last records asked for, by content (the first look and the problem ask alike;
#: a campaign's tests and a model's responses to them: a few kB each)
CACHED_RECORDS = 32
_ESTIMATES: OrderedDict = OrderedDict()


def without_offsets(force, response, remove: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Fresh float copies of a record's force (n,) and response (n,) or (n, n_sensors),
    each channel's mean removed when ``remove`` (a record's mean is a sensor offset,
    not physics).  The one preparation the first look and the problem share, so that
    both hand :func:`linear_modes` the same samples."""
    force, response = np.array(force, float), np.array(response, float)
    if remove:
        force -= force.mean()
        response -= response.mean(axis=0)
    return force, response


def linear_modes(force, response, fs: float, period_samples=None, n_modes=None) -> volterra.ModalEstimate:
    """:func:`volterra.estimate_modes` of a record in the band its force excites
    (:func:`bayes_update.data.quiet.excited_band`), poles refined on the modal fit:
    the estimate a basis is built on.  ``force`` (n,), ``response`` (n,) or
    (n, n_sensors) as they are (prepare them with :func:`without_offsets`);
    ``period_samples`` [samples] (default: found in the force); ``n_modes``: that
    many modes, the most energetic.  Made once per content; the result is shared,
    do not modify it.  Raises :class:`volterra.PoleEstimationError` (a
    ValueError) when no mode is found."""
    u, y = np.asarray(force, float), np.asarray(response, float)
    key = _key(u, y, fs, period_samples, n_modes)
    if key in _ESTIMATES:
        _ESTIMATES.move_to_end(key)
        return _ESTIMATES[key]
    est = volterra.estimate_modes(
        u, y, fs, f_range=excited_band(u, fs), n_modes=n_modes, refine=True, period_samples=period_samples
    )
    _ESTIMATES[key] = est
    while len(_ESTIMATES) > CACHED_RECORDS:
        _ESTIMATES.popitem(last=False)
    return est


def find_modes(force, response, fs: float, period_samples=None, n_modes=None, remove_offsets: bool = True) -> list:
    """``[(freq_hz, damping_ratio), ...]`` of every mode a record shows in the band
    it excites, sorted by frequency: :func:`linear_modes` (the estimate
    ``calibrate``'s basis starts from; period-synchronous spectra when the force
    repeats, with ``period_samples`` or without) on the record without its
    offsets (``remove_offsets``, as the problem prepares it); ``n_modes``: that
    many, the most energetic (a high-level test's equivalent linear modes, where
    its distortion would read as more).  Raises :class:`volterra.PoleEstimationError`
    (a ValueError) when no mode is found."""
    u, y = without_offsets(force, response, remove_offsets)
    est = linear_modes(u, y, fs, period_samples, n_modes)
    return sorted((float(p.freq_hz), float(p.damping_ratio)) for p in est.poles)


def _key(u, y, fs, period_samples, n_modes) -> str:
    h = hashlib.blake2b(digest_size=20)
    as_int = [None if v is None else int(v) for v in (period_samples, n_modes)]
    h.update(repr((float(fs), *as_int, u.shape, y.shape)).encode())
    for a in (u, y):
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()
