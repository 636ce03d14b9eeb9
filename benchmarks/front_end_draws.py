"""One seeded record of the front-end corpus: :func:`draw` (a data set and its truth).

A record is a small data set (``bayes_update.data.dataset.Dataset``): a
low-level test with role ``linear``, and for the nonlinear class a
high-level test (role ``nonlinear``) too.  Its class (:data:`CLASSES`) names
the structure (``front_end_systems``); the rest is drawn for every record:

* excitation: periodic multisine (3-8 periods; the first a transient unless
  the record starts in steady state; the period declared in half of them;
  quiet lead-in and tail in some), Gaussian random noise (recorded from rest
  or in steady state), a linear or logarithmic sweep and its free decay,
  bursts of noise with free decays;
* band: top 20-2000 Hz, bottom 5-40 % of it; fs 2.5-50x the top;
* sensors: 1-3, each displacement, velocity or acceleration;
* noise: 20-60 dB below each channel's rms in the low-level test, white or
  coloured (AR(1), low-pass, pink), on the force too; the same sd in every
  test of the record (a sensor's noise does not grow with the level);
* offsets on every channel in half the records, slow drifts in a third.

Record lengths follow the lightest damped mode's decay time tau (a periodic
record's period 8-16 tau, a random record 40-100 tau, ...); at most
:data:`MAX_SAMPLES` samples (:data:`MAX_SAMPLES_ODE` for the classes solved
by solve_ivp): fs is lowered towards 2.5x the band, and only then the
lightest dampings raised, to fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import front_end_signals as sig
import front_end_systems as sysm
import numpy as np

from bayes_update.data.dataset import Dataset, Record

CLASSES = ("sdof_ode", "modal", "close_pair", "beam", "plate", "lumped", "nonlinear")
EXCITATIONS = ("periodic", "random", "sweep", "burst")
EXCITATION_P = (0.4, 0.25, 0.2, 0.15)
MAX_SAMPLES = 1 << 17
MAX_SAMPLES_ODE = 1 << 14
FINE = 16  # the generator's oversampling of the record's rate (linear systems)
FINE_ODE = 8  # ... for solve_ivp
PAD = 64  # samples simulated past the record's end (the anti-alias FIR's edge)
#: a mode's peak is clear when its own response at resonance has this many times the noise's power
#: there on its best sensor (per line; the force's noise through the FRF included)
CLEAR_PEAK = 10.0

#: the low-level test's displacement rms as a share of each form's scale: the describing-function
#: change of the mode it causes is under a tenth of the tolerances (0.05 % in frequency, 1.5 % in
#: damping): cubic 3/2 (x/s)^2, Bouc-Wen's hysteretic damping about 0.1 x/s, the friction's
#: (v/v0)^2, the clearance none below the gap
LOW_LEVEL = {"linear": 0.01, "cubic": 0.01, "quadratic": 0.01, "bouc_wen": 2e-4, "friction": 0.02, "clearance": 0.1}
#: the high-level test's displacement rms over the scale (by the linearised response)
HIGH_LEVEL = {
    "cubic": (0.2, 0.6),
    "quadratic": (0.2, 0.6),
    "bouc_wen": (0.5, 3.0),
    "friction": (5.0, 20.0),
    "clearance": (0.5, 2.0),
}


@dataclass
class Truth:
    """What the front end should find: ``modes`` [(f Hz, zeta)] in the band and ``outside``
    those out of it (of the linear test; the linearisation for the nonlinear class),
    ``band`` (lo, hi) Hz of the excitation, ``noise`` {test: {channel: sd}} as added,
    ``period`` {test: samples, or None}, and the draw's ``details``."""

    modes: list
    outside: list
    band: tuple
    noise: dict
    period: dict
    details: dict = field(default_factory=dict)


def _loguniform(rng, lo, hi, size=None):
    return np.exp(rng.uniform(np.log(lo), np.log(hi), size))


def _kinds(rng, n):
    return tuple(str(k) for k in rng.choice(sysm.KINDS, size=n))


def _spread(rng, n, lo, hi, zeta, gap):
    """n sorted frequencies in (lo, hi) with neighbours more than ``gap`` x (zeta_i f_i + zeta_j f_j) apart."""
    for _ in range(500):
        f = np.sort(_loguniform(rng, lo, hi, n))
        if n == 1 or np.all(np.diff(f) > gap * (zeta[:-1] * f[:-1] + zeta[1:] * f[1:])):
            return f
    return None


