"""What ``bayes-update sample`` writes: posterior.nc, posterior_summary.json, run.json,
figures, and the summary table."""

from __future__ import annotations

import math
from numbers import Real

from bayes_update.core.logs import info

__all__ = ["format_summary", "truth_in_model_units", "write_posterior"]


def truth_in_model_units(block, units: dict, log=info) -> dict | None:
    """The values of a data set's ``truth`` block (``dataset.json``) that name the
    model's parameters in the model's units, for marking the figures; None when
    there are none.

    Parameters
    ----------
    block : the ``truth`` block, in either form (or both mixed):
        ``{"k": 4.6, "fn": 23.7, "units": {"k": "kN/m", "fn": "Hz"}}`` or
        ``{"k": {"value": 4.6, "unit": "kN/m"}}``.
    units : ``{name: unit}`` of the model's reported variables
        (:attr:`~bayes_update.core.parameters.ParameterSet.report_units`).
    log : where the one line saying what is not drawn, and why, goes.

    A value is drawn only when its stated unit is the model's unit for that
    name (the same string); a value without a stated unit, or in another
    unit, is not drawn (nothing converts units)."""
    if not isinstance(block, dict):
        return None
    stated_units = block.get("units") if isinstance(block.get("units"), dict) else {}
    drawn, skipped = {}, []
    for name, unit in units.items():
        if name not in block:
            continue
        entry = block[name]
        if isinstance(entry, dict):
            value, stated = entry.get("value"), entry.get("unit")
        else:
            value, stated = entry, stated_units.get(name)
        if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
            skipped.append(f"{name} (not a number)")
        elif not isinstance(stated, str):
            skipped.append(f"{name} (no unit stated)")
        elif stated != unit:
            skipped.append(f"{name} (in {stated!r}, the model's unit is {unit!r})")
        else:
            drawn[name] = float(value)
    if skipped:
        name, unit = next(iter(units.items()))
        log(
            f"the data set's truth is not drawn for {', '.join(skipped)}: state each value in the model's "
            f'unit, e.g. "{name}": {{"value": ..., "unit": "{unit}"}}, or a "units" block'
        )
    return drawn or None


def write_posterior(res, out, truth: dict | None = None, figures: bool = True):
    """``posterior.nc`` (ArviZ), ``posterior_summary.json`` (what was found: the
    same seed and data give the same bytes), ``run.json`` (wall times and model
    runs) and the figures (PNG) in folder ``out``; ``truth`` (``{name: value}``,
    each in the model's unit: :func:`truth_in_model_units` for a data set's
    ``truth`` block) only marks the plots."""
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
