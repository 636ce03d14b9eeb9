"""The paper's two-stage deterministic updating (section 4), on any data set.

1. Linear stage (test with role ``linear``, the low-level chirp): a first
   scan of e_lin against eta at the preload where the model's first mode
   matches the data's Kautz pole; e_lin over a grid of (F, k_s) for each c of
   the paper's Table 1 at that eta; then e_lin against eta at the best
   (c, F, k_s) (the paper's Fig. 8), refined by a parabola through the three
   best points.
2. Nonlinear stage (role ``nonlinear``, the high-level chirp): e_lin + e_nlin
   over the same (F, k_s) grid for each c at the updated eta (Table 2); then a
   derivative-free local refinement (Nelder-Mead) of (F, k_s, c) from the best
   grid point (Table 3).
3. Validation (roles ``validation``): medium chirp in time, sines by PSD.

The (F, k_s) grid is laid out in (P_eff, k_s): e_lin sees only the preload the
beam carries, P_eff = F K_b / (K_b + k_s), so each k_s column spans a window of
P_eff around the preload at which the model's first mode matches the data's
Kautz pole, and F follows.  A regular F grid would spend most runs far from the
valley, whose width is a fraction of a newton.
"""

from __future__ import annotations

import time
from concurrent.futures import Executor
from functools import partial

import numpy as np
from scipy.optimize import minimize

from bayes_update.core.logs import info
from bayes_update.core.model import ModelSpecError
from bayes_update.core.problem import Problem
from bayes_update.data.dataset import Dataset
from bayes_update.models.beam.calibration_grid import (
    CalibrationSettings,
    paper_units,
    parameters_from,
    preload_for_frequency,
)
from bayes_update.models.beam.calibration_result import CalibrationResult, format_tables
from bayes_update.models.beam.validation import validate
from surrogates.evaluation import evaluate_many, executor_for

__all__ = [
    "MPA_S",
    "CalibrationResult",
    "CalibrationSettings",
    "calibrate",
    "coarse_start",
    "format_tables",
    "paper_units",
    "parabola_vertex",
    "parameters_from",
    "preload_for_frequency",
]


#: Pa s per MPa s (the grids are in the paper's units)
MPA_S = 1e6


