"""The likelihood as an object: each metric's scale and the log-likelihood they make.

:class:`StageScale` holds one metric's noise and model-error scales;
:class:`Likelihood` turns the metrics into ``log L = -1/2 sum (e / s)^2`` (and
into the surrogate's ``z``).  Apart from their measurement
(:mod:`bayes_update.core.noise_bootstrap` at the estimate,
:mod:`bayes_update.core.mode_errors` at the mode): every posterior step uses
these, only the builders run models.  Why this form: :mod:`bayes_update.core.likelihood`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass, field

import numpy as np

from bayes_update.core.metrics import STAGES, metric_key, stage_role


@dataclass(frozen=True)
class StageScale:
    """Noise and model-error scale of one metric (all dimensionless, relative)."""

    stage: str
    noise_mean_square: float  # mean of e^2 over the noise replicates at the estimate
    noise_dof: float  # nu: effective directions of the noise
    model_error: float  # e_model: model against its refined version at the estimate
    n_regressors: int
    n_replicates: int
    noise_levels: dict = field(default_factory=dict)  # channel -> {sd, unit, method, detail} the bootstrap added
    span_variance: float | None = None  # noise variance per direction in the span of the parameters' sensitivities
    span_rank: int | None = None
    model_error_unabsorbed: float | None = None  # the part of e_model no parameter change can take up
    model_error_source: str | None = None  # what e_model was measured against, or why it is zero
    #: the model-form error's variance per direction of the span (its draws at the mode,
    #: bayes_update.core.model_form), in the units of span_variance; 0 where not measured
    model_form_variance: float = 0.0
    #: {sensor: rms of the residual's excess over the noise at the mode / the record's rms}
    model_form_rms: dict | None = None
    model_form_source: str | None = None  # how the model-form error was measured, or why not

    @property
    def noise_sd(self) -> float:
        """s_n: the noise's sd per direction in the span of the parameter
        sensitivities when measured (``span_variance``), else mean(e^2) / nu."""
        if self.span_variance is not None:
            return math.sqrt(self.span_variance)
        return math.sqrt(self.noise_mean_square / self.noise_dof)

    @property
    def model_form_sd(self) -> float:
        """The model-form error's sd per direction of the span."""
        return math.sqrt(self.model_form_variance)

    @property
    def sd(self) -> float:
        """s = sqrt(s_n^2 + s_form^2 + e_model^2): the metric's scale in the likelihood."""
        return math.sqrt(self.noise_sd**2 + self.model_form_variance + self.model_error**2)

    def to_dict(self) -> dict:
        return {**asdict(self), "noise_sd": self.noise_sd, "model_form_sd": self.model_form_sd, "sd": self.sd}


