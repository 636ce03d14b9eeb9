"""The virtual test rig and the embedded default data set.

We have no access to the paper's measurements, so the product ships a
*virtual rig*: the FE model of :mod:`fe` at given true parameters, run finer
than the updating model (no inverse crime), with measurement noise on both
channels, producing records in the same structure as real measurements.

What the virtual rig does (:class:`VirtualRig`)
-----------------------------------------------
1. The force is defined at ``fs_fine = oversampling * fs`` (4 x 1024 =
   4096 Hz) and the FE model (``n_elements = 2 x DEFAULT_ELEMENTS = 20``,
   ``substeps = DEFAULT_SUBSTEPS = 4`` per fine sample, i.e. 16 generalized-
   alpha steps per 1/1024 s: 4x the updating model's) is run at ``fs_fine``.
   The run goes on a little past the record (the filter's half length) so
   that the filter sees no artificial end; before t = 0 the rig is at rest.
2. Force and velocity are low-pass filtered and decimated to ``fs`` (1024 Hz)
   by a linear-phase FIR (161 taps, Kaiser beta 8, cutoff 0.39 fs = 400 Hz at 1024 Hz;
   flat to 1e-4 dB below 300 Hz, -73 dB at 464 Hz, below -96 dB from 512 Hz
   up) whose delay is compensated (zero phase; ``scipy.signal.resample_poly``).
3. White Gaussian noise is added to each channel at an SNR [dB] relative to
   the channel's RMS over the record (defaults 40 dB both: noise RMS 1 % of
   the signal RMS; a load cell and a laser vibrometer behind a 24-bit
   acquisition do better, but 1 % also stands for what a real record has and
   the model lacks, and it is the level the Volterra defaults were tuned
   for).  The noise comes from ``numpy.random.Generator(PCG64)`` seeded with
   ``SeedSequence(seed, spawn_key=(test index,))``: same seed, same bytes.
   The recorded force is the filtered true force plus noise; the updating
   model is driven by that recorded force, as in a real test.
4. Effects from :mod:`fe` (e.g. ``InitialImperfection``) can be switched on;
   they show only in the ``truth`` block, never to the updating side.

The default data set (the paper-equivalent rig)
-----------------------------------------------
``Rig(bending_stiffness_factor=1.24)`` (the paper's hexahedral mesh is 24 %
too stiff in bending, docs/design.md#mesh-locking-and-the-bending-stiffness-factor) at the
paper's Table 3 values
(eta = 3 MPa s, c = 15 N s/mm, F = 77 N, k_s = 180 N/mm): f1 = 37.13 Hz,
zeta1 = 1.31 %, so the 35 Hz sine sits at 0.943 f1.  Six tests of 4 s at
1024 Hz: chirp 20 -> 50 Hz during 2 s then free decay, and 35 Hz sine, each
at three levels (:data:`CHIRP_LEVELS_N`, :data:`SINE_LEVELS_N`).  Levels were
chosen by their nonlinear share, measured on the noise-free rig output with
``benchmarks/rig_levels.py`` (numbers in :data:`LEVEL_NOTES`).
``bayes-update make-dataset`` regenerates it bit for bit;
:func:`load_default_dataset` reads the embedded copy.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy import signal as ss

import fe
from bayes_update.data import signals
from bayes_update.data.dataset import Dataset, Record
from bayes_update.data.folder import write_dataset
from bayes_update.models.beam.default_dataset import (
    DEFAULT_DATASET_DIR,
    default_dataset_path,
    load_default_dataset,
    truth_paper_units,
)
from bayes_update.models.beam.paper_tests import (
    CHIRP_LEVELS_N,
    LEVEL_NOTES,
    PAPER_TESTS,
    ROLES_BY_TEST,
    SINE_LEVELS_N,
    TestSpec,
)
from fe.model import DEFAULT_ELEMENTS, DEFAULT_RHO_INF, DEFAULT_SUBSTEPS

__all__ = [
    "CHIRP_LEVELS_N",
    "DATASET_NAME",
    "DECIMATION_CUTOFF",
    "DECIMATION_KAISER_BETA",
    "DECIMATION_TAPS",
    "DEFAULT_DATASET_DIR",
    "DEFAULT_OVERSAMPLING",
    "DEFAULT_SEED",
    "DEFAULT_SNR_DB",
    "LEVEL_NOTES",
    "PAPER_EQUIVALENT_RIG",
    "PAPER_TESTS",
    "ROLES_BY_TEST",
    "SINE_LEVELS_N",
    "TestSpec",
    "VirtualRig",
    "default_dataset_path",
    "load_default_dataset",
    "make_dataset",
    "noise_generator",
    "truth_paper_units",
]


PAPER_EQUIVALENT_RIG = fe.Rig(bending_stiffness_factor=1.24)
"""The rig of the embedded data set: the paper's geometry with EI x 1.24."""

