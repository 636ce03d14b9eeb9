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
from dataclasses import asdict, dataclass, field
from functools import partial

import numpy as np
from scipy.optimize import brentq, minimize

import fe
from bayes_update.core.logs import info
from bayes_update.core.model import ModelSpecError
from bayes_update.core.problem import Problem
from bayes_update.data.dataset import Dataset
from bayes_update.models.beam.validation import validate
from surrogates.evaluation import evaluate_many, executor_for


@dataclass(frozen=True)
class CalibrationSettings:
    """Grids in the paper's units (c [N s/mm], k_s [N/mm], P_eff [N], eta [MPa s])."""

    c_values: tuple = (0.0, 5.0, 10.0, 15.0, 20.0, 25.0)
    k_s_values: tuple = tuple(float(k) for k in range(0, 601, 60))
    p_eff_halfwidth: float = 3.0
    p_eff_step: float = 0.5
    eta_values: tuple = tuple(float(e) for e in np.round(np.arange(1.0, 6.001, 0.25), 2))
    refine_max_evaluations: int = 80

    def __post_init__(self):
        for name in ("c_values", "k_s_values", "eta_values"):
            v = np.asarray(getattr(self, name), float)
            if v.ndim != 1 or v.size == 0 or not np.all(np.isfinite(v)) or np.any(v < 0):
                raise ValueError(f"{name} must be a non-empty list of non-negative numbers")
        if len(self.eta_values) < 3:
            raise ValueError("eta_values needs at least 3 values (a parabola is fitted)")
        if not (self.p_eff_step > 0 and self.p_eff_halfwidth >= self.p_eff_step):
            raise ValueError("need p_eff_step > 0 and p_eff_halfwidth >= p_eff_step")

    @classmethod
    def quick(cls) -> "CalibrationSettings":
        """Coarse grids for tests and a first look (about 1/10 of the runs)."""
        return cls(
            c_values=(5.0, 15.0, 25.0),
            k_s_values=(0.0, 200.0, 400.0, 600.0),
            p_eff_halfwidth=1.0,
            p_eff_step=0.5,
            eta_values=(2.0, 2.5, 3.0, 3.5, 4.0, 4.5),
            refine_max_evaluations=40,
        )


#: Pa s per MPa s (the grids are in the paper's units)
MPA_S = 1e6


def parameters_from(beam, eta_mpa_s: float, c_n_s_per_mm: float, k_s_n_per_mm: float, p_eff_n: float) -> dict:
    """theta (paper units) from (eta, c, k_s) and the preload P_eff [N] carried
    by the beam: F = P_eff (K_b + k_s) / K_b."""
    return beam.from_internal([eta_mpa_s, c_n_s_per_mm, p_eff_n, k_s_n_per_mm])


def paper_units(theta: dict, beam) -> dict:
    """A point's row of the tables: the parameters and P_eff, paper units."""
    return {
        "eta_MPa_s": theta["eta"],
        "c_N_s_per_mm": theta["c"],
        "F_N": theta["F"],
        "k_s_N_per_mm": theta["k_s"],
        "P_eff_N": float(beam.to_internal(theta)[2]),
    }


def preload_for_frequency(model, freq_hz: float, eta: float = 0.0) -> float:
    """P_eff [N] at which the model's linearised first mode is ``freq_hz``
    (k_s = c = 0 so that F = P_eff)."""
    p_cr = model.buckling_load()

    def f1(p):
        return model.modal_analysis(fe.Parameters(eta=eta, c=0.0, F=p, k_s=0.0), n_modes=1).frequencies_hz[0]

    lo, hi = 0.0, 0.995 * p_cr
    if not f1(hi) < freq_hz < f1(lo):
        raise ValueError(
            f"no preload between 0 and {hi:.1f} N gives a first mode at {freq_hz:.2f} Hz "
            f"(model: {f1(lo):.2f} Hz unloaded, {f1(hi):.2f} Hz near buckling); "
            "check the rig (length, thickness, modulus, bending_stiffness_factor)"
        )
    # Brent's method to 1e-9 of the buckling load: some ten modal analyses against the 50 of a
    # bisection to machine precision (0.2 s each on the default rig)
    return float(brentq(lambda p: f1(p) - freq_hz, lo, hi, xtol=1e-9 * p_cr))


