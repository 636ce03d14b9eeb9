"""What :func:`~bayes_update.core.posterior.sample` returns: the posterior, how it was
found, and its reports (JSON summaries, a markdown table, the surrogate evidence)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from bayes_update.core.likelihood import Likelihood
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior.laplace import MapResult
from bayes_update.core.posterior.settings import PosteriorSettings
from bayes_update.core.problem import Problem


@dataclass
class PosteriorResult:
    idata: object
    summary: dict
    likelihood: Likelihood
    space: ParameterSet
    map: MapResult
    box: np.ndarray
    start: dict
    diagnostics: dict
    timing: dict
    n_model_runs: dict
    settings: PosteriorSettings
    direct: bool
    problem: Problem = field(repr=False, default=None)
    surrogates: dict = field(repr=False, default_factory=dict)
    design: dict = field(repr=False, default_factory=dict)
    draws: np.ndarray = field(repr=False, default=None)  # flat internal-coordinate draws
    extras: dict = field(repr=False, default_factory=dict)  # what a study adds (the beam: linear_only)
    seeds: list = field(repr=False, default_factory=list)  # the pipeline's spawned seeds
    predictive: dict = field(repr=False, default_factory=dict)
    sensitivity: dict = field(repr=False, default_factory=dict)
    n_model_runs_reused: dict = field(default_factory=dict)  # found in the cache instead of run
    target: object = field(repr=False, default=None)  # the surrogate log posterior the chain sampled (in u)
    adjustment: object = field(repr=False, default=None)  # the likelihood's curvature adjustment, if any

    def log_evidence(self, n: int = 4000, seed: int = 0):
        """log p(data) of the surrogate posterior, no model run
        (:func:`~bayes_update.core.posterior.evidence.surrogate_log_evidence`)."""
        from bayes_update.core.posterior.evidence import surrogate_log_evidence

        return surrogate_log_evidence(self, n, seed)

    def summary_json(self) -> dict:
        return {
            "parameters": self.summary,
            "map": dict(zip(self.space.coordinate_names, map(float, self.map.x))),
            "map_units": dict(self.space.units),
            "likelihood": self.likelihood.to_dict(),
            "prior": self.space.to_dict(),
            "laplace_box": dict(zip(self.space.coordinate_names, self.box.tolist())),
            "start": self.start,
            "diagnostics": self.diagnostics,
            "direct": self.direct,
            "settings": asdict(self.settings),
            **{name: {k: v for k, v in extra.items() if not k.startswith("_")} for name, extra in self.extras.items()},
            "predictive_coverage": self.predictive.get("coverage", {}),
            "prediction_error": self.predictive.get("prediction_error", {}),
            "error_model": self.predictive.get("error_model", {}),
            "surrogate_check": {
                k: v
                for k, v in self.predictive.items()
                if not k.startswith("_") and k not in ("coverage", "prediction_error", "error_model")
            },
            "sensitivity": self.sensitivity,
            "fit_warnings": self.diagnostics.get("fit_warnings", []),
            "noise": {t: {ch: e.to_dict() for ch, e in chans.items()} for t, chans in self.problem.noise.items()},
            "representation_floor": {
                self.problem.tests[st].name: self.problem.representation_floor(st) for st in self.problem.stages
            },
        }

    def summary_table(self) -> str:
        """Markdown table of the posterior: mean, sd, 94 % HDI, R-hat and bulk ESS of
        every reported variable, in its unit; the mean and the HDI with the digits
        the sd resolves (:mod:`bayes_update.core.numbers`)."""
        from bayes_update.core.numbers import format_sd, format_value
        from bayes_update.core.posterior.mcmc import MIN_ESS, RHAT_TARGET

        lines = ["| parameter | mean | sd | 94 % HDI | R-hat | bulk ESS | tail ESS |", "|---|---|---|---|---|---|---|"]
        for var, v in self.summary.items():
            unit = f" [{v['units']}]" if v["units"] else ""
            sd = v["sd"]  # the mean and the HDI to the decimal place of sd's second digit
            lines.append(
                f"| {var}{unit} | {format_value(v['mean'], sd)} | {format_sd(sd)} | "
                f"{format_value(v['hdi_3%'], sd)} - {format_value(v['hdi_97%'], sd)} | "
                f"{v['r_hat']:.4f} | {v['ess_bulk']:.0f} | " + (f"{v['ess_tail']:.0f} |" if "ess_tail" in v else "- |")
            )
        # a summary written before the tail ESS was kept (posterior.json of an older
        # run) is judged on what it has, its missing column shown as '-'
        ok = all(
            v["r_hat"] < RHAT_TARGET and min(v["ess_bulk"], v.get("ess_tail", np.inf)) >= MIN_ESS
            for v in self.summary.values()
        )
        steps = self.diagnostics.get("convergence", {}).get("n_steps")
        lines.append("")
        lines.append(
            ("converged" if ok else "NOT converged") + f": R-hat < {RHAT_TARGET} and bulk and tail ESS >= "
            f"{MIN_ESS} for every variable {'holds' if ok else 'fails'}"
            + (f" ({steps} steps of {self.settings.n_walkers} walkers)" if steps else "")
        )
        return "\n".join(lines)

    def run_json(self) -> dict:
        """How the run went (not what it found): wall time per step [s] and model
        runs per step, which a resumed run or another machine changes while the
        posterior stays the same."""
        return {
            "timing_s": self.timing,
            "n_model_runs": self.n_model_runs,
            "n_model_runs_reused": self.n_model_runs_reused,
        }
