"""Where do the model and the data disagree?  Diagnostics after an update.

:func:`diagnose` compares the data with the model at given parameters (for
example the posterior mean) four ways, the first step of the discrepancy
workflow (naming the missing effect and re-updating follow in a later
release):

* **by test**: velocity relative L2 for every test, whatever its role;
* **by kernel order**: the residual (data - model) of each chirp test
  decomposed in the data set's Kautz basis under the test's recorded force;
  its y1, y2 and y3 parts relative to the data's norm.  A missing symmetry
  breaker (a bow) shows in y2, a missing stiffness or mass in y1, missing
  nonlinear damping in y3;
* **by frequency**: the sine tests' harmonics 1x, 2x, 3x (amplitude of a
  least-squares sine/cosine fit over the second half of the record, where
  the transient has died), data against model in dB;
* **by amplitude**: the free decay after each chirp's sweep, band-passed
  around the first mode; Hilbert envelope and instantaneous frequency give
  the damping ratio and the frequency in amplitude bins, data against model.
  Amplitude-dependent damping shows as a damping ratio that changes with
  amplitude in the data and not in the model.

Units: velocities [m/s], frequencies [Hz], damping ratios [-], levels [dB].
"""

from __future__ import annotations

import numpy as np
from scipy import signal as ss

import volterra
from bayes_update.core.basis import basis_from_reference
from bayes_update.core.metrics import relative_error
from bayes_update.data.dataset import Dataset

HARMONICS = (1, 2, 3)


def harmonic_amplitudes(x, fs: float, f0: float, harmonics=HARMONICS) -> dict:
    """{k: amplitude of the k f0 component} [units of x] over the second half of x."""
    x = np.asarray(x, float)
    n = x.size // 2
    t = np.arange(n) / fs
    seg = x[-n:]
    cols = [np.ones(n)]
    for k in harmonics:
        w = 2 * np.pi * k * f0 * t
        cols += [np.sin(w), np.cos(w)]
    coef = np.linalg.lstsq(np.column_stack(cols), seg, rcond=None)[0]
    return {k: float(np.hypot(coef[1 + 2 * i], coef[2 + 2 * i])) for i, k in enumerate(harmonics)}


def decay_curve(v, fs: float, f1: float, t_start: float, n_bins: int = 6) -> dict:
    """Damping ratio and frequency against amplitude in a free decay.

    The record after ``t_start`` [s] is band-passed (4th order Butterworth,
    0.7-1.3 f1, zero phase); the Hilbert envelope A(t) and phase give, per
    amplitude bin (log-spaced between 90 % and 10 % of the initial envelope),
    zeta = -d ln A / dt / (2 pi f) and f = d phase / dt / (2 pi)."""
    v = np.asarray(v, float)
    i0 = int(round(t_start * fs))
    if v.size - i0 < int(0.5 * fs):
        raise ValueError("the free decay is shorter than 0.5 s")
    sos = ss.butter(4, [0.7 * f1, 1.3 * f1], btype="band", fs=fs, output="sos")
    x = ss.sosfiltfilt(sos, v)[i0:]
    z = ss.hilbert(x)
    env = np.abs(z)
    phase = np.unwrap(np.angle(z))
    t = np.arange(x.size) / fs
    trim = int(0.1 * fs)  # the filter's and the transform's edges
    env, phase, t = env[trim:-trim], phase[trim:-trim], t[trim:-trim]
    a0 = env[: int(0.05 * fs)].mean()
    edges = a0 * np.geomspace(0.9, 0.1, n_bins + 1)
    amp, zeta, freq = [], [], []
    for hi, lo in zip(edges[:-1], edges[1:]):
        sel = (env <= hi) & (env > lo)
        if sel.sum() < int(0.05 * fs):
            continue
        idx = np.flatnonzero(sel)
        tt = t[idx]
        slope = np.polyfit(tt, np.log(env[idx]), 1)[0]
        w = np.polyfit(tt, phase[idx], 1)[0]
        amp.append(float(np.sqrt(hi * lo)))
        freq.append(float(w / (2 * np.pi)))
        zeta.append(float(-slope / w))
    return {"amplitude": np.array(amp), "zeta": np.array(zeta), "freq_hz": np.array(freq)}