def parabola_vertex(x, y) -> float:
    """Minimiser of the parabola through the lowest sample and its neighbours
    (the sample itself at an end of the range)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    i = int(np.nanargmin(y))
    if i == 0 or i == x.size - 1:
        return float(x[i])
    a, b, _ = np.polyfit(x[i - 1 : i + 2], y[i - 1 : i + 2], 2)
    return float(-b / (2 * a)) if a > 0 else float(x[i])


def _best(rows, key):
    ok = [r for r in rows if np.isfinite(r[key])]
    if not ok:
        raise ModelSpecError(
            f"every beam run of this grid failed (first: {rows[0].get('error')}): the grid lies "
            "where the beam cannot run (it buckles or diverges); check the data set's rig (its "
            "bending_stiffness_factor, or --bending-stiffness-factor) and the grids' ranges (a "
            "[calibrate] table of --config)"
        )
    return min(ok, key=lambda r: r[key])


def calibrate(
    dataset: Dataset,
    model,
    settings: CalibrationSettings | None = None,
    executor: Executor | None = None,
    workers: int | None = None,
    progress: bool = True,
    log=info,
    store=None,
) -> CalibrationResult:
    """Run the two-stage updating on ``dataset`` (see the module docstring).

    model : the beam as a model of the contract
        (:class:`~bayes_update.models.beam.model.Beam`, e.g.
        :func:`~bayes_update.models.beam.model.beam_model` of the data set).
    executor : any ``concurrent.futures.Executor`` for the grids; default a
        local process pool over ``workers`` processes (all cores); ``workers=1``
        runs serially.
    store : the run cache (:class:`~bayes_update.core.runs.RunStore`) the grids' runs are
        kept in and found in, or None.
    """
    settings = settings or CalibrationSettings()
    if not hasattr(model, "fe_model"):
        raise TypeError(
            f"calibrate runs the paper's grids on the beam: pass a Beam (beam_model(dataset)), "
            f"got {type(model).__name__}"
        )
    beam = model
    model, rig = beam.fe_model, beam.rig
    t_start = time.perf_counter()
    problem = Problem(dataset, beam, metrics="paper")
    problem.run_store = store
    if "nonlinear" not in problem.stages:
        raise ValueError(f"{problem.source}: the nonlinear stage needs a test with role 'nonlinear'")
    pole = problem.basis.pole(1)
    p0 = preload_for_frequency(model, pole.freq_hz, eta=float(np.median(settings.eta_values)) * MPA_S)
    p_grid = p0 + np.arange(-settings.p_eff_halfwidth, settings.p_eff_halfwidth + 1e-9, settings.p_eff_step)
    p_grid = p_grid[(p_grid > 0) & (p_grid < 0.99 * model.buckling_load())]
    log(
        f"Kautz pole from {problem.tests['linear'].name}: {pole.freq_hz:.3f} Hz, zeta = "
        f"{pole.damping_ratio:.4f}; model first mode there at P_eff = {p0:.2f} N; "
        f"grid P_eff {p_grid[0]:.2f}..{p_grid[-1]:.2f} N"
    )
    n_runs = 0
    timing = {}
    with executor_for(executor, workers) as pool:
        # ---------------------------------------------------------------- linear stage
        # eta first, at the frequency-matched preload (e_lin is sharp in eta, so a
        # grid at a wrong eta would report misfits that are only damping)
        t0 = time.perf_counter()
        c_mid = float(np.median(settings.c_values))
        eta_pre, _ = _eta_scan(problem, beam, settings, pool, progress, c_mid, 0.0, p0, "eta pre-scan")
        n_runs += len(settings.eta_values)
        combos = [(c, ks, p) for c in settings.c_values for ks in settings.k_s_values for p in p_grid]
        pts = [parameters_from(beam, eta_pre, c, ks, p) for c, ks, p in combos]
        res = evaluate_many(
            partial(problem.evaluate, stages=("linear",)), pts, pool, progress=progress, desc="linear grid"
        )
        n_runs += len(pts)
        linear_grid = [{**paper_units(q, beam), "e_lin": r["e_lin"], "error": r["error"]} for q, r in zip(pts, res)]
        table1 = [_best([g for g in linear_grid if g["c_N_s_per_mm"] == c], "e_lin") for c in settings.c_values]
        best_lin = _best(linear_grid, "e_lin")
        timing["linear_grid"] = time.perf_counter() - t0

        t0 = time.perf_counter()
        eta_hat, eta_scan = _eta_scan(
            problem,
            beam,
            settings,
            pool,
            progress,
            best_lin["c_N_s_per_mm"],
            best_lin["k_s_N_per_mm"],
            best_lin["P_eff_N"],
            "eta scan",
        )
        n_runs += len(settings.eta_values)
        timing["eta_scan"] = time.perf_counter() - t0
        log(
            f"linear stage (eta pre-scan: {eta_pre:.3f} MPa s): best c = {best_lin['c_N_s_per_mm']:g} "
            f"N s/mm, F = {best_lin['F_N']:.2f} N, k_s = {best_lin['k_s_N_per_mm']:g} N/mm (P_eff = "
            f"{best_lin['P_eff_N']:.2f} N), e_lin = {100 * best_lin['e_lin']:.2f} %; eta = {eta_hat:.3f} MPa s"
        )

        # ------------------------------------------------------------- nonlinear stage
        t0 = time.perf_counter()
        pts = [parameters_from(beam, eta_hat, c, ks, p) for c, ks, p in combos]
        res = evaluate_many(problem.evaluate, pts, pool, progress=progress, desc="nonlinear grid")
        n_runs += 2 * len(pts)
        nonlinear_grid = [
            {
                **paper_units(q, beam),
                "e_lin": r["e_lin"],
                "e_nlin": r["e_nlin"],
                "e_lin_nlin": r["e_lin"] + r["e_nlin"],
                "error": r["error"],
            }
            for q, r in zip(pts, res)
        ]
        table2 = [_best([g for g in nonlinear_grid if g["c_N_s_per_mm"] == c], "e_lin_nlin") for c in settings.c_values]
        best_nl = _best(nonlinear_grid, "e_lin_nlin")
        timing["nonlinear_grid"] = time.perf_counter() - t0

    # ------------------------------------------------------------------ refinement
    t0 = time.perf_counter()
    scale = np.array([settings.p_eff_step, 60.0, 2.5])  # N, N/mm, N s/mm: one unit each
    x0 = np.array([best_nl["P_eff_N"], best_nl["k_s_N_per_mm"], best_nl["c_N_s_per_mm"]])
    p_max = 0.99 * model.buckling_load()
    history = []

    def objective(z):
        p, ks, c = x0 + z * scale
        q = parameters_from(beam, eta_hat, max(c, 0.0), max(ks, 0.0), p)
        r = problem.evaluate(q)
        history.append(
            {**paper_units(q, beam), "e_lin": r["e_lin"], "e_nlin": r["e_nlin"], "e_lin_nlin": r["e_lin"] + r["e_nlin"]}
        )
        val = r["e_lin"] + r["e_nlin"]
        return val if np.isfinite(val) else 10.0

    bounds = [
        ((1.0 - x0[0]) / scale[0], (p_max - x0[0]) / scale[0]),
        (-x0[1] / scale[1], None),
        (-x0[2] / scale[2], None),
    ]
    opt = minimize(
        objective,
        np.zeros(3),
        method="Nelder-Mead",
        bounds=bounds,
        options={
            "maxfev": settings.refine_max_evaluations,
            "xatol": 0.02,
            "fatol": 1e-5,
            "initial_simplex": np.vstack([np.zeros(3), np.eye(3)]),
        },
    )
    n_runs += 2 * len(history)
    best_ref = min(history, key=lambda r: r["e_lin_nlin"])
    final_theta = parameters_from(
        beam, eta_hat, best_ref["c_N_s_per_mm"], best_ref["k_s_N_per_mm"], best_ref["P_eff_N"]
    )
    final_params = beam.fe_parameters(final_theta)
    timing["refinement"] = time.perf_counter() - t0
    log(
        f"nonlinear stage: grid best c = {best_nl['c_N_s_per_mm']:g} N s/mm, k_s = "
        f"{best_nl['k_s_N_per_mm']:g} N/mm, e_lin+nlin = {100 * best_nl['e_lin_nlin']:.2f} %; refined "
        f"({len(history)} evaluations, {opt.message}): c = {best_ref['c_N_s_per_mm']:.2f} N s/mm, "
        f"F = {best_ref['F_N']:.2f} N, k_s = {best_ref['k_s_N_per_mm']:.1f} N/mm, "
        f"e_lin+nlin = {100 * best_ref['e_lin_nlin']:.2f} %"
    )

    # ----------------------------------------------------- the ridge along k_s
    ridge = _ridge_profile(nonlinear_grid, best_ref["c_N_s_per_mm"], settings.c_values)

    # ------------------------------------------------------------------ validation
    t0 = time.perf_counter()
    val = validate(dataset, beam, final_theta)
    velocities = dict(val["_velocity"])
    for stage in problem.stages:
        velocities[problem.tests[stage].name] = problem.simulate(final_theta, stage)
    n_runs += len(velocities)
    timing["validation"] = time.perf_counter() - t0
    timing["total"] = time.perf_counter() - t_start

    final = {
        **paper_units(final_theta, beam),
        "e_lin": best_ref["e_lin"],
        "e_nlin": best_ref["e_nlin"],
        "e_lin_nlin": best_ref["e_lin_nlin"],
    }
    table3 = {
        "eta_MPa_s": eta_hat,
        "c_N_s_per_mm": final["c_N_s_per_mm"],
        "F_N": final["F_N"],
        "k_s_N_per_mm": final["k_s_N_per_mm"],
        "P_eff_N": final["P_eff_N"],
        "e_lin": final["e_lin"],
        "e_nlin": final["e_nlin"],
    }
    setup = {
        **problem.describe(),
        "p_eff_window_centre_N": p0,
        "eta_pre_scan_MPa_s": eta_pre,
        "n_model_runs": n_runs,
        "data": problem.source,
        "rig": rig.to_dict(),
    }
    return CalibrationResult(
        final=final,
        linear_grid=linear_grid,
        eta_scan=eta_scan,
        nonlinear_grid=nonlinear_grid,
        refinement=history,
        table1=table1,
        table2=table2,
        table3=table3,
        ridge=ridge,
        validation=val,
        setup=setup,
        timing=timing,
        settings=settings,
        final_theta=final_theta,
        final_params=final_params,
        velocities=velocities,
        problem=problem,
    )


def coarse_start(dataset: Dataset, beam, executor=None, progress: bool = False, store=None) -> tuple[dict, int]:
    """(theta, model runs): a start for a search that goes on from it (the
    posterior's MAP with its starts along the (c, k_s) band): P_eff where the
    model's first mode has the Kautz pole's frequency (no model run), eta by
    the parabola through a scan of e_lin at the quick grid's c and k_s = 0 (six
    linear runs).  The low level pins eta and P_eff; c and k_s are left to the
    search.  ``store``: the run cache its runs are kept in and found in, or None."""
    settings = CalibrationSettings.quick()
    problem = Problem(dataset, beam, metrics="paper")
    problem.run_store = store
    model = beam.fe_model
    eta_mid = float(np.median(settings.eta_values))
    p0 = preload_for_frequency(model, problem.basis.pole(1).freq_hz, eta=eta_mid * MPA_S)
    c_mid = float(np.median(settings.c_values))
    eta, _ = _eta_scan(problem, beam, settings, executor, progress, c_mid, 0.0, p0, "eta scan")
    return parameters_from(beam, eta, c_mid, 0.0, p0), len(settings.eta_values)


def _eta_scan(problem, beam, settings, pool, progress, c, k_s, p_eff, desc):
    """e_lin against eta at (c, k_s, P_eff); the estimate is the vertex of the
    parabola through the three lowest points (clipped to the scanned range)."""
    pts = [parameters_from(beam, e, c, k_s, p_eff) for e in settings.eta_values]
    res = evaluate_many(partial(problem.evaluate, stages=("linear",)), pts, pool, progress=progress, desc=desc)
    scan = [{"eta_MPa_s": e, "e_lin": r["e_lin"]} for e, r in zip(settings.eta_values, res)]
    eta = parabola_vertex(settings.eta_values, [r["e_lin"] for r in scan])
    return float(np.clip(eta, min(settings.eta_values), max(settings.eta_values))), scan


def _ridge_profile(grid, c_best, c_values, rise=0.5) -> dict:
    """How well the data pin k_s along the P_eff ridge: the minimum of
    e_lin + e_nlin over P_eff for each k_s, at the grid c nearest to the
    estimate, and the k_s interval (linear interpolation between grid points)
    where it stays below (1 + ``rise``) x its minimum, i.e. 50 % above it."""
    c_near = min(c_values, key=lambda c: abs(c - c_best))
    rows = [g for g in grid if g["c_N_s_per_mm"] == c_near and np.isfinite(g["e_lin_nlin"])]
    ks = np.array(sorted({g["k_s_N_per_mm"] for g in rows}))
    prof = np.array([min(g["e_lin_nlin"] for g in rows if g["k_s_N_per_mm"] == k) for k in ks])
    i = int(np.argmin(prof))
    level = (1 + rise) * prof[i]

    def crossing(step):
        j = i
        while 0 <= j + step < ks.size and prof[j + step] <= level:
            j += step
        if not 0 <= j + step < ks.size:
            return float(ks[j])  # still below the level at the grid's end
        k0, k1, e0, e1 = ks[j], ks[j + step], prof[j], prof[j + step]
        return float(k0 + (level - e0) / (e1 - e0) * (k1 - k0))

    return {
        "c_N_s_per_mm": c_near,
        "k_s_N_per_mm": ks.tolist(),
        "min_e_lin_nlin": prof.tolist(),
        "rise": rise,
        "k_s_interval_N_per_mm": [crossing(-1), crossing(+1)],
    }
