"""Figures of the posterior (matplotlib ``Figure`` objects, no pyplot state).

Every axis in its unit: the model's parameters in their declared units (the
beam's paper units: eta [MPa s], c [N s/mm], F [N], k_s [N/mm], P_eff [N]),
the responses in the data set's sensor units.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator, NullLocator


def _label(space, name: str) -> str:
    unit = space.report_units.get(name, "")
    return f"{name} [{unit}]" if unit else name


def _compared(stage: str, metrics: str | None) -> str:
    """What a stage's metric compares: y1, y2 + y3 or y1 + y2 + y3."""
    from bayes_update.core.metrics import METRIC_SETS, stage_role

    orders = METRIC_SETS.get(metrics or "paper", METRIC_SETS["paper"])[stage_role(stage)]
    return " + ".join(f"y{n}" for n in orders)


def predictive_bands(
    bands: dict, fs: float, names: dict | None = None, sensors=None, unit: str | None = None, metrics: str | None = None
):
    """Left: the compared output of each test (y1 of the linear test; y2 + y3 or
    y1 + y2 + y3 of the nonlinear one, per the metric set ``metrics``) of the
    data, a thin dark line on top of the model's median and 5-95 % band over
    posterior draws.  Right: the band of model - data, where the two would
    otherwise be indistinguishable.

    Parameters
    ----------
    sensors : the data set's ``[(name, kind), ...]`` (default: one velocity
        sensor); several sensors get a row each.
    unit : the outputs' unit (:attr:`~bayes_update.core.problem.Problem.output_unit`;
        default: the single sensor kind's unit).
    """
    from bayes_update.data.dataset import RESPONSE_UNITS

    sensors = list(sensors) if sensors else [("velocity", "velocity")]
    if unit is None:
        unit = RESPONSE_UNITS[sensors[0][1]] if len(sensors) == 1 else "noise sd"
    rows = []
    for stage, b in bands.items():
        n = len(b["reference"]) // len(sensors)
        for j, (sensor, kind) in enumerate(sensors):
            cut = slice(j * n, (j + 1) * n)
            rows.append((stage, sensor, kind, {k: np.asarray(v)[cut] for k, v in b.items()}))
    fig = Figure(figsize=(12, 3 * len(rows)), constrained_layout=True)
    axes = fig.subplots(len(rows), 2, squeeze=False)
    for (ax, ax_r), (stage, sensor, kind, b) in zip(axes, rows):
        ref = b["reference"]
        t = np.arange(len(ref)) / fs
        ax.fill_between(
            t, b["low"], b["high"], color="C1", alpha=0.35, lw=0, zorder=1, label="model, 5-95 % over draws"
        )
        ax.plot(t, b["median"], color="C1", lw=2.2, alpha=0.8, zorder=2, label="model, median over draws")
        ax.plot(t, ref, color="k", lw=0.5, zorder=3, label="data (reference decomposition)")
        ax_r.fill_between(
            t, b["low"] - ref, b["high"] - ref, color="C1", alpha=0.45, lw=0, label="model - data, 5-95 % over draws"
        )
        ax_r.plot(t, b["median"] - ref, color="C1", lw=0.5, label="model - data, median")
        ax_r.axhline(0.0, color="k", lw=0.5)
        what = _compared(stage, metrics)
        test = (names or {}).get(stage, stage)
        where = f", {sensor}" if len(sensors) > 1 else ""
        ax.set_title(f"{what}, {test}{where}", fontsize=10)
        ax_r.set_title(
            f"{what}, {test}{where}: model - data (RMS of data {np.sqrt(np.mean(ref**2)):.2e} {unit})", fontsize=9
        )
        label = f"{kind} [{unit}]" if len(sensors) == 1 else f"{sensor} ({kind}) [{unit}]"
        ax.set_ylabel(label)
        ax_r.set_ylabel(f"model - data [{unit}]")
        ax.legend(loc="upper right", fontsize=7)
        ax_r.legend(loc="upper right", fontsize=7)
    axes[-1, 0].set_xlabel("time [s]")
    axes[-1, 1].set_xlabel("time [s]")
    return fig


