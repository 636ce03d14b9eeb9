"""What ``bayes-update sample`` writes: posterior.nc, posterior_summary.json, run.json,
figures, and the summary table."""
from __future__ import annotations


def write_posterior(res, out, truth: dict | None = None, figures: bool = True):
    """``posterior.nc`` (ArviZ), ``posterior_summary.json`` (what was found: the
    same seed and data give the same bytes), ``run.json`` (wall times and model
    runs) and the figures (PNG) in folder ``out``; ``truth`` (paper units) only
    marks the plots."""
    import json
    from pathlib import Path

    from bayes_update.reports.posterior_plots import posterior_figures

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    res.idata.to_netcdf(str(out / "posterior.nc"))
    (out / "posterior_summary.json").write_text(json.dumps(res.summary_json(), indent=1, default=float))
    (out / "run.json").write_text(json.dumps(res.run_json(), indent=1, default=float))
    if figures:
        for name, fig in posterior_figures(res, truth).items():
            fig.savefig(out / f"{name}.png", dpi=110)
    return out


def format_summary(res) -> str:
    """Markdown table of the posterior (each variable in its unit):
    :meth:`~bayes_update.core.posterior.PosteriorResult.summary_table`."""
    return res.summary_table()