# ---------------------------------------------------------------- systems
def _modal(rng, cls, band, kinds):
    lo, hi = band
    m = int(rng.integers(1, 9)) if cls == "modal" else int(rng.integers(2, 7))
    z = _loguniform(rng, 0.002, 0.1, m)
    pair = cls == "close_pair"
    while True:  # as many modes as the band holds apart, down to one (plus the pair)
        f = _spread(rng, m - pair, lo * 1.15, hi / (1.3 if pair else 1.15), z[: m - pair], 8.0 if pair else 4.0)
        if f is not None or m == 1 + pair:
            break
        m -= 1
    if f is None:
        f = np.array([np.sqrt(lo * hi)])
        z[0] = min(z[0], 0.02)
    z = z[:m]
    if pair:
        # a close pair (1.3-3 half-power bandwidths apart: resolvable, barely) among separated modes
        i = int(rng.integers(0, m - 1))
        z[i] = min(z[i], 0.03)
        zp, g = z[i] * _loguniform(rng, 0.7, 1.4), rng.uniform(1.3, 3.0)
        fp = f[i] * (1 + g * z[i]) / (1 - g * zp)  # fp - f_i = g (zeta_i f_i + zeta_p fp)
        f, z = np.insert(f, i + 1, fp), np.insert(z[:-1], i + 1, zp)
    if rng.uniform() < 0.6:  # modes outside the band: residual terms
        f_out = np.concatenate(
            [
                lo * _loguniform(rng, 0.2, 0.8, int(rng.integers(0, 3))),
                hi * _loguniform(rng, 1.2, 3.0, int(rng.integers(1, 4))),
            ]
        )
        f = np.concatenate([f, f_out])
        z = np.concatenate([z, _loguniform(rng, 0.005, 0.05, f_out.size)])
    return sysm.modal_draw(f, z, rng, len(kinds), kinds, complex_modes=bool(rng.uniform() < 0.5)), band


_CANTILEVER = np.array([1.8751, 4.6941, 7.8548, 10.9955] + [(j - 0.5) * np.pi for j in range(5, 31)]) ** 2


def _beam(rng, band, kinds):
    lo, _ = band
    support = str(rng.choice(["pinned", "cantilever"]))
    ratio = np.arange(1, 31.0) ** 2 if support == "pinned" else _CANTILEVER / _CANTILEVER[0]
    first, n_in = int(rng.integers(0, 3)), int(rng.integers(1, 9))
    f1 = lo * _loguniform(rng, 1.15, 1.6) / ratio[first]
    top, nxt = f1 * ratio[first + n_in - 1], f1 * ratio[first + n_in]
    hi = min(np.sqrt(top * nxt), top * 1.5)
    z = np.clip(_loguniform(rng, 0.002, 0.05) * (ratio / ratio[first]) ** rng.uniform(-0.3, 0.3), 0.002, 0.1)
    lin = sysm.beam(rng, 30, f1, support, rng.uniform(0.05, 0.95), rng.uniform(0.05, 0.95, len(kinds)), kinds, z)
    return lin, (lo, hi)


def _plate(rng, band, kinds):
    lo, _ = band
    aspect = rng.uniform(1.0, 1.5)
    z0 = _loguniform(rng, 0.002, 0.03)
    pts = rng.uniform(0.1, 0.9, (len(kinds) + 1, 2)) * [1.0, aspect]
    lin = sysm.plate(
        aspect, 7, lo * _loguniform(rng, 1.15, 1.5), pts[0], pts[1:], kinds, lambda f: z0 * np.ones_like(f)
    )
    n_in = int(rng.integers(1, 9))
    top, nxt = lin.freq_hz[n_in - 1], lin.freq_hz[n_in]
    return lin, (lo, min(np.sqrt(top * nxt), top * 1.5))


def _lumped(rng, band, kinds):
    lo, _ = band
    n_dof = int(rng.integers(2, 9))
    dofs = rng.integers(0, n_dof, len(kinds) + 1)
    lin = sysm.lumped(rng, n_dof, lo * _loguniform(rng, 1.2, 2.0), (0.002, 0.08), int(dofs[0]), dofs[1:], kinds)
    n_in = int(rng.integers(1, n_dof + 1))
    f = np.sort(lin.freq_hz)
    top = f[n_in - 1]
    hi = min(np.sqrt(top * f[n_in]), top * 1.5) if n_in < n_dof else top * 1.3
    return lin, (lo, hi)