DEFAULT_SEED = 2017
DEFAULT_SNR_DB = 40.0
DEFAULT_OVERSAMPLING = 4
DATASET_NAME = "buckled-beam-virtual-rig"

DECIMATION_TAPS = 161
DECIMATION_KAISER_BETA = 8.0
DECIMATION_CUTOFF = 0.390625  # fraction of the output sampling rate (400 Hz at 1024 Hz)


@dataclass(frozen=True)
class VirtualRig:
    """A virtual test rig: FE model at true parameters, finer than the updating
    model, filtered, decimated and noisy (see the module docstring).

    Parameters
    ----------
    rig : geometry/material (default: the paper-equivalent rig, factor 1.24).
    truth : true parameters (SI; default: the paper's Table 3).
    effects : :mod:`fe` effects switched on (hidden from the updating side).
    n_elements : FE elements (default 2 x DEFAULT_ELEMENTS).
    substeps : generalized-alpha steps per *fine* sample (default
        DEFAULT_SUBSTEPS; with ``oversampling`` 4 that is 4x the updating
        model's steps per output sample).
    oversampling : fine rate / output rate.
    rho_inf : generalized-alpha spectral radius.
    fs : output sampling rate [Hz].
    snr_force_db, snr_velocity_db : noise levels [dB re channel RMS]; None
        for no noise on that channel.
    """

    rig: fe.Rig = PAPER_EQUIVALENT_RIG
    truth: fe.Parameters = field(default_factory=fe.Parameters)
    effects: tuple = ()
    n_elements: int = 2 * DEFAULT_ELEMENTS
    substeps: int = DEFAULT_SUBSTEPS
    oversampling: int = DEFAULT_OVERSAMPLING
    rho_inf: float = DEFAULT_RHO_INF
    fs: float = signals.PAPER_FS
    snr_force_db: float | None = DEFAULT_SNR_DB
    snr_velocity_db: float | None = DEFAULT_SNR_DB

    def __post_init__(self):
        object.__setattr__(self, "effects", tuple(self.effects))
        if int(self.oversampling) != self.oversampling or self.oversampling < 1:
            raise ValueError(f"oversampling must be a positive integer, got {self.oversampling}")
        if not (self.fs > 0 and math.isfinite(self.fs)):
            raise ValueError(f"fs must be a positive sampling rate in Hz, got {self.fs}")
        for name in ("snr_force_db", "snr_velocity_db"):
            v = getattr(self, name)
            if v is not None and not math.isfinite(v):
                raise ValueError(f"{name} must be finite or None, got {v}")
        self.model  # validates mesh, substeps, effects

    @functools.cached_property
    def model(self) -> fe.BeamModel:
        """The FE model the rig runs (at ``fs_fine``)."""
        return fe.BeamModel(
            rig=self.rig,
            n_elements=self.n_elements,
            substeps=self.substeps,
            rho_inf=self.rho_inf,
            effects=self.effects,
            # the rig's force is the analytic signal on the fine grid:
            # linear between fine samples (gain error 2.7e-4 at 37 Hz)
            # keeps the embedded data set bit for bit
            input_interpolation="linear",
        )

    @property
    def fs_fine(self) -> float:
        """Rate [Hz] of the force given to the FE model and of its output."""
        return self.fs * self.oversampling

    @functools.cached_property
    def decimation_filter(self) -> np.ndarray:
        """FIR taps of the anti-alias filter (at ``fs_fine``, unit DC gain)."""
        if self.oversampling == 1:
            return np.array([1.0])
        return ss.firwin(
            DECIMATION_TAPS, DECIMATION_CUTOFF * self.fs, window=("kaiser", DECIMATION_KAISER_BETA), fs=self.fs_fine
        )

    def decimate(self, x_fine: np.ndarray, n_samples: int) -> np.ndarray:
        """Zero-phase low-pass and decimation of a fine-rate signal to ``n_samples`` at ``fs``."""
        if self.oversampling == 1:
            return np.asarray(x_fine[:n_samples], dtype=float).copy()
        y = ss.resample_poly(np.asarray(x_fine, dtype=float), 1, self.oversampling, window=self.decimation_filter)
        if y.size < n_samples:
            raise ValueError(f"fine signal too short for {n_samples} output samples")
        return y[:n_samples].copy()

    @property
    def margin_fine_samples(self) -> int:
        """Fine samples simulated past the record end (the filter's length)."""
        return self.decimation_filter.size

    def respond(self, force_fine, n_samples: int) -> tuple[np.ndarray, np.ndarray]:
        """Noise-free (force [N], velocity [m/s]) at ``fs``, ``n_samples`` each, for a
        force sampled at ``fs_fine`` covering at least ``n_samples * oversampling
        + margin_fine_samples`` samples (the rig is at rest before sample 0)."""
        force_fine = np.asarray(force_fine, dtype=float)
        need = n_samples * self.oversampling + self.margin_fine_samples
        if force_fine.size < need:
            raise ValueError(
                f"force_fine has {force_fine.size} samples, needs {need} "
                f"({n_samples} x {self.oversampling} + filter margin)"
            )
        result = fe.simulate(
            self.model, self.truth, force_fine, fs=self.fs_fine, positions=[self.rig.sensor_position_m]
        )
        return self.decimate(force_fine, n_samples), self.decimate(result.sensor_velocity, n_samples)

    def clean(self, spec: TestSpec) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Noise-free (time [s], force [N], velocity [m/s]) of one test (cached)."""
        t, f, v = _clean_run(self, spec)
        return t.copy(), f.copy(), v.copy()

    def measure(self, spec: TestSpec, rng: np.random.Generator) -> tuple:
        """(time, recorded force, recorded velocity) of one test: noise-free
        channels plus noise at the rig's SNRs, drawn from ``rng`` (force first)."""
        t, f, v = _clean_run(self, spec)
        return (t.copy(), signals.add_noise(f, self.snr_force_db, rng), signals.add_noise(v, self.snr_velocity_db, rng))

    def modes(self, n_modes: int = 2) -> fe.Modes:
        """Modes of the rig's model linearised at the truth."""
        return self.model.modal_analysis(self.truth, n_modes=n_modes)

    def truth_block(self, seed: int | None) -> dict:
        """The ``truth`` block of a data set made by this rig (SI units)."""
        p = self.truth
        modes = self.modes(1)
        f1 = float(modes.frequencies_hz[0])
        return {
            "note": "virtual rig: true parameters and settings; the updating code never reads this block",
            "parameters_si": p.to_dict(),
            "parameters_paper_units": {
                "eta_mpa_s": _sig(p.eta / 1e6),
                "c_n_s_per_mm": _sig(p.c / 1e3),
                "F_n": _sig(p.F),
                "k_s_n_per_mm": _sig(p.k_s / 1e3),
            },
            "effects": [dict({"name": e.name}, **e.parameters()) for e in self.effects],
            "rig_model": {
                "model": "fe.BeamModel",
                "formulation": self.model.formulation,
                "n_elements": self.n_elements,
                "rho_inf": self.rho_inf,
                "fs_fine_hz": self.fs_fine,
                "substeps_per_fine_sample": self.substeps,
                "steps_per_output_sample": self.substeps * self.oversampling,
                "decimation": (
                    f"linear-phase FIR, {self.decimation_filter.size} taps, Kaiser "
                    f"beta {DECIMATION_KAISER_BETA:g}, cutoff "
                    f"{DECIMATION_CUTOFF * self.fs:g} Hz, delay compensated (zero "
                    f"phase), scipy.signal.resample_poly, factor {self.oversampling}"
                    if self.oversampling > 1
                    else "none"
                ),
            },
            "noise": {
                "kind": "white Gaussian, SNR relative to each channel's RMS over the record",
                "snr_force_db": self.snr_force_db,
                "snr_velocity_db": self.snr_velocity_db,
                "seed": seed,
                "generator": "numpy.random.Generator(PCG64(SeedSequence(seed, "
                "spawn_key=(test index,)))), force noise drawn first",
            },
            "linearised": {
                "f1_hz": _sig(f1),
                "zeta1": _sig(float(modes.damping_ratios[0])),
                "sine_frequency_over_f1": _sig(signals.PAPER_SINE_HZ / f1),
                "p_eff_n": _sig(p.effective_preload(self.rig)),
                "euler_load_n": _sig(self.rig.euler_load),
            },
        }


