"""What a data set holds, before any model sees it: the data side of
``bayes-update inspect --data DIR --out OUT`` (the figures are
:mod:`bayes_update.reports.inspection`).

:func:`inspect_dataset` returns a JSON-ready dict (``inspection.json``):

``tests.<file>``
    ``role``, ``signal``, ``level``, ``n_samples``, ``duration_s``;
    ``excited_band_hz`` [lo, hi]; ``period_samples`` (declared, or found in
    the force; None); ``noise.<channel>`` = ``{"sd", "method", "detail"}``
    for ``force`` and every sensor (:func:`bayes_update.data.noise.dataset_noise`,
    not strict: a channel may be ``unknown``); ``offset.<channel>`` [unit],
    ``drift.<channel>`` [share of rms], ``clipping.<channel>``
    (:mod:`bayes_update.data.checks`); ``coherence.<sensor>`` = the median
    coherence over the excited band and the share of its lines below 0.9;
    ``distortion`` (a periodic record: :func:`volterra.distortion`, what its
    unexcited lines hold beyond the noise, odd and even, per sensor and for the
    force; a sine sweep: :func:`volterra.sweep_distortion`, the same numbers from
    its odd and even harmonics, with ``sweep`` in place of ``periods``;
    ``{"not_read": why}`` where it cannot be read; None for another record).
``modes``
    ``[{"freq_hz", "damping_ratio"}, ...]`` of the (first) ``linear`` test,
    every sensor sharing the poles (:func:`find_modes`); ``modes_from`` its file.
``level_dependence``
    one entry per mode, ``{"freq_hz": {file: f}, "damping_ratio": {file: z}}``
    over the tests whose excited band holds the mode and whose mode found
    lies within 20 % of it.
``warnings``
    plain sentences: offsets, drifts, clipping, coherence loss, noise that
    is unknown, large or differs between tests, modes not found, a linear
    test that distorts.

Frequencies Hz, damping ratios [-], sd and offsets in each channel's unit.
"""

from __future__ import annotations

import numpy as np

import volterra
from bayes_update.data import checks, spectral
from bayes_update.data.modes import find_modes
from bayes_update.data.noise import dataset_noise
from bayes_update.data.periodic import PeriodLayout, find_periods
from bayes_update.data.quiet import excited_band, quiet_sections
from volterra.sweep_distortion import record_distortion

#: warn above these: offset / rms, drift (share of rms), noise / rms, noise ratio between tests
OFFSET_WARN = 0.05
DRIFT_WARN = 0.05
NOISE_WARN = 0.1
NOISE_SPREAD_WARN = 2.0
#: coherence: a line is "lost" below COHERENCE_LOW; warn when more than COHERENCE_SHARE of the band is
COHERENCE_LOW = 0.9
COHERENCE_SHARE = 0.2
#: a test's mode belongs to the linear test's mode within this relative frequency distance
MODE_MATCH = 0.2
#: a 'linear' test whose unexcited lines hold distortion above this share of its output [dB] warns
LINEAR_DISTORTION_DB = -30.0
TRANSIENT_SIGNALS = ("chirp", "sweep", "burst", "impact", "hammer")


def _detrended(x) -> np.ndarray:
    x = np.asarray(x, float)
    t = np.arange(x.size)
    return x - np.polyval(np.polyfit(t, x, 1), t)


def is_transient(record, fs: float) -> bool:
    """A test that starts and ends at rest (a chirp, a burst, a multisine between
    quiet sections): its FRF is taken from the whole record."""
    if any(s in record.signal.lower() for s in TRANSIENT_SIGNALS):
        return True
    sections = quiet_sections(record.force, fs)
    if isinstance(sections, str):
        return False
    ends = 2 * max(16, int(0.1 * fs))
    return sections[0][0] <= ends and sections[-1][1] >= record.n_samples - ends