def parabola_vertex(x, y) -> float:
    """Minimiser of the parabola through the lowest sample and its neighbours
    (the sample itself at an end of the range)."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    i = int(np.nanargmin(y))
    if i == 0 or i == x.size - 1:
        return float(x[i])
    a, b, _ = np.polyfit(x[i - 1 : i + 2], y[i - 1 : i + 2], 2)
    return float(-b / (2 * a)) if a > 0 else float(x[i])


@dataclass
class CalibrationResult:
    """Everything the two stages produced (paper units in the tables)."""

    final: dict
    linear_grid: list
    eta_scan: list
    nonlinear_grid: list
    refinement: list
    table1: list
    table2: list
    table3: dict
    ridge: dict
    validation: dict
    setup: dict
    timing: dict
    settings: CalibrationSettings
    final_theta: dict = field(repr=False, default=None)  # paper units
    final_params: fe.Parameters = field(repr=False, default=None)  # the same, SI
    velocities: dict = field(repr=False, default_factory=dict)
    problem: Problem | None = field(repr=False, default=None)

    def calibration_json(self) -> dict:
        f = self.final_params
        return {
            "eta": f.eta,
            "c": f.c,
            "F": f.F,
            "k_s": f.k_s,
            "P_eff": self.final["P_eff_N"],
            "e_lin": self.final["e_lin"],
            "e_nlin": self.final["e_nlin"],
            "units": {"eta": "Pa s", "c": "N s/m", "F": "N", "k_s": "N/m", "P_eff": "N"},
            "paper_units": self.table3,
            "ridge": self.ridge,
            "validation": {k: v for k, v in self.validation.items() if not k.startswith("_")},
            "setup": self.setup,
            "timing_s": self.timing,
            "settings": asdict(self.settings),
        }


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


# ---------------------------------------------------------------------- output


def format_tables(result: CalibrationResult) -> str:
    """Tables 1-3 in the paper's units, as text."""
    lines = [
        "Table 1 (linear stage, low-level chirp): minimum of e_lin per c",
        f"{'c [N s/mm]':>11} {'e_lin [%]':>10} {'F [N]':>8} {'k_s [N/mm]':>11} {'P_eff [N]':>10}",
    ]
    for r in result.table1:
        lines.append(
            f"{r['c_N_s_per_mm']:11g} {100 * r['e_lin']:10.3f} {r['F_N']:8.2f} "
            f"{r['k_s_N_per_mm']:11g} {r['P_eff_N']:10.2f}"
        )
    lines += [
        "",
        f"e_lin against eta: minimum at eta = {result.table3['eta_MPa_s']:.3f} MPa s",
        "",
        "Table 2 (nonlinear stage, high-level chirp): minimum of e_lin + e_nlin per c",
        f"{'c [N s/mm]':>11} {'e_lin+nlin [%]':>15} {'F [N]':>8} {'k_s [N/mm]':>11} {'P_eff [N]':>10}",
    ]
    for r in result.table2:
        lines.append(
            f"{r['c_N_s_per_mm']:11g} {100 * r['e_lin_nlin']:15.3f} {r['F_N']:8.2f} "
            f"{r['k_s_N_per_mm']:11g} {r['P_eff_N']:10.2f}"
        )
    t = result.table3
    lines += [
        "",
        "Table 3 (final, after local refinement)",
        f"eta = {t['eta_MPa_s']:.3f} MPa s, c = {t['c_N_s_per_mm']:.2f} N s/mm, F = {t['F_N']:.2f} N, "
        f"k_s = {t['k_s_N_per_mm']:.1f} N/mm, P_eff = {t['P_eff_N']:.2f} N; "
        f"e_lin = {100 * t['e_lin']:.3f} %, e_nlin = {100 * t['e_nlin']:.2f} %",
        f"k_s along the ridge: min over P_eff of e_lin+nlin stays within "
        f"{100 * result.ridge['rise']:.0f} % of its minimum for k_s in "
        f"{result.ridge['k_s_interval_N_per_mm'][0]:.0f}..{result.ridge['k_s_interval_N_per_mm'][1]:.0f}"
        f" N/mm (c = {result.ridge['c_N_s_per_mm']:g} N s/mm)",
        "",
        "Validation",
    ]
    for name, v in result.validation.items():
        if name.startswith("_"):
            continue
        s = f"  {name:14s} velocity rel. L2 = {100 * v['rel_l2']:.2f} %"
        if "harmonics_db" in v:
            h = ", ".join(f"{k} {'n/a' if d is None else f'{d:+.2f} dB'}" for k, d in v["harmonics_db"].items())
            s += f"; PSD model - data: {h}; RMS over 1-140 Hz {v['psd_db_rms']:.2f} dB"
        lines.append(s)
    lines.append(f"\n{result.setup['n_model_runs']} model runs in {result.timing['total']:.1f} s")
    return "\n".join(lines)
