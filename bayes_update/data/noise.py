"""One noise estimate per record and channel (force and every sensor), from the
best source the record offers, saying which it used.

Sources, best first (:data:`METHODS`):

``declared``
    ``noise_sd`` in ``dataset.json`` (top level, overridden per test; see
    :mod:`bayes_update.data.folder`): a user who knows the sensors always wins.
``periods``
    repeated periods of a periodic excitation (``period_samples`` of the
    test, or a period found in the force): the period-to-period scatter
    after the transient, a linear trend removed per period
    (:mod:`bayes_update.data.periodic`).
``zero_input``
    stretches where the force is at its floor, after the free decay of the
    previous excitation has died out (:mod:`bayes_update.data.quiet`).
``quiet_band``
    the band from 3x the top of the excited band to 0.45 fs, where such a
    band exists and holds white noise (its level the same across it within
    3 dB: coloured noise's level there does not stand for the excited
    band's, and a record's harmonics change it too).
``fit_residual``
    the residual of a model-free linear fit (the local polynomial method,
    :mod:`bayes_update.data.lpm`) on the test with role ``linear`` (the
    low-level test, whose response is linear to well below the noise);
    sensors only.  It holds the response to the force's noise too: taken out
    when the force's noise is known, else kept (the detail says so, and it
    is then what the weights need: the force's noise counts as zero).
``carried``
    on any other test without a source of its own, or whose own source the
    record's harmonics or transient fill (its estimate more than twice the
    ``linear`` test's: a quiet band holding the high-level test's harmonics,
    periods of a response that does not repeat): the sensor's estimate on
    the ``linear`` test (sensor noise does not grow with the excitation
    level; nonlinear distortion does, and would count as noise in a fit
    residual of a high-level test).  Sensors only: the force is never carried.
``unknown``
    none of the above; ``sd`` is None (never a silent 0).  A response
    channel left unknown makes :func:`dataset_noise` raise
    :class:`NoiseEstimationError` saying what to add.

All sd are per sample, in the channel's unit (force [N], each sensor in its
kind's SI unit), of the noise over the recorded band.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from bayes_update.data.dataset import RESPONSE_UNITS, DatasetError
from bayes_update.data.lpm import lpm_noise, noise_from_fit_residual
from bayes_update.data.periodic import MIN_PERIODS, find_periods, period_noise
from bayes_update.data.quiet import MIN_TOTAL, band_noise, noise_band, quiet_sections, zero_input_noise

METHODS = ("declared", "periods", "zero_input", "quiet_band", "fit_residual", "carried", "unknown")


class NoiseEstimationError(DatasetError):
    """A response channel of a data set has no noise estimate; the message says what to add."""


@dataclass(frozen=True)
class NoiseEstimate:
    """The noise of one channel of one test.

    Attributes
    ----------
    sd : standard deviation per sample [channel unit], None when unknown.
    method : one of :data:`METHODS`.
    detail : what was used, in words (e.g. ``periods 2-6 of 1024 samples ...``,
        ``quiet band 250-450 Hz ...``) or, when unknown, why each source failed.
    dof : degrees of freedom behind ``sd`` (its relative sd is about
        1 / sqrt(2 dof) for white noise), None when not measured.
    spans : sample ranges ``((start, stop), ...)`` of the record used, if any.
    source_test : the test a ``carried`` estimate comes from.
    """

    sd: float | None
    method: str
    detail: str
    dof: float | None = None
    spans: tuple = ()
    source_test: str | None = None

    def __post_init__(self):
        if self.method not in METHODS:
            raise ValueError(f"unknown noise method {self.method!r}; methods are {METHODS}")
        if (self.sd is None) != (self.method == "unknown"):
            raise ValueError("sd is None exactly when the method is 'unknown'")

    @property
    def known(self) -> bool:
        return self.sd is not None

    def to_dict(self) -> dict:
        """``{"sd", "method", "detail"}`` (JSON-ready)."""
        return {"sd": self.sd, "method": self.method, "detail": self.detail}


def _estimate(method: str, result) -> NoiseEstimate:
    sd, dof, detail, spans = result
    return NoiseEstimate(sd, method, detail, dof, tuple(spans))


def from_fit_residual(residual, n_parameters: int, what: str = "the caller's fit") -> NoiseEstimate:
    """A ``fit_residual`` estimate from a fit's residual [response unit] and its
    number of fitted parameters (``||r|| / sqrt(n - p)``), e.g. a Volterra fit
    of orders 1-3 on the low-level test; the caller vouches that the fit is
    complete (all of the response but noise is in the model)."""
    sd, dof = noise_from_fit_residual(residual, n_parameters)
    return NoiseEstimate(sd, "fit_residual", f"residual of {what} ({int(n_parameters)} parameters)", dof)


def record_noise(
    record,
    fs: float | None = None,
    *,
    declared: dict | None = None,
    fit: bool = False,
    fit_residual: dict | None = None,
) -> dict:
    """``{channel: NoiseEstimate}`` for ``force`` and every sensor of ``record``
    (a :class:`bayes_update.data.dataset.Record`), from its own data only.

    Parameters
    ----------
    fs : sampling rate [Hz] (default: from the record's time column).
    declared : ``{channel: sd}`` declared for this test (default the
        record's own ``noise_sd``; :meth:`Dataset.declared_noise_sd` merges the
        data set's).
    fit : allow the ``fit_residual`` source for the sensors (only on a test
        whose response is linear: the low-level test): the LPM here.
    fit_residual : ``{sensor: NoiseEstimate}`` from the caller's own complete
        fit (:func:`from_fit_residual`), used at the ``fit_residual`` rank in
        place of the LPM (whatever ``fit``).

    A channel without a source is ``unknown`` (its detail says why); this
    function never raises for that (see :func:`dataset_noise`).
    """
    fs = float(record.sampling_rate_hz if fs is None else fs)
    declared = dict(record.noise_sd if declared is None else declared)
    force = np.asarray(record.force, float)
    layout = find_periods(force, record.period_samples)
    sections = quiet_sections(force, fs)
    band = noise_band(force, fs)
    out = {}
    for name in record.channels:
        x = force if name == "force" else record.channel(name)
        if name in declared:
            out[name] = NoiseEstimate(float(declared[name]), "declared", "declared in dataset.json (noise_sd)")
            continue
        why = []
        tries = [
            ("periods", layout, lambda lay: period_noise(x, lay)),
            ("zero_input", sections, lambda sec: zero_input_noise(x, sec, fs)),
            ("quiet_band", band, lambda b: band_noise(x, fs, b)),
        ]
        for method, found, measure in tries:
            result = found if isinstance(found, str) else measure(found)
            if not isinstance(result, str):
                out[name] = _estimate(method, result)
                break
            why.append(f"{method}: {result}")
        if name in out:
            if (
                out[name].method == "quiet_band"
                and fit
                and name != "force"
                and not (fit_residual and name in fit_residual)
            ):
                # the quiet band's white level stands for the record only if the noise is white:
                # where the model-free fit sees the noise inside the band too, they must agree
                out[name] = _white_or_fit(out[name], force, x, fs, out.get("force"))
        else:
            if fit_residual and name in fit_residual:
                out[name] = fit_residual[name]
                continue
            if fit and name != "force":
                try:
                    # the force's own noise, where known, is taken out of the fit's residual
                    known = out.get("force")
                    est = lpm_noise(force, x, fs, force_noise_sd=known.sd if known and known.known else None)
                    out[name] = NoiseEstimate(est.sd, "fit_residual", est.detail, est.dof)
                    continue
                except ValueError as exc:
                    why.append(f"fit_residual: {exc}")
            out[name] = NoiseEstimate(None, "unknown", "; ".join(why))
    return out


#: the quiet band and the model-free fit agree within this factor where the noise is white
COLOURED = 1.5
#: the words that mark an estimate taken over from the quiet band for coloured noise
COLOURED_WORDS = "coloured noise"


def _white_or_fit(band_est: NoiseEstimate, force, x, fs, force_est) -> NoiseEstimate:
    """The quiet band's estimate, or the fit residual's where they differ by more than
    :data:`COLOURED` (the noise is coloured: its level above the band does not stand
    for the record's, which the fit sees on every line)."""
    try:
        known = force_est if force_est is not None and force_est.known else None
        est = lpm_noise(force, x, fs, force_noise_sd=known.sd if known else None)
    except ValueError:
        return band_est
    ratio = est.sd / band_est.sd
    if 1.0 / COLOURED <= ratio <= COLOURED:
        return band_est
    return NoiseEstimate(
        est.sd,
        "fit_residual",
        f"{COLOURED_WORDS}: the quiet band's white level ({band_est.sd:.3g}, {band_est.detail}) is "
        f"{ratio:.3g}x below the fit's, which sees every line; {est.detail}"
        if ratio > 1
        else f"{COLOURED_WORDS}: the quiet band's white level ({band_est.sd:.3g}, {band_est.detail}) is "
        f"{1 / ratio:.3g}x above the fit's, which sees every line; {est.detail}",
        est.dof,
    )


def carried(estimate: NoiseEstimate, from_test: str, why: str = "") -> NoiseEstimate:
    """A known estimate of the same sensor on another test, carried to this one
    (``why``: the reason its own could not be used, to lead the detail)."""
    return NoiseEstimate(
        estimate.sd,
        "carried",
        f"{why}carried from test {from_test!r} ({estimate.method}: {estimate.detail})",
        estimate.dof,
        (),
        from_test,
    )


#: a sensor's own estimate on a test that is not the low-level one is the record's own content,
#: not noise, when it rose from the low-level test's by more than this factor times what the
#: force's own estimate rose (a sensor's noise does not grow with the level, or grows as the
#: force's does when noise is added in proportion to it; harmonics, distortion and transients
#: of the response grow faster)
CONTAMINATION = 2.0
#: the sources a test measures itself (not declared, carried or unknown)
OWN_METHODS = ("periods", "zero_input", "quiet_band", "fit_residual")


def _uncontaminated(dataset, out: dict) -> None:
    """Replace, on every test but the low-level ones, a sensor's own estimate that rose
    from the first ``linear`` test's own by more than :data:`CONTAMINATION` times the
    force's own rise with that test's, carried, the reason leading the detail (the
    issue's "noise that is noise").  Where the force's own noise is not known on both
    tests the rise cannot be judged and the test's own estimate is kept."""
    linear = [t.name for t in dataset.tests if t.role == "linear"]
    for name, _ in dataset.sensors:
        ref = next((s for s in linear if out[s][name].method in OWN_METHODS), None)
        if ref is None:
            continue
        base, force_base = out[ref][name], out[ref].get("force")
        for t in dataset.tests:
            est, force = out[t.name][name], out[t.name].get("force")
            if t.role == "linear" or est.method not in OWN_METHODS:
                continue
            if est.method == "quiet_band" and base.detail.startswith(COLOURED_WORDS):
                out[t.name][name] = carried(
                    base,
                    ref,
                    f"its quiet band ({est.sd:.3g}) reads coloured noise as white, as on the low-level test; ",
                )
                continue
            if not (
                force is not None
                and force_base is not None
                and force.known
                and force_base.known
                and force.method in OWN_METHODS
                and force_base.method in OWN_METHODS
            ):
                # without the force's own rise, a sensor noise added in proportion to the level cannot
                # be told from harmonics: the estimate stands on its source's own checks (a quiet
                # band's whiteness: harmonics filling it change its level across it)
                continue
            rise = max(1.0, force.sd / force_base.sd)
            if est.sd <= CONTAMINATION * rise * base.sd:
                continue
            forces = f" (the force's {rise:.3g}x)" if rise > 1 else ""
            why = (
                f"its own {est.method} estimate ({est.sd:.3g}: {est.detail}) is {est.sd / base.sd:.3g}x the "
                f"low-level test's{forces}: the record's "
                "harmonics, distortion or transient fill that source, and a sensor's noise does not grow "
                "with the response; "
            )
            out[t.name][name] = carried(base, ref, why)


def what_to_add(sensor: str, kind: str | None = None) -> str:
    """The sentence naming what a data set needs for ``sensor``'s noise."""
    unit = f" in {RESPONSE_UNITS[kind]}" if kind in RESPONSE_UNITS else ""
    return (
        f'declare noise_sd for sensor {sensor!r} in dataset.json (e.g. "noise_sd": '
        f'{{"{sensor}": <sd per sample{unit}>}}), or add period_samples to the test (a periodic '
        f"excitation with at least {MIN_PERIODS} periods, the first is dropped as a transient), or "
        f"record a quiet (zero-force) section of at least {MIN_TOTAL} samples after the response has "
        "died out, or add a low-level test with role 'linear' (its noise is carried to the others)"
    )


def dataset_noise(dataset, *, strict: bool = True, fit_residuals: dict | None = None) -> dict:
    """``{test name: {channel: NoiseEstimate}}`` for every test of a data set.

    Each test from its own data (:func:`record_noise`, the declared noise
    merged by :meth:`Dataset.declared_noise_sd`; ``fit_residual`` only on
    tests with role ``linear``); a sensor whose own estimate on another test
    exceeds the ``linear`` test's by more than :data:`CONTAMINATION` holds the
    record's harmonics or transient, not noise, and takes the ``linear``
    test's (``carried``, the reason in its detail); a sensor still unknown
    then takes its estimate on the first ``linear`` test that has one.

    strict : raise :class:`NoiseEstimationError` if a sensor of any test is
        still unknown (the message names each, why, and what to add);
        False leaves it ``unknown`` (for the inspection report).  The force
        may stay ``unknown`` either way.
    fit_residuals : ``{test name: {sensor: NoiseEstimate}}`` from the
        caller's own complete fits (:func:`from_fit_residual`), in place of
        the LPM on those tests.

    A command's first look and its problem ask for the same data set: the
    estimates are made once per data set content (:data:`CACHED_DATASETS`
    kept, by a digest of every sample and setting they read) and handed out
    as fresh dicts.
    """
    key = None if fit_residuals else _content_key(dataset)
    if key is not None and key in _ESTIMATES:
        _ESTIMATES.move_to_end(key)
        out = {t: dict(chans) for t, chans in _ESTIMATES[key].items()}
    else:
        out = _estimates(dataset, fit_residuals or {})
        if key is not None:
            _ESTIMATES[key] = {t: dict(chans) for t, chans in out.items()}
            while len(_ESTIMATES) > CACHED_DATASETS:
                _ESTIMATES.popitem(last=False)
    tests = {t.name: t for t in dataset.tests}
    missing = [
        (tests[name], ch, est.detail)
        for name, chans in out.items()
        for ch, est in chans.items()
        if not est.known and ch != "force"
    ]
    if strict and missing:
        kinds = dict(dataset.sensors)
        lines = [
            f"test {t.name!r} ({t.source or t.file}), sensor {name!r}: no noise estimate ({why}); "
            f"{what_to_add(name, kinds.get(name))}"
            for t, name, why in missing
        ]
        raise NoiseEstimationError(f"{dataset.source or dataset.name}: " + "\n".join(lines))
    return out


#: the estimates of the last data sets asked for, by their content: the first look (the inspection
#: report) and the problem of every command ask for the same data set's noise, estimated once
_ESTIMATES: OrderedDict = OrderedDict()
CACHED_DATASETS = 4


def _content_key(dataset) -> str:
    """A digest of everything :func:`dataset_noise` reads: the rate, each test's name, role,
    signal, level, sensors, period, declared noise and samples."""
    h = hashlib.blake2b(digest_size=20)
    h.update(repr(float(dataset.sampling_rate_hz)).encode())
    for t in dataset.tests:
        declared = sorted(dataset.declared_noise_sd(t).items())
        h.update(repr((t.name, t.role, t.signal, t.level, tuple(t.sensors), t.period_samples, declared)).encode())
        for a in (t.time, t.force, t.response):
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    return h.hexdigest()


def _estimates(dataset, fits: dict) -> dict:
    """Every test's estimates, contaminated ones and unknown sensors carried where a
    ``linear`` test has one (:func:`dataset_noise`)."""
    fs = float(dataset.sampling_rate_hz)
    out = {
        t.name: record_noise(
            t, fs, declared=dataset.declared_noise_sd(t), fit=t.role == "linear", fit_residual=fits.get(t.name)
        )
        for t in dataset.tests
    }
    _uncontaminated(dataset, out)
    linear = [t.name for t in dataset.tests if t.role == "linear"]
    for t in dataset.tests:
        for name, est in out[t.name].items():
            if est.known or name == "force":
                continue
            source = next(
                (s for s in linear if s != t.name and out[s][name].known and out[s][name].method != "carried"), None
            )
            if source is not None:
                out[t.name][name] = carried(out[source][name], source)
    return out