def periodic_frf(record, sensor: str, layout: PeriodLayout) -> spectral.FRFEstimate:
    """H1 and coherence of a periodic test at its excited lines, averaged over the
    periods after the first (a transient): ``S_uy = mean_j conj(U_j) Y_j`` etc.,
    the coherence over the periods (1 without noise, even for a nonlinear
    structure: its distortion repeats too)."""
    fs, N = record.sampling_rate_hz, layout.period
    a = layout.start + N
    P = layout.n_periods - 1
    u = _detrended(record.force)[a : a + P * N].reshape(P, N)
    y = _detrended(record.channel(sensor))[a : a + P * N].reshape(P, N)
    U, Y = np.fft.rfft(u, axis=1), np.fft.rfft(y, axis=1)
    s_uu, s_yy = np.mean(np.abs(U) ** 2, axis=0), np.mean(np.abs(Y) ** 2, axis=0)
    s_uy = np.mean(np.conj(U) * Y, axis=0)
    k = np.flatnonzero(s_uu > 1e-4 * s_uu[1:].max())
    k = k[k > 0]
    scale = 2.0 / (fs * N)
    coh = np.clip(np.abs(s_uy[k]) ** 2 / (s_uu[k] * s_yy[k]), 0.0, 1.0)
    return spectral.FRFEstimate(
        np.fft.rfftfreq(N, 1.0 / fs)[k],
        s_uy[k] / s_uu[k],
        coh,
        scale * s_uu[k],
        scale * s_yy[k],
        scale * s_uy[k],
        P,
        f"periodic: {P} periods of {N} samples, excited lines only",
    )


def frf(record, sensor: str, fs: float) -> spectral.FRFEstimate:
    """H1 and coherence from the force to ``sensor`` (channels detrended): over
    the periods of a periodic test (:func:`periodic_frf`);
    :func:`spectral.transient_frf` for a test that starts and ends at rest
    (:func:`is_transient`); else Welch (Hann, 7 half-overlapping segments)."""
    layout = find_periods(record.force, record.period_samples)
    if isinstance(layout, PeriodLayout):
        return periodic_frf(record, sensor, layout)
    u, y = _detrended(record.force), _detrended(record.channel(sensor))
    if is_transient(record, fs):
        return spectral.transient_frf(u, y, fs)
    return spectral.frf_h1(u, y, fs, nperseg=volterra.frf.default_nperseg(u.size))


def _period(record):
    layout = find_periods(record.force, record.period_samples)
    return layout.period if isinstance(layout, PeriodLayout) else None


def _distortion(record, fs, warnings) -> dict | None:
    """:func:`volterra.record_distortion` of a periodic record or a sweep (JSON-ready; None for another record,
    or where it cannot be read, with the reason), and a warning where a test of role
    'linear' shows distortion above :data:`LINEAR_DISTORTION_DB` of its output."""
    try:
        d = record_distortion(
            record.force, record.response, fs, record.period_samples, sensors=[n for n, _ in record.sensors]
        )
    except ValueError as exc:
        return {"not_read": str(exc)}
    if d is None:
        return None
    if record.role == "linear":
        for name, classes in d.sensors.items():
            loud = {
                c: r["level_db"] for c, r in classes.items() if r["detected"] and r["level_db"] > LINEAR_DISTORTION_DB
            }
            if loud:
                what = ", ".join(f"{c} lines {v:.0f} dB" for c, v in loud.items())
                warnings.append(
                    f"test {record.file} (role linear), sensor {name!r}: distortion ({what} "
                    "of the output): the linear test is not linear at its level; a lower level, or the "
                    "nonlinearity in the model's first stage"
                )
    return d.to_dict()