def _system(rng, cls, band):
    """(system, sensor kinds, band): the band may be redrawn so that it ends between two modes."""
    lo, hi = band
    if cls in ("sdof_ode", "nonlinear"):
        kinds = _kinds(rng, 1)
        form = "linear" if cls == "sdof_ode" else str(rng.choice(sysm.NONLINEAR_FORMS))
        zeta = _loguniform(rng, 0.002, 0.1) if cls == "sdof_ode" else _loguniform(rng, 0.005, 0.08)
        system = sysm.NonlinearSDOF(
            float(_loguniform(rng, 0.1, 10.0)),
            float(_loguniform(rng, lo * 1.3, hi / 1.3)),
            float(zeta),
            form,
            1e-3,
            kinds[0],
        )
        return system, kinds, band
    kinds = _kinds(rng, int(rng.integers(1, 4)))
    if cls in ("modal", "close_pair"):
        lin, band = _modal(rng, cls, band, kinds)
    elif cls == "beam":
        lin, band = _beam(rng, band, kinds)
    elif cls == "plate":
        lin, band = _plate(rng, band, kinds)
    elif cls == "lumped":
        lin, band = _lumped(rng, band, kinds)
    else:
        raise ValueError(f"unknown class {cls!r}; classes are {CLASSES}")
    return lin, kinds, band


# ------------------------------------------------------------ excitation
def _excitation(rng, kind, fs, R, band, n_target, tau, f_lo):
    """(u_fine of n + PAD record samples, n, period or None, leading samples simulated before
    the record, meta): the record is u_fine[pre * R:] cut to n samples."""
    if kind == "periodic":
        P = int(max(rng.uniform(8, 16) * tau, 20 / f_lo) * fs)
        n_per = int(rng.integers(3, 9))
        steady = rng.uniform() < 0.3  # recorded after the transient has died out
        lead = int(rng.uniform(0.1, 0.5) * P) if (not steady and rng.uniform() < 0.3) else 0
        tail = int(8 * tau * fs) if lead else 0
        pre = (int(np.ceil(8 * tau * fs / P)) * P) if steady else 0
        total = pre // P + n_per + (1 if not tail else 0)
        u, _ = sig.periodic_multisine(rng, fs, R, band, P, total, lead=0, tail=0)
        u = np.concatenate([np.zeros(lead * R), u, np.zeros((tail + PAD) * R)])
        n = lead + n_per * P + tail
        return u, n, P, pre, {"periods": n_per, "steady": bool(steady), "lead": lead, "tail": tail}
    if kind == "random":
        steady = rng.uniform() < 0.5
        pre = int(10 * tau * fs) if steady else 0
        n = n_target
        return sig.random_noise(rng, fs, R, band, pre + n + PAD), n, None, pre, {"steady": bool(steady)}
    if kind == "sweep":
        decay = rng.uniform(2, 10) * tau  # at rest at the end, or not quite
        n = int(n_target + decay * fs)
        on = n_target / n
        log = bool(rng.uniform() < 0.5)
        u = sig.sweep(rng, fs, R, band, n + PAD, on * n / (n + PAD), log)
        return u, n, None, 0, {"log": log, "decay_tau": float(decay / tau)}
    if kind == "burst":
        frames = int(rng.integers(3, 9))
        frame = int(max(rng.uniform(8, 16) * tau, 20 / f_lo) * fs)
        on = rng.uniform(0.3, 0.7)
        n = frames * frame
        u = np.concatenate([sig.bursts(rng, fs, R, band, n, frames, on), np.zeros(PAD * R)])
        return u, n, None, 0, {"frames": frames, "on": float(on)}
    raise ValueError(kind)


def _budget(kind, tau, f_lo):
    """Record length [s] the excitation asks for (before the sample limit)."""
    if kind == "periodic":
        return 8 * max(16 * tau, 20 / f_lo)
    if kind == "random":
        return max(100 * tau, 200 / f_lo)
    if kind == "sweep":
        return max(40 * tau, 40 / f_lo) + 10 * tau
    return 8 * max(16 * tau, 20 / f_lo)


