"""Laboratory-like test records with known noise (a test helper: no tests here).

Built the way a laboratory acquires them, so that the noise estimators of
:mod:`bayes_update.data.noise` are checked against the noise sequences that
were really added:

* the structure: a 3-degree-of-freedom chain (ground - k1 - m1 - k2 - m2 - k3 -
  m3), 2 % modal damping, a cubic spring ``k_nl x1^3`` between the ground and
  mass 1, the force on mass 3; three accelerometers ``acc1..acc3`` [m/s^2] on
  the masses (modes at about 17.9, 45.5 and 70.1 Hz);
* the excitation: continuous-time random-phase multisines (a sum of cosines,
  exact at any instant): several periods of a periodic one (the first period
  is the structure's transient), or a "random" one whose period is twice the
  segment (it never repeats inside the record), separated by quiet (zero
  force) sections;
* the integration: classic RK4 at 16x the output rate, the force taken
  exactly at the half steps (no interpolation), compiled with numba;
* the acquisition: every channel through the same anti-alias FIR and 16:1
  decimation (``scipy.signal.resample_poly``), sampled at 2.5x the top of the
  excited band (200 Hz for 2-80 Hz: no quiet band above the excitation);
  the simulation starts before and ends after the record, so the filter's
  edges are outside it;
* then: coloured (first-order autoregressive, "pink-ish") noise on every
  sensor, the three sensors 10x apart, coloured noise on the force channel,
  a constant offset on every channel and a slow drift (a trend over the
  record) that differs between separately recorded tests.

Every random draw comes from ``numpy.random.default_rng(seed)`` of the
record.  The constants below are this module's own (nothing else in the
repository uses them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np
from scipy import linalg, signal

from bayes_update.data.dataset import Dataset, Record
from bayes_update.data.folder import write_dataset

LAB_MASSES_KG = (1.2, 0.8, 0.5)
LAB_STIFFNESS_N_M = (4.0e4, 6.0e4, 4.0e4)  # k1 (ground-m1), k2 (m1-m2), k3 (m2-m3)
LAB_DAMPING_RATIO = 0.02  # every mode
LAB_CUBIC_N_M3 = 7.5e8  # k_nl of the ground spring
LAB_FS_HZ = 200.0
LAB_BAND_HZ = (2.0, 80.0)  # fs = 2.5 x the band's top
LAB_OVERSAMPLING = 16
LAB_PERIOD_SAMPLES = 1024  # 5.12 s at 200 Hz
LAB_SENSORS = (("acc1", "acceleration"), ("acc2", "acceleration"), ("acc3", "acceleration"))
LAB_SENSOR_NOISE = (8.0e-3, 8.0e-3 * 10**0.5, 8.0e-2)  # sd [m/s^2]: 10x from first to last
LAB_SENSOR_NOISE_POLE = (0.6, 0.4, 0.75)  # AR(1) pole of each sensor's noise
LAB_FORCE_NOISE = 5.0e-4  # sd [N]
LAB_FORCE_NOISE_POLE = 0.3
LAB_OFFSETS = (0.05, 0.03, -0.04, 0.02)  # force [N], acc1..acc3 [m/s^2]
LAB_DRIFT = 5.0  # trend amplitude, in noise sd of its channel
LAB_PRE_ROLL_S = 0.5  # simulated at rest before the record, cut


def lab_modes() -> tuple[np.ndarray, np.ndarray]:
    """(natural frequencies [Hz], mode shapes (3, 3)) of the linear chain."""
    M, K = np.diag(LAB_MASSES_KG), _stiffness()
    w2, V = linalg.eigh(K, M)
    return np.sqrt(w2) / (2 * np.pi), V


def _stiffness() -> np.ndarray:
    k1, k2, k3 = LAB_STIFFNESS_N_M
    return np.array([[k1 + k2, -k2, 0.0], [-k2, k2 + k3, -k3], [0.0, -k3, k3]])


def _damping(ratio: float = LAB_DAMPING_RATIO) -> np.ndarray:
    """Modal damping ``ratio`` (default LAB_DAMPING_RATIO): C = M V diag(2 zeta w) V^T M (V mass-normalised)."""
    M = np.diag(LAB_MASSES_KG)
    f, V = lab_modes()
    return M @ V @ np.diag(2 * ratio * 2 * np.pi * f) @ V.T @ M


@numba.njit(cache=False)
def _acc(x, v, f, minv, C, K, knl, cq, b, out):
    """out = M^-1 (b f - C v - K x - (knl x1^3 + cq |v1| v1) e1) (3 degrees of freedom, written out;
    ``cq``: the optional quadratic damper beside the ground spring, 0 by default)."""
    r0 = b[0] * f - knl * x[0] ** 3 - cq * abs(v[0]) * v[0]
    r1 = b[1] * f
    r2 = b[2] * f
    for j in range(3):
        r0 -= C[0, j] * v[j] + K[0, j] * x[j]
        r1 -= C[1, j] * v[j] + K[1, j] * x[j]
        r2 -= C[2, j] * v[j] + K[2, j] * x[j]
    for i in range(3):
        out[i] = minv[i, 0] * r0 + minv[i, 1] * r1 + minv[i, 2] * r2


@numba.njit(cache=False)
def _rk4(minv, C, K, knl, cq, b, F, h):
    """RK4 of M a + C v + K x + (knl x1^3 + cq |v1| v1) e1 = b F(t) from rest; F on the half-step
    grid (F[2j] at step j); returns the accelerations at the steps, (n, 3)."""
    n = (F.size - 1) // 2 + 1
    out = np.zeros((n, 3))
    x, v = np.zeros(3), np.zeros(3)
    x2, v2, x3, v3, x4, v4 = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
    a1, a2, a3, a4 = np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3)
    _acc(x, v, F[0], minv, C, K, knl, cq, b, a1)
    out[0] = a1
    for j in range(n - 1):
        _acc(x, v, F[2 * j], minv, C, K, knl, cq, b, a1)
        for i in range(3):
            x2[i] = x[i] + 0.5 * h * v[i]
            v2[i] = v[i] + 0.5 * h * a1[i]
        _acc(x2, v2, F[2 * j + 1], minv, C, K, knl, cq, b, a2)
        for i in range(3):
            x3[i] = x[i] + 0.5 * h * v2[i]
            v3[i] = v[i] + 0.5 * h * a2[i]
        _acc(x3, v3, F[2 * j + 1], minv, C, K, knl, cq, b, a3)
        for i in range(3):
            x4[i] = x[i] + h * v3[i]
            v4[i] = v[i] + h * a3[i]
        _acc(x4, v4, F[2 * j + 2], minv, C, K, knl, cq, b, a4)
        for i in range(3):
            x[i] += h / 6.0 * (v[i] + 2 * v2[i] + 2 * v3[i] + v4[i])
            v[i] += h / 6.0 * (a1[i] + 2 * a2[i] + 2 * a3[i] + a4[i])
        _acc(x, v, F[2 * j + 2], minv, C, K, knl, cq, b, a1)
        for i in range(3):
            out[j + 1, i] = a1[i]
    return out


def multisine(n_half_steps_per_period: int, period_s: float, band_hz, rng) -> np.ndarray:
    """One period of a random-phase multisine with flat amplitudes on the
    lines k / period_s inside ``band_hz``, unit rms, sampled at
    ``n_half_steps_per_period`` points per period (exact: a finite Fourier sum)."""
    k = np.arange(int(np.ceil(band_hz[0] * period_s)), int(np.floor(band_hz[1] * period_s)) + 1)
    X = np.zeros(n_half_steps_per_period // 2 + 1, complex)
    X[k] = np.exp(2j * np.pi * rng.random(k.size))
    x = np.fft.irfft(X, n_half_steps_per_period)
    return x / np.sqrt(np.mean(x**2))


def coloured_noise(n: int, sd: float, pole: float, rng) -> np.ndarray:
    """Stationary AR(1) noise ``e[k] = pole e[k-1] + w[k]`` of standard deviation ``sd``
    (the theoretical one; the sequence's own sd differs by ~1/sqrt(n))."""
    burn = 400
    w = rng.standard_normal(n + burn) * np.sqrt(1.0 - pole**2)
    return sd * signal.lfilter([1.0], [1.0, -pole], w)[burn:]


@dataclass
class LabRecord:
    """One laboratory-like test with everything that went into it.

    force, response : the recorded channels ([N], (n, 3) [m/s^2]).
    force_noise, sensor_noise : the noise sequences added (exactly), (n,), (n, 3).
    offsets : constant offsets added, (4,) force then sensors.
    drift : the slow trends added, (n, 4) force then sensors.
    clean_force, clean_response : the anti-alias filtered, decimated noise-free channels.
    sections : [(kind, first sample, stop sample)] of the excitation ("quiet",
        "multisine", "random").
    period_samples : the multisine's period [samples], or None.
    """

    file: str
    role: str
    signal: str
    level: str
    fs: float
    time: np.ndarray
    force: np.ndarray
    response: np.ndarray
    force_noise: np.ndarray
    sensor_noise: np.ndarray
    offsets: np.ndarray
    drift: np.ndarray
    clean_force: np.ndarray
    clean_response: np.ndarray
    sections: list
    period_samples: int | None = None
    meta: dict = field(default_factory=dict)

    @property
    def noise_sd(self) -> dict:
        """The sd of the noise actually added, per channel: ``{"force": ..., "acc1": ...}``."""
        out = {"force": float(np.std(self.force_noise))}
        out.update({n: float(np.std(self.sensor_noise[:, j])) for j, (n, _) in enumerate(LAB_SENSORS)})
        return out

    def section(self, kind: str) -> list:
        return [(a, b) for k, a, b in self.sections if k == kind]

    def record(self, declare_period: bool = True, noise_sd: dict | None = None) -> Record:
        """The :class:`Record` a reader would give (``period_samples`` declared if asked)."""
        return Record(
            self.file,
            self.signal,
            self.level,
            self.role,
            self.time,
            self.force,
            self.response,
            dict(self.meta),
            sensors=LAB_SENSORS,
            period_samples=self.period_samples if declare_period else None,
            noise_sd=dict(noise_sd or {}),
        )


def lab_record(
    file: str,
    role: str,
    level_n: float,
    segments,
    *,
    seed: int,
    level: str = "",
    fs: float = LAB_FS_HZ,
    band_hz=LAB_BAND_HZ,
    period_samples: int = LAB_PERIOD_SAMPLES,
    sensor_noise=LAB_SENSOR_NOISE,
    force_noise: float = LAB_FORCE_NOISE,
    white: bool = False,
    offsets=LAB_OFFSETS,
    drift: float = LAB_DRIFT,
    cubic: float = LAB_CUBIC_N_M3,
    damping_ratio: float = LAB_DAMPING_RATIO,
    quadratic_damping: float = 0.0,
) -> LabRecord:
    """A recorded test: ``segments`` is a list of ``("quiet", seconds)``,
    ``("multisine", n_periods)`` (of ``period_samples`` samples each) or
    ``("random", seconds)``; ``level_n`` [N] is the rms of the excited
    segments' force.  ``white``: white instead of coloured noise on every
    channel.  ``drift``: amplitude of each channel's slow trend in units of
    that channel's noise sd (a per-test random shape, so tests drift apart).
    ``damping_ratio``: the modal damping of every mode.  ``quadratic_damping``
    [N s^2/m^2]: a damper ``c2 |v1| v1`` beside the ground spring (damping that
    grows with amplitude, which real joints show); 0 (off) by default, so that the
    default records are exactly those of the noise tests."""
    rng = np.random.default_rng(seed)
    q = LAB_OVERSAMPLING
    h = 1.0 / (q * fs)
    pre = int(round(LAB_PRE_ROLL_S * fs))
    pieces, sections, n_rec = [np.zeros(2 * pre * q)], [], 0
    signal_kind = "multisine"
    for kind, size in segments:
        if kind == "quiet":
            n = int(round(size * fs))
            x = np.zeros(2 * n * q)
        elif kind == "multisine":
            n = int(size) * period_samples
            x = np.tile(multisine(2 * q * period_samples, period_samples / fs, band_hz, rng), int(size))
        elif kind == "random":
            n = int(round(size * fs))
            x = multisine(4 * q * n, 2 * n / fs, band_hz, rng)[: 2 * q * n]
            signal_kind = "random"
        else:
            raise ValueError(f"unknown segment kind {kind!r}")
        pieces.append(level_n * x if kind != "quiet" else x)
        sections.append((kind, n_rec, n_rec + n))
        n_rec += n
    pieces.append(np.zeros(2 * pre * q + 1))
    F = np.concatenate(pieces)
    minv = np.linalg.inv(np.diag(LAB_MASSES_KG))
    b = np.array([0.0, 0.0, 1.0])
    acc = _rk4(minv, _damping(float(damping_ratio)), _stiffness(), float(cubic), float(quadratic_damping), b, F, h)
    fine = np.column_stack([F[::2], acc])
    rec = signal.resample_poly(fine, 1, q, axis=0)[pre : pre + n_rec]
    clean_force, clean_response = rec[:, 0], rec[:, 1:]
    sds = np.array([force_noise, *sensor_noise], float)
    poles = np.zeros(4) if white else np.array([LAB_FORCE_NOISE_POLE, *LAB_SENSOR_NOISE_POLE])
    noise = np.column_stack([coloured_noise(n_rec, s, p, rng) for s, p in zip(sds, poles)])
    t = np.arange(n_rec) / fs
    u = t / t[-1]
    shapes = [0.6 * (u - 0.5) + 0.4 * np.sin(2 * np.pi * (0.7 * u + rng.random())) for _ in range(4)]
    trend = drift * sds * np.column_stack(shapes)
    offs = np.asarray(offsets, float) * (1.0 + 0.5 * rng.standard_normal(4))  # differs per test
    measured = rec + noise + offs + trend
    return LabRecord(
        file,
        role,
        signal_kind,
        level or file.split(".")[0],
        fs,
        t,
        measured[:, 0],
        measured[:, 1:],
        noise[:, 0],
        noise[:, 1:],
        offs,
        trend,
        clean_force,
        clean_response,
        sections,
        period_samples if any(k == "multisine" for k, _ in segments) else None,
        meta={"force_rms_n": level_n},
    )


# -------------------------------------------------------------------- the usual tests
MULTISINE_LAYOUT = [("quiet", 2.0), ("multisine", 6), ("quiet", 6.0)]
RANDOM_LAYOUT = [("random", 40.0)]


def periodic_test(seed: int = 11, level_n: float = 0.5, **options) -> LabRecord:
    """Quiet lead-in 2 s, 6 periods of a multisine (5.12 s each), quiet tail 6 s."""
    return lab_record("multisine_low.csv", "linear", level_n, MULTISINE_LAYOUT, seed=seed, level="low", **options)


def random_tests(seed: int = 23, low_n: float = 0.5, high_n: float = 4.0, **options) -> list:
    """A low-level (role linear) and a high-level (role nonlinear) random test of
    40 s each, without periods or quiet sections."""
    return [
        lab_record("random_low.csv", "linear", low_n, RANDOM_LAYOUT, seed=seed, level="low", **options),
        lab_record("random_high.csv", "nonlinear", high_n, RANDOM_LAYOUT, seed=seed + 1, level="high", **options),
    ]


def lab_dataset(records, noise_sd: dict | None = None, declare_period: bool = True) -> Dataset:
    """A :class:`Dataset` of lab records (the truth of the noise in ``extra['truth']``)."""
    truth = {
        "note": "tests/lab_records.py: sd of the noise sequences added",
        "noise_sd": {r.file: r.noise_sd for r in records},
    }
    return Dataset(
        "lab-chain",
        records[0].fs,
        None,
        [r.record(declare_period) for r in records],
        {"truth": truth},
        noise_sd=dict(noise_sd or {}),
    )


def write_lab_dataset(records, folder, noise_sd: dict | None = None, declare_period: bool = True):
    """Write the records as a data-set folder (:func:`bayes_update.data.folder.write_dataset`)."""
    return write_dataset(lab_dataset(records, noise_sd, declare_period), folder)