def _test_entry(record, fs, noise, warnings) -> dict:
    band = excited_band(record.force, fs)
    entry = {
        "name": record.name,
        "role": record.role,
        "signal": record.signal,
        "level": record.level,
        "n_samples": record.n_samples,
        "duration_s": record.n_samples / fs,
        "excited_band_hz": [band[0], band[1]],
        "period_samples": _period(record),
        "noise": {ch: est.to_dict() for ch, est in noise.items()},
        "offset": {},
        "drift": {},
        "clipping": {},
        "coherence": {},
        "distortion": _distortion(record, fs, warnings),
    }
    units = record.units
    for ch in record.channels:
        x = record.force if ch == "force" else record.channel(ch)
        off, dr, clip = checks.offset(x), checks.drift(x, fs, band[0]), checks.clipping(x)
        # None (JSON null): too short for two trend windows of two cycles of the lowest line
        entry["offset"][ch], entry["drift"][ch], entry["clipping"][ch] = off, None if np.isnan(dr) else dr, clip
        rms = float(np.std(x))
        where = f"test {record.file}, channel {ch!r}"
        if rms > 0 and abs(off) > OFFSET_WARN * rms:
            warnings.append(
                f"{where}: an offset of {off:.4g} {units[ch]} ({abs(off) / rms:.0%} of its rms); "
                "it is removed before any fit, but check the sensor's zero"
            )
        if dr > DRIFT_WARN:
            warnings.append(
                f"{where}: drifts by {dr:.0%} of its rms over the record (a slow trend); "
                "check the sensor's conditioning (AC coupling, temperature)"
            )
        if clip["clipped"]:
            warnings.append(
                f"{where}: clipped ({clip['longest_run']} consecutive samples at its max or min); "
                "the test is not usable as recorded, repeat it with a larger range"
            )
        est = noise[ch]
        if not est.known:
            what = "cannot be estimated" if ch == "force" else "is unknown"
            warnings.append(f"{where}: the noise {what} ({est.detail})")
        elif rms > 0 and est.sd > NOISE_WARN * rms:
            warnings.append(
                f"{where}: the noise ({est.sd:.3g} {units[ch]}, {est.method}) is {est.sd / rms:.0%} "
                "of the channel's rms"
            )
    for name, _ in record.sensors:
        est = frf(record, name, fs)
        sel = est.band(*band) & np.isfinite(est.coherence)
        coh = est.coherence[sel]
        med = float(np.median(coh)) if coh.size else float("nan")
        low = float(np.mean(coh < COHERENCE_LOW)) if coh.size else float("nan")
        entry["coherence"][name] = {"median_in_band": med, "share_below_0.9": low}
        if coh.size and low > COHERENCE_SHARE:
            warnings.append(
                f"test {record.file}, sensor {name!r}: coherence below {COHERENCE_LOW} on {low:.0%} "
                f"of the excited band (median {med:.2f}): noise, nonlinearity, or a channel that does "
                "not follow the force"
            )
    return entry


def level_dependence(
    dataset, modes, warnings: list | None = None, remove_offsets: bool = True, modes_from: str | None = None
) -> list:
    """Each of ``modes`` ``[(f_hz, zeta), ...]`` (the linear test's) as every test of ``dataset``
    shows it: ``[{"freq_hz": {test file: f}, "damping_ratio": {test file: zeta}}, ...]``, the
    equivalent linear modes :func:`find_modes` reads from each test whose excited band holds the
    mode, each matched to the nearest of ``modes``; a test where none is found adds a line to
    ``warnings``; ``remove_offsets``: as :func:`find_modes`; ``modes_from``: the name of the
    test ``modes`` were read from (its entries are ``modes``, not estimated again)."""
    fs = float(dataset.sampling_rate_hz)
    warnings = [] if warnings is None else warnings
    out = [{"freq_hz": {}, "damping_ratio": {}} for _ in modes]
    for t in dataset.tests:
        lo, hi = excited_band(t.force, fs)
        inside = [i for i, (f, _) in enumerate(modes) if lo <= f <= hi]
        if not inside:
            continue
        if t.name == modes_from:
            for i, (f, z) in enumerate(modes):
                out[i]["freq_hz"][t.file], out[i]["damping_ratio"][t.file] = f, z
            continue
        try:
            # as many modes as the linear test has in this test's band: a strong nonlinearity's
            # distortion would read as more (its equivalent linear modes are what moves with level)
            found = find_modes(t.force, t.response, fs, t.period_samples, len(inside), remove_offsets)
        except ValueError:
            try:
                # fewer stable clusters than that (a mode damped 5x by the level): every mode the
                # test shows, each matched to the linear test's nearest (the GVT-like wing's high
                # level: 5 clusters asked 6, all six found this way, its joint mode at 5.3 %)
                found = find_modes(t.force, t.response, fs, t.period_samples, None, remove_offsets)
            except ValueError as exc:
                warnings.append(f"test {t.file}: no mode found ({exc})")
                continue
        # each found mode to one linear mode at most, the closest pairs first (relative distance):
        # a sweep that shows 8.05 Hz but not 6.94 Hz gave the 8.05 to both modes near it
        pairs = sorted(
            (abs(m[0] - modes[i][0]) / modes[i][0], i, j)
            for i in inside
            for j, m in enumerate(found)
            if abs(m[0] - modes[i][0]) <= MODE_MATCH * modes[i][0]
        )
        taken_i, taken_j = set(), set()
        for _, i, j in pairs:
            if i in taken_i or j in taken_j:
                continue
            taken_i.add(i)
            taken_j.add(j)
            out[i]["freq_hz"][t.file], out[i]["damping_ratio"][t.file] = found[j]
    return out