def ridge(space, X_linear, X_full, truth: dict | None = None, max_points: int = 4000, seed: int = 0):
    """The beam's (k_s, F) of the linear-only posterior (the ridge of constant
    P_eff) and of the full posterior; X: internal-coordinate draws (n, d)."""
    rng = np.random.default_rng(seed)
    fig = Figure(figsize=(11, 4.5), constrained_layout=True)
    ax1, ax2 = fig.subplots(1, 2)
    for X, color, label in ((X_linear, "C0", "low level only"), (X_full, "C3", "low + high level")):
        pick = rng.choice(len(X), size=min(max_points, len(X)), replace=False)
        d = space.report(X[pick])
        ax1.plot(d["k_s"], d["F"], ".", ms=1.5, alpha=0.3, color=color, label=label)
        ax2.plot(d["c"], d["k_s"], ".", ms=1.5, alpha=0.3, color=color, label=label)
    if truth:
        ax1.plot(truth["k_s"], truth["F"], "x", color="k", ms=9, mew=2)
        ax1.annotate("truth", (truth["k_s"], truth["F"]), xytext=(8, -12), textcoords="offset points")
        ax2.plot(truth["c"], truth["k_s"], "x", color="k", ms=9, mew=2)
    ax1.set_xlabel(_label(space, "k_s"))
    ax1.set_ylabel(_label(space, "F"))
    ax1.set_title("the linear-only ridge: F = P_eff (K_b + k_s) / K_b")
    ax2.set_xlabel(_label(space, "c"))
    ax2.set_ylabel(_label(space, "k_s"))
    ax2.set_title("c and k_s: unidentified by the low level")
    ax1.legend(markerscale=6, fontsize=8)
    return fig


def gp_diagnostics(predictive: dict, sensitivity: dict):
    """Left: surrogate against model metrics at posterior draws.  Right: Sobol'
    indices of log e_lin and log e_nlin over the prior box."""
    fig = Figure(figsize=(11, 4.5), constrained_layout=True)
    ax1, ax2 = fig.subplots(1, 2)
    drawn = False
    for st, key, color in (("linear", "e_lin", "C0"), ("nonlinear", "e_nlin", "C3")):
        pairs = predictive.get(f"_{st}_pairs")
        if pairs is None:
            continue
        drawn = True
        e_model, e_gp = pairs
        ax1.loglog(
            100 * e_model,
            100 * e_gp,
            "o",
            ms=4,
            color=color,
            label=f"{key}: median |error| {100 * predictive[f'{key}_gp_median_rel_error']:.1f} %",
        )
    lim = ax1.get_xlim()
    ax1.plot(lim, lim, "k-", lw=0.6)
    ax1.set_xlabel("metric from the model [%]")
    ax1.set_ylabel("metric from the GP [%]")
    ax1.set_title("surrogate honesty at posterior draws")
    if drawn:
        ax1.legend(fontsize=8)
    else:  # the predictive runs are opt-in (PosteriorSettings.n_predictive)
        ax1.text(
            0.5,
            0.5,
            "no predictive model runs\n(opt-in: n_predictive > 0)",
            ha="center",
            va="center",
            transform=ax1.transAxes,
        )
    names = [n for n in next((v["S1"] for v in sensitivity.values() if isinstance(v, dict) and "S1" in v), {})]
    units = sensitivity.get("units", {})
    width = 0.2
    for k, (key, color) in enumerate((("e_lin", "C0"), ("e_nlin", "C3"))):
        if key not in sensitivity:
            continue
        s1 = [sensitivity[key]["S1"][n] for n in names]
        st = [sensitivity[key]["ST"][n] for n in names]
        x = np.arange(len(names)) + (k - 0.5) * 2 * width
        ax2.bar(x - width / 2, s1, width, color=color, alpha=0.5, label=f"S1, log {key}")
        ax2.bar(x + width / 2, st, width, color=color, label=f"ST, log {key}")
    ax2.set_xticks(np.arange(len(names)), [f"{n} [{units[n]}]" if units.get(n) else n for n in names])
    ax2.set_ylabel("Sobol' index")
    ax2.set_title("global sensitivity over the prior box")
    if names:
        ax2.legend(fontsize=8)
    else:
        ax2.text(
            0.5, 0.5, "no Sobol' indices\n(opt-in: n_global > 0)", ha="center", va="center", transform=ax2.transAxes
        )
    return fig


def predictive_records(time_bands: dict, coverage: dict, fs: float, sensors, roles: dict | None = None):
    """Every test's record (each sensor a row) on a window around its largest response,
    over the posterior predictive's 50 % and 90 % bands (the model at posterior draws
    with the error model: noise and model-form error), each title with the share of
    the whole record's samples inside the bands (their targets 50 % and 90 %)."""
    from bayes_update.data.dataset import RESPONSE_UNITS

    rows = [(test, j, name, RESPONSE_UNITS[kind]) for test in time_bands for j, (name, kind) in enumerate(sensors)]
    fig = Figure(figsize=(12, 2.3 * len(rows)), constrained_layout=True)
    axes = fig.subplots(len(rows), 1, squeeze=False)[:, 0]
    for ax, (test, j, sensor, unit) in zip(axes, rows):
        b = time_bands[test]
        rec = np.asarray(b["record"])[:, j]
        t = (b["start"] + np.arange(len(rec))) / fs
        ax.fill_between(t, b["q05"][:, j], b["q95"][:, j], color="C0", alpha=0.25, lw=0, label="90 % band")
        ax.fill_between(t, b["q25"][:, j], b["q75"][:, j], color="C0", alpha=0.45, lw=0, label="50 % band")
        ax.plot(t, b["median"][:, j], color="C0", lw=0.8, label="median")
        ax.plot(t, rec, color="k", lw=0.6, label="record")
        c = coverage.get(test, {}).get(sensor, {})
        role = f" ({roles[test]})" if roles and test in roles else ""
        ax.set_title(
            f"{test}{role}, {sensor}: {100 * c.get('50', np.nan):.0f} % of the record inside the 50 % "
            f"band, {100 * c.get('90', np.nan):.0f} % inside the 90 % band",
            fontsize=9,
        )
        ax.set_ylabel(f"{sensor} [{unit}]")
        ax.legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1].set_xlabel("time [s]")
    return fig