# ---------------------------------------------------------------- draw
def draw(seed: int, cls: str | None = None):
    """(Dataset, Truth) of record ``seed`` (its class ``CLASSES[seed % 7]`` unless given)."""
    rng = np.random.default_rng([seed, 40])
    cls = CLASSES[seed % len(CLASSES)] if cls is None else cls
    kind = str(rng.choice(EXCITATIONS, p=EXCITATION_P))
    f_hi = float(_loguniform(rng, 20.0, 2000.0))
    system, kinds, band = _system(rng, cls, (f_hi * rng.uniform(0.05, 0.4), f_hi))
    ode = isinstance(system, sysm.NonlinearSDOF)
    lin = system.linearised() if ode else system
    R, n_max = (FINE_ODE, MAX_SAMPLES_ODE) if ode else (FINE, MAX_SAMPLES)
    inband = (lin.freq_hz >= band[0]) & (lin.freq_hz <= band[1])
    tau = float(np.max(1 / (lin.zeta * 2 * np.pi * lin.freq_hz)[inband]))
    fs = float(band[1] * _loguniform(rng, 2.5, 50.0))
    seconds = _budget(kind, tau, band[0])
    if seconds * fs > n_max:  # lower fs first, then the lightest dampings
        fs = max(2.5 * band[1], n_max / seconds)
        if seconds * fs > n_max:
            tau_max = tau * n_max / (seconds * fs)
            zeta = np.maximum(lin.zeta, 1 / (tau_max * 2 * np.pi * lin.freq_hz))
            system, lin = _with_damping(system, lin, zeta)
            tau = tau_max
    if not ode:
        # modes the generator's own grid cannot carry (the fine rate's Nyquist aliases them back
        # into the band: an analog anti-alias filter never lets a lab's sensor see them) are cut
        system = lin = _truncated(lin, 0.25 * fs * R)
    n_target = int(min(n_max, _budget(kind, tau, band[0]) * fs) * (0.5 if kind == "sweep" else 1.0))
    tests, noise, effective, period, details = (
        [],
        {},
        {},
        {},
        {"class": cls, "excitation": kind, "fs": fs, "kinds": list(kinds), "tau_s": tau},
    )
    sensors = tuple((f"{k[:3]}{i}", k) for i, k in enumerate(kinds))
    levels = [("low", "linear")] + ([("high", "nonlinear")] if cls == "nonlinear" else [])
    snr = rng.uniform(20, 60, len(kinds) + 1)
    colour = [str(rng.choice(sig.NOISE_COLOURS)) if rng.uniform() < 0.5 else "white" for _ in snr]
    offsets, drifts = rng.uniform() < 0.5, rng.uniform() < 1 / 3
    declare = bool(rng.uniform() < 0.5)
    sds = None
    for level, role in levels:
        u, n, P, pre, meta = _excitation(rng, kind, fs, R, band, n_target, tau, band[0])
        scale = _force_scale(rng, system, lin, u, R, fs, level)
        clean = _simulate(system, scale * u, R, fs)
        clean = clean[pre : pre + n]
        if sds is None:  # the noise of each channel: the low test's rms / SNR
            sds = np.std(clean, axis=0) * 10 ** (-snr / 20)
        meas = clean.copy()
        added = np.zeros_like(clean)
        for c in range(meas.shape[1]):
            added[:, c] = sig.measurement_noise(rng, n, sds[c], colour[c])
            meas[:, c] += added[:, c]
            rms = np.std(clean[:, c])
            if offsets:
                meas[:, c] += rng.uniform(-2, 2) * rms
            if drifts:
                meas[:, c] += sig.drift(rng, n, rng.uniform(1, 10) * sds[c])
        name = f"{kind}_{level}"
        resp = meas[:, 1] if len(kinds) == 1 else meas[:, 1:]
        tests.append(
            Record(
                f"{name}.csv",
                kind,
                level,
                role,
                np.arange(n) / fs,
                meas[:, 0],
                resp,
                sensors=sensors,
                period_samples=P if (P and declare) else None,
            )
        )
        noise[name] = dict(zip(("force",) + tuple(s for s, _ in sensors), map(float, sds)))
        # what a fit driven by the measured force cannot tell from a sensor's noise: its own and the
        # (linearised) structure's response to the force's noise in the excited band (outside it the
        # fit does not follow the force, and sees the sensor's noise alone)
        spec = np.fft.rfft(added[:, 0])
        fk = np.fft.rfftfreq(n, 1.0 / fs)
        spec[(fk < band[0]) | (fk > band[1])] = 0.0
        through = lin.respond(np.fft.irfft(spec, n), 1.0 / fs)
        effective[name] = {s: float(np.std(added[:, 1 + j] - through[:, j])) for j, (s, _) in enumerate(sensors)}
        period[name] = P if (P and (n - meta.get("lead", 0) - meta.get("tail", 0)) // P >= 3) else None
        details[name] = {**meta, "force_rms": float(np.std(clean[:, 0]))}
        if level == "low":
            clarity = _clarity(lin, clean, added, fs, band)
    details.update(
        snr_db=snr.tolist(),
        colour=colour,
        offsets=bool(offsets),
        drifts=bool(drifts),
        declared_period=declare,
        form=getattr(system, "form", None),
    )
    f, z = lin.freq_hz, lin.zeta
    inband = (f >= band[0]) & (f <= band[1])
    order = np.argsort(f)
    details["clarity"] = [float(clarity[i]) for i in order if inband[i]]
    details["effective_noise"] = effective
    truth = Truth(
        [(float(f[i]), float(z[i])) for i in order if inband[i]],
        [(float(f[i]), float(z[i])) for i in order if not inband[i]],
        (float(band[0]), float(band[1])),
        noise,
        period,
        details,
    )
    return Dataset(f"corpus-{seed}", fs, None, tests), truth, lin


def _clarity(lin, clean, noise, fs, band):
    """Per mode (lin's order): the largest over the sensors of the power its own part of the
    response has at its resonance over the noise there (the sensor's, and the force's through
    the FRF), from Welch PSDs of the clean force and of the noise added."""
    from scipy.signal import welch

    nper = min(clean.shape[0], 8192)
    f, s_uu = welch(clean[:, 0], fs, nperseg=nper)
    _, s_nn = welch(noise, fs, nperseg=nper, axis=0, detrend="linear")
    out = []
    for k, fk in enumerate(lin.freq_hz):
        if not band[0] <= fk <= band[1]:
            out.append(0.0)
            continue
        part = _mode_part(lin, k, fk)
        total = lin.frf([fk])[0]
        j = np.argmin(np.abs(f - fk))
        ratio = s_uu[j] * np.abs(part) ** 2 / (s_nn[j, 1:] + np.abs(total) ** 2 * s_nn[j, 0])
        out.append(float(np.max(ratio)))
    return np.array(out)


def _mode_part(lin, k, fk):
    """Mode k's own part of every sensor's FRF at fk [Hz]."""
    one = sysm.Linear(lin.lam[k : k + 1], lin.residues[k : k + 1], lin.kinds)
    return one.frf([fk])[0]


def _truncated(lin, f_max):
    keep = lin.freq_hz < f_max
    return sysm.Linear(lin.lam[keep], lin.residues[keep], lin.kinds)


def _with_damping(system, lin, zeta):
    if isinstance(system, sysm.NonlinearSDOF):
        s = sysm.NonlinearSDOF(system.mass, system.freq_hz, float(zeta[0]), system.form, system.scale, system.kind)
        return s, s.linearised()
    w = np.abs(lin.lam)
    lam = -zeta * w + 1j * w * np.sqrt(1 - zeta**2)
    new = sysm.Linear(lam, lin.residues * (lin.lam.imag / lam.imag)[:, None], lin.kinds)
    return new, new


def _force_scale(rng, system, lin, u, R, fs, level):
    """Force rms [N]: any for a linear system; for the nonlinear class, the one that puts the
    linearised displacement at the level's share of the nonlinearity's scale."""
    if not isinstance(system, sysm.NonlinearSDOF):
        return float(_loguniform(rng, 0.1, 100.0))
    disp = sysm.Linear(lin.lam, lin.residues, ("displacement",)).respond(u, 1 / (fs * R))
    share = LOW_LEVEL[system.form] if level == "low" else _loguniform(rng, *HIGH_LEVEL[system.form])
    return float(share * system.scale / np.std(disp))


def _simulate(system, u_fine, R, fs):
    """(n, 1 + S): the acquired force and responses (anti-alias FIR, R:1), from rest."""
    y = system.respond(u_fine, 1.0 / (fs * R))
    out = sig.acquire(np.column_stack([u_fine, y]), R)
    return out[: out.shape[0] - PAD]