def _noise_spread(dataset, noise, warnings) -> None:
    own = ("periods", "zero_input", "quiet_band", "fit_residual")
    for name, kind in dataset.sensors:
        sds = {t.file: noise[t.name][name] for t in dataset.tests}
        sds = {f: e for f, e in sds.items() if e.method in own}
        if len(sds) < 2:
            continue
        hi, lo = max(sds, key=lambda f: sds[f].sd), min(sds, key=lambda f: sds[f].sd)
        if sds[hi].sd > NOISE_SPREAD_WARN * sds[lo].sd:
            warnings.append(
                f"sensor {name!r}: its noise differs {sds[hi].sd / sds[lo].sd:.1f}x between tests "
                f"({hi}: {sds[hi].method}, {lo}: {sds[lo].method}); a sensor's noise does not grow "
                "with the level: check these tests (a transient or distortion counted as noise, or "
                "noise that was added in proportion to the level)"
            )


def inspect_dataset(dataset, noise: dict | None = None, remove_offsets: bool = True) -> dict:
    """The inspection of a data set (module docstring), JSON-ready.

    noise : the result of :func:`bayes_update.data.noise.dataset_noise` if
        already computed (default: computed here, not strict).
    remove_offsets : the modes are read with each channel's mean removed, as a
        problem prepares its records (False: as recorded, for a model whose
        records carry no offset, the beam's virtual rig); the first look and the
        calibration's basis then share one estimate (:mod:`bayes_update.data.modes`)."""
    fs = float(dataset.sampling_rate_hz)
    for t in dataset.tests:
        checks.require_live_force(t)
    noise = dataset_noise(dataset, strict=False) if noise is None else noise
    warnings = []
    tests = {t.file: _test_entry(t, fs, noise[t.name], warnings) for t in dataset.tests}
    _noise_spread(dataset, noise, warnings)
    linear = dataset.by_role("linear")
    modes, modes_from, dependence = [], None, []
    if not linear:
        warnings.append("no test has role 'linear': no modes are reported (they come from the low-level test)")
    else:
        ref = linear[0]
        modes_from = ref.file
        try:
            modes = find_modes(ref.force, ref.response, fs, ref.period_samples, None, remove_offsets)
        except ValueError as exc:
            warnings.append(f"test {ref.file}: no mode found ({exc})")
        dependence = level_dependence(dataset, modes, warnings, remove_offsets, ref.name)
    return {
        "dataset": dataset.name,
        "source": dataset.source,
        "sampling_rate_hz": fs,
        "sensors": [{"name": n, "response": k, "unit": dataset.units[n]} for n, k in dataset.sensors],
        "tests": tests,
        "modes": [{"freq_hz": f, "damping_ratio": z} for f, z in modes],
        "modes_from": modes_from,
        "level_dependence": dependence,
        "warnings": warnings,
    }