@dataclass(frozen=True)
class Likelihood:
    """``log L = -1/2 sum_stage (e_stage / s_stage)^2`` (see :mod:`bayes_update.core.likelihood`).

    ``noise_residuals`` (stage -> ((K, n) array, (K,) weights), optional): the
    bootstrap's replicate residual vectors, relative to the reference's norm,
    and their weights in the noise's second moment ``sum_i w_i d_i d_i^T``
    (1/K each, or a control variate's, :func:`~bayes_update.core.likelihood.estimate_likelihood`);
    ``form_residuals`` the same of the model-form error's draws at the mode
    (:func:`~bayes_update.core.likelihood.errors_at_mode`).  :func:`bayes_update.core.adjustment.curvature_adjustment`
    needs both (:meth:`error_rows`); none of these is pickled (workers need only the scales)."""

    scales: dict  # stage -> StageScale
    noise_residuals: dict | None = field(default=None, compare=False, repr=False)
    #: stage -> :class:`~bayes_update.core.span.Sensitivity` at the point the scales were measured (the sensitivity
    #: span's runs), which a mode search from that point takes as its first Jacobian
    sensitivities: dict | None = field(default=None, compare=False, repr=False)
    #: stage -> the noise's periodogram in a replicate's time-domain residual, (n // 2 + 1,) or
    #: (n // 2 + 1, n_sensors): what the model-form error is measured beyond
    noise_spectra: dict | None = field(default=None, compare=False, repr=False)
    form_residuals: dict | None = field(default=None, compare=False, repr=False)
    #: the model runs :func:`~bayes_update.core.likelihood.estimate_likelihood` made for it (counted
    #: where they are made; :func:`~bayes_update.core.likelihood.likelihood_runs` plans them beforehand)
    n_model_runs: int = field(default=0, compare=False)

    def __getstate__(self):
        return {
            "scales": self.scales,
            "noise_residuals": None,
            "sensitivities": None,
            "noise_spectra": None,
            "form_residuals": None,
            "n_model_runs": self.n_model_runs,
        }

    def error_rows(self, stage: str):
        """``(D, w)``: the noise replicates' rows and, where measured, the model-form
        draws' (weights 1/K each), one second moment ``sum_i w_i d_i d_i^T``; None
        without the noise replicates."""
        res = (self.noise_residuals or {}).get(stage)
        if res is None:
            return None
        D, w = res if isinstance(res, tuple) else (res, np.full(len(res), 1.0 / len(res)))
        form = (self.form_residuals or {}).get(stage)
        if form is None:
            return D, w
        return np.vstack([D, form[0]]), np.concatenate([w, form[1]])

    def __post_init__(self):
        for st, sc in self.scales.items():
            stage_role(st)  # raises on an unknown stage
            if not (sc.sd > 0 and math.isfinite(sc.sd)):
                raise ValueError(f"stage {st}: the likelihood scale must be positive and finite, got {sc.sd}")

    @property
    def stages(self) -> tuple:
        return tuple(sorted(self.scales, key=lambda s: STAGES.index(stage_role(s))))

    @staticmethod
    def key(stage: str) -> str:
        return metric_key(stage)

    def restricted(self, stages) -> "Likelihood":
        def part(d):
            return {s: d[s] for s in stages if s in d} if d else None

        return Likelihood(
            {s: self.scales[s] for s in stages},
            part(self.noise_residuals),
            noise_spectra=part(self.noise_spectra),
            form_residuals=part(self.form_residuals),
        )

    def unabsorbed(self) -> "Likelihood":
        """The same noise with only the unabsorbed part of the model error
        (orthogonal to the parameters' sensitivities): the misfit a model
        comparison should count as explained.  The posterior keeps the whole
        model error, so that its bias moves a parameter by at most one sd."""
        return Likelihood(
            {
                st: dataclasses.replace(sc, model_error=sc.model_error_unabsorbed)
                if sc.model_error_unabsorbed is not None
                else sc
                for st, sc in self.scales.items()
            },
            self.noise_residuals,
            self.sensitivities,
            self.noise_spectra,
            self.form_residuals,
        )

    def log_likelihood(self, metrics: dict) -> float:
        """From a dict with each stage's metric (e_lin, e_nlin, ...); a failed run (NaN) gives -inf."""
        total = 0.0
        for st, sc in self.scales.items():
            e = metrics[self.key(st)]
            if not np.isfinite(e):
                return -np.inf
            total += (e / sc.sd) ** 2
        return -0.5 * total

    # The surrogate emulates z = log(1 + e^2 / s^2): quadratic (smooth) near the
    # minimum, where e itself has a kink (|.| of a linear function) and log e a
    # -inf spike; logarithmic far from it, where e^2 spans decades.
    def to_z(self, stage: str, e):
        return np.log1p((np.asarray(e, float) / self.scales[stage].sd) ** 2)

    def from_z(self, stage: str, z):
        return self.scales[stage].sd * np.sqrt(np.expm1(np.maximum(np.asarray(z, float), 0.0)))

    @staticmethod
    def log_likelihood_from_z(z_by_stage: dict):
        """-1/2 sum (e/s)^2 written in z: -1/2 sum (exp(z) - 1)."""
        return -0.5 * sum(np.expm1(z) for z in z_by_stage.values())

    def to_dict(self) -> dict:
        return {st: sc.to_dict() for st, sc in self.scales.items()}