def _posterior_arrays(res) -> dict:
    """{variable: (chain, draw) array} of the reported variables (InferenceData or DataTree)."""
    group = res.idata["posterior"]
    return {n: np.asarray(group[n].values, float) for n in res.space.report_units}


def corner(res, truth: dict | None = None, bins: int = 40):
    """Pairs of the posterior's reported variables (a 2D histogram of the draws
    below the diagonal, each marginal on it), with the truth if given, each axis
    in its unit."""
    draws = _posterior_arrays(res)
    names = list(draws)
    n = len(names)
    fig = Figure(figsize=(2.4 * n, 2.4 * n), constrained_layout=True)
    axes = np.atleast_2d(fig.subplots(n, n, squeeze=False))
    for i, yi in enumerate(names):
        for j, xj in enumerate(names):
            ax = axes[i, j]
            if j > i:
                ax.set_visible(False)
                continue
            x = draws[xj].ravel()
            if i == j:
                ax.hist(x, bins=bins, color="C0", histtype="stepfilled", alpha=0.6)
                if truth and xj in truth:
                    ax.axvline(truth[xj], color="k", lw=1.2)
            else:
                ax.hist2d(x, draws[yi].ravel(), bins=bins, cmap="Blues")
                if truth and xj in truth and yi in truth:
                    ax.plot(truth[xj], truth[yi], "x", color="k", ms=8, mew=2)
            ax.xaxis.set_major_locator(MaxNLocator(3))
            ax.yaxis.set_major_locator(NullLocator() if i == j else MaxNLocator(3))
            ax.ticklabel_format(axis="x", useOffset=False)
            if i != j:
                ax.ticklabel_format(axis="y", useOffset=False)
            ax.set_xlim(np.quantile(x, [0.001, 0.999]))
            if i == n - 1:
                ax.set_xlabel(_label(res.space, xj))
                ax.tick_params(axis="x", labelrotation=30)
            else:
                ax.tick_params(labelbottom=False)
            if j == 0 and i > 0:
                ax.set_ylabel(_label(res.space, yi))
            elif i != j:
                ax.tick_params(labelleft=False)
            if 0 < i != j:
                ax.set_ylim(np.quantile(draws[yi], [0.001, 0.999]))
    return fig


def traces(res):
    """Each reported variable's chains (one line a walker) against the draw index."""
    draws = _posterior_arrays(res)
    fig = Figure(figsize=(9, 1.7 * len(draws)), constrained_layout=True)
    axes = np.atleast_1d(fig.subplots(len(draws), 1, sharex=True, squeeze=False)[:, 0])
    for ax, (name, values) in zip(axes, draws.items()):
        ax.plot(values.T, lw=0.4, alpha=0.5)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.set_ylabel(_label(res.space, name))
    axes[-1].set_xlabel("draw (kept, thinned)")
    return fig


def posterior_figures(res, truth: dict | None = None) -> dict:
    """{file stem: Figure} of a :class:`~bayes_update.core.posterior.PosteriorResult`:
    the pairs and traces of the draws, the predictive bands and the GP checks, and
    the beam's ridge when the result carries its linear-only posterior."""
    figs = {"corner": corner(res, truth), "traces": traces(res)}
    if res.predictive.get("_bands"):
        names = {st: t.name for st, t in res.problem.tests.items()}
        figs["predictive"] = predictive_bands(
            res.predictive["_bands"],
            res.problem.fs,
            names,
            sensors=res.problem.sensors,
            unit=res.problem.output_unit,
            metrics=res.problem.metrics,
        )
    if res.predictive.get("_time"):
        roles = {t.name: st for st, t in res.problem.tests.items()}
        roles.update({name: "validation" for name in res.problem.validation})
        figs["predictive_records"] = predictive_records(
            res.predictive["_time"], res.predictive.get("coverage", {}), res.problem.fs, res.problem.sensors, roles
        )
    linear_only = res.extras.get("linear_only", {})
    if linear_only.get("_draws") is not None:
        figs["ridge"] = ridge(res.space, linear_only["_draws"], res.draws, truth)
    if res.surrogates or res.sensitivity:
        figs["gp_diagnostics"] = gp_diagnostics(res.predictive, res.sensitivity)
    return figs


__all__ = ["corner", "gp_diagnostics", "posterior_figures", "predictive_bands", "predictive_records", "ridge", "traces"]
