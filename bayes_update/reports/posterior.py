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
    """Markdown table of the posterior (the beam's in paper units)."""
    lines = ["| parameter | mean | sd | 94 % HDI | R-hat | bulk ESS |", "|---|---|---|---|---|---|"]
    for var, v in res.summary.items():
        p = v.get("paper_units", {**v, "unit": v["units"]})
        lines.append(f"| {var} [{p['unit']}] | {p['mean']:.5g} | {p['sd']:.3g} | "
                     f"{p['hdi_3%']:.5g} - {p['hdi_97%']:.5g} | {v['r_hat']:.4f} | {v['ess_bulk']:.0f} |")
    return "\n".join(lines)