def diagnose(dataset: Dataset, beam, theta: dict, basis: volterra.KautzBasis | None = None) -> dict:
    """The four diagnostics of the module docstring for ``beam`` (a model of the
    contract whose response is the sensor velocity) at ``theta``, as a
    JSON-ready dict (arrays as lists) plus ``_velocity`` {test: model velocity}."""
    fs = dataset.sampling_rate_hz
    lin = dataset.by_role("linear")
    if basis is None:
        if not lin:
            raise ValueError("no test has role 'linear': pass the Kautz basis explicitly")
        basis = basis_from_reference(lin[0].force, lin[0].velocity, fs, feedthrough=())
    f1 = basis.pole(1).freq_hz
    out = {"by_test": {}, "by_order": {}, "by_frequency": {}, "by_amplitude": {}, "f1_hz": f1, "_velocity": {}}
    for t in dataset.tests:
        v = np.asarray(beam.simulate(theta, t.force, fs), float)
        out["_velocity"][t.name] = v
        out["by_test"][t.name] = {
            "role": t.role,
            "signal": t.signal,
            "level": t.level,
            "rel_l2": relative_error(t.velocity, v),
        }
        if t.signal == "chirp":
            proj = volterra.VolterraProjector(t.force, basis)
            res = proj.components(t.velocity - v)
            norm = np.linalg.norm(t.velocity)
            out["by_order"][t.name] = {f"y{n}": float(np.linalg.norm(res[n]) / norm) for n in res}
            sweep = float(t.meta.get("sweep_time_s", 2.0))
            try:
                dd = decay_curve(t.velocity, fs, f1, sweep + 0.05)
                dm = decay_curve(v, fs, f1, sweep + 0.05)
            except ValueError:
                continue
            out["by_amplitude"][t.name] = {
                "data": {k: a.tolist() for k, a in dd.items()},
                "model": {k: a.tolist() for k, a in dm.items()},
            }
        elif t.signal == "sine":
            f0 = float(t.meta.get("frequency_hz", 35.0))
            hd = harmonic_amplitudes(t.velocity, fs, f0)
            hm = harmonic_amplitudes(v, fs, f0)
            noise = _noise_amplitude(t.velocity, fs, f0)
            out["by_frequency"][t.name] = {
                f"{k}x": {
                    "data": hd[k],
                    "model": hm[k],
                    "difference_db": float(20 * np.log10(hm[k] / hd[k])) if hd[k] > 0 and hm[k] > 0 else None,
                    "data_above_noise": bool(hd[k] > 3 * noise),
                }
                for k in HARMONICS
            }
    return out


def _noise_amplitude(x, fs, f0) -> float:
    """Amplitude a sinusoid fit picks up from the record's broadband noise:
    the fit at a frequency between harmonics (1.5 f0)."""
    return harmonic_amplitudes(x, fs, 1.5 * f0, harmonics=(1,))[1]


def diagnostics_figure(diag: dict):
    """Four panels: by test, by order, by frequency, by amplitude."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 8), constrained_layout=True)
    (a1, a2), (a3, a4) = fig.subplots(2, 2)
    names = list(diag["by_test"])
    a1.bar(range(len(names)), [100 * diag["by_test"][n]["rel_l2"] for n in names], color="C0")
    a1.set_xticks(range(len(names)), names, rotation=30, fontsize=8)
    a1.set_ylabel("velocity rel. L2, data - model [%]")
    a1.set_title("by test")
    chirps = list(diag["by_order"])
    for i, n in enumerate(chirps):
        vals = [100 * diag["by_order"][n][k] for k in ("y1", "y2", "y3")]
        a2.bar(np.arange(3) + 0.8 * i / max(len(chirps), 1), vals, width=0.8 / max(len(chirps), 1), label=n)
    a2.set_xticks(range(3), ["y1", "y2", "y3"])
    a2.set_ylabel("residual share of the data [%]")
    a2.set_title("by kernel order (chirp tests)")
    a2.legend(fontsize=7)
    sines = list(diag["by_frequency"])
    for i, n in enumerate(sines):
        d = [diag["by_frequency"][n][f"{k}x"]["difference_db"] or 0.0 for k in HARMONICS]
        a3.bar(np.arange(3) + 0.8 * i / max(len(sines), 1), d, width=0.8 / max(len(sines), 1), label=n)
    a3.axhline(0, color="k", lw=0.5)
    a3.set_xticks(range(3), [f"{k}x" for k in HARMONICS])
    a3.set_ylabel("model - data [dB]")
    a3.set_title("by frequency (sine harmonics)")
    if sines:
        a3.legend(fontsize=7)
    for i, (n, d) in enumerate(diag["by_amplitude"].items()):
        a4.semilogx(d["data"]["amplitude"], 100 * np.array(d["data"]["zeta"]), "o-", color=f"C{i}", label=f"{n} data")
        a4.semilogx(
            d["model"]["amplitude"], 100 * np.array(d["model"]["zeta"]), "x--", color=f"C{i}", label=f"{n} model"
        )
    a4.set_xlabel("envelope amplitude [m/s]")
    a4.set_ylabel("damping ratio [%]")
    a4.set_title("by amplitude (free decay after the sweep)")
    a4.legend(fontsize=7)
    return fig