def _sig(x: float, digits: int = 6) -> float:
    """Round to ``digits`` significant digits (keeps dataset.json stable across platforms)."""
    if x == 0 or not math.isfinite(x):
        return float(x)
    return float(round(x, digits - 1 - int(math.floor(math.log10(abs(x))))))


@functools.lru_cache(maxsize=64)
def _clean_run(vrig: VirtualRig, spec: TestSpec):
    n = int(round(spec.duration_s * vrig.fs))
    n_fine = n * vrig.oversampling + vrig.margin_fine_samples
    force_fine = signals.test_signal(spec.signal, spec.amplitude_n, fs=vrig.fs_fine, duration=n_fine / vrig.fs_fine)
    f, v = vrig.respond(force_fine, n)
    t = np.arange(n) / vrig.fs
    for a in (t, f, v):
        a.flags.writeable = False
    return t, f, v


def noise_generator(seed: int, index: int) -> np.random.Generator:
    """The noise generator of test ``index`` of a data set made with ``seed``."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed), spawn_key=(int(index),))))


def make_dataset(
    out=None,
    *,
    seed: int = DEFAULT_SEED,
    snr_force_db: float | None = DEFAULT_SNR_DB,
    snr_velocity_db: float | None = DEFAULT_SNR_DB,
    imperfection: float = 0.0,
    rig: VirtualRig | None = None,
    tests=PAPER_TESTS,
    name: str = DATASET_NAME,
) -> Dataset:
    """Make a virtual data set (and write it to the folder ``out`` if given).

    Parameters
    ----------
    out : folder to write (dataset.json + one CSV per test), or None.
    seed : noise seed (same seed, same bytes).
    snr_force_db, snr_velocity_db : noise levels [dB re channel RMS]; None: no noise.
    imperfection : initial bow amplitude at mid-span [m]
        (:class:`fe.InitialImperfection`); 0 = straight beam.
    rig : the virtual rig (default: the paper-equivalent rig at Table 3);
        its SNRs are replaced by the arguments and the imperfection, if
        non-zero, is added to its effects.
    tests : :class:`TestSpec` list (default: the paper's six tests).
    name : data-set name.

    ``make_dataset(DEFAULT_DATASET_DIR)`` with the defaults regenerates the
    embedded data set byte for byte (``bayes-update make-dataset``).
    """
    vrig = rig if rig is not None else VirtualRig()
    if not math.isfinite(imperfection):
        raise ValueError(f"imperfection must be finite, got {imperfection}")
    effects = tuple(vrig.effects)
    if imperfection != 0.0:
        effects += (fe.InitialImperfection(amplitude=float(imperfection)),)
    vrig = dataclasses.replace(vrig, effects=effects, snr_force_db=snr_force_db, snr_velocity_db=snr_velocity_db)
    records = []
    for index, spec in enumerate(tests):
        t, f, v = vrig.measure(spec, noise_generator(seed, index))
        records.append(Record(f"{spec.name}.csv", spec.signal, spec.level, spec.role, t, f, v, spec.meta()))
    extra = {
        "description": "Virtual measurements of the preloaded-beam rig (bayes_update."
        "virtual_rig); regenerate with: bayes-update make-dataset",
        "truth": vrig.truth_block(seed),
    }
    ds = Dataset(name, vrig.fs, vrig.rig, records, extra)
    if out is not None:
        write_dataset(ds, out)
        ds.source = str(out)
    return ds


# ------------------------------------------------------------ level diagnostics
