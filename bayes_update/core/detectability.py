"""What the tests could have seen: for each candidate effect, the smallest magnitude
the discrepancy workflow would name on these tests (``detectable_from``).

A magnitude m in (0, 1] puts every parameter of the effect at ``null + m (far -
null)``, far the bound of its prior farther from the null (a symmetric effect,
whose prior spans both sides, is measured on its upper side).  On a geometric
ladder of magnitudes, with the model at the baseline's mode and the effect at m
(one run per test and magnitude, the effect's Jacobian by forward differences:
one more per parameter):

* the evidence the workflow would find on records holding the effect at m,
  scored as it scores it (:mod:`bayes_update.core.comparison`: each model under
  the noise and the model-form error its own residual leaves), each model at its
  linearised least-squares optimum: the model with the effect takes up the
  effect's change and whatever of the baseline's own residual the span of its
  parameters and the effect's holds; the model without it leaves the baseline's
  residual plus the part of the effect's change no change of the baseline's
  parameters takes up; ``2 ln B(m)`` is twice the difference of their Laplace
  log evidences (the effect's Jacobian in the first);
* the held-out gain: the validation tests' response change, with the baseline's
  parameters moved as the fit would move them (their Gauss-Newton step on the
  estimation tests' change), in units of the records' noise: the gain's z is
  half its norm (:mod:`bayes_update.core.held_out`: a model with the effect
  against one without, on a record holding it).

``detectable_from`` is the smallest m with ``2 ln B > DECISIVE`` and the held-out
z above :data:`~bayes_update.core.held_out.SIGNIFICANT_SD` (the log of m
interpolated between ladder points), reported in the effect's parameters' units;
None when not even the prior's far bound would be named.  Linearised about the
baseline's mode, so a limit is an estimate: the tests
(``tests/test_detectability.py``) run the whole workflow on data with the effect
just above and just below it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bayes_update.core.comparison import error_covariance, evidence, form_scale
from bayes_update.core.effects import DECISIVE, ExtendedSpace
from bayes_update.core.held_out import SIGNIFICANT_SD
from bayes_update.core.mode import FAILED_RESIDUAL, ResidualFunction, SpacePoint
from bayes_update.core.span import derivative_points
from surrogates.evaluation import evaluate_many

__all__ = ["LADDER", "detectability", "limit_text"]

#: the magnitudes tried, as fractions of the way from the null to the prior's far bound
LADDER = tuple(np.geomspace(1e-3, 1.0, 10))
#: the ratio of neighbouring rungs, and how far below the ladder it is extended where its
#: first rung is already named
RUNG = LADDER[1] / LADDER[0]
MIN_MAGNITUDE = 1e-7


@dataclass
class _Point:
    """Picklable: at internal point x of ``space``, the estimation tests' scaled residual
    and the validation tests' responses (None where the model cannot run)."""

    fun: ResidualFunction
    space: ExtendedSpace

    def __call__(self, x):
        problem, theta = self.fun.problem, self.space.to_parameters(x)
        r = self.fun(x) if self.fun.stages else np.zeros(0)
        if np.any(r == FAILED_RESIDUAL):
            return None
        try:
            v = {
                n: problem.compared_response(problem.run(theta, t.force, model=problem.model))
                for n, t in problem.validation.items()
            }
        except problem.failures:
            return None
        return r, v


def _far(p) -> float:
    """The bound of ``p``'s prior farther from its null (the upper one on a tie)."""
    return p.high if abs(p.high - p.null) >= abs(p.low - p.null) else p.low


def detectability(problem, base, fit, lik, effects: dict, executor=None) -> tuple[dict, int]:
    """``({effect: record}, model runs)`` for the baseline ``fit`` (its mode and
    Jacobian under ``lik``; module docstring).  Each record: ``detectable_from``
    ({parameter: value} or None), ``magnitude`` (its fraction of the way to the far
    bound), and the ladder's ``two_ln_B`` and ``held_out_z``."""
    out, runs = {}, 0
    x0 = np.asarray(fit.mode.x, float)
    Jb, r0 = np.asarray(fit.mode.jacobian, float), np.asarray(fit.mode.residual, float)
    Q = _span(Jb)
    steps = _base_steps(problem, fit, base, executor)
    runs += steps["runs"]
    base_space = ExtendedSpace(base)
    base_prior, base_widths = base_space.log_prior_density(x0), base_space.widths()
    sizes = [problem.output(st, problem.reference_components(st)).size for st in problem.stages]
    sd = [lik.scales[st].sd for st in problem.stages]
    # each test's noise covariance (and its observation basis); each model's form error comes
    # from what it leaves (bayes_update.core.comparison)
    noise = [error_covariance(problem, lik, st) for st in problem.stages]
    for name, params in effects.items():
        space = ExtendedSpace(base, list(params))
        fun = ResidualFunction(problem, problem.stages, tuple(sd), SpacePoint(space, problem.model))
        k, n0 = len(params), len(x0)
        far = np.array([_far(p) for p in params])
        null = np.array([p.null for p in params])
        box = space.box()[n0:]
        h = 1e-3 * (box[:, 1] - box[:, 0])

        def rungs(magnitudes):
            """The ladder's (m, 2 ln B, held-out z) at ``magnitudes``."""
            nonlocal runs
            points, shifts = [], []
            for m in magnitudes:
                xe = space.effects.to_internal({p.name: float(v) for p, v in zip(params, null + m * (far - null))})
                points.append(np.concatenate([x0, xe]))
                for i in range(k):  # the effect's Jacobian: a step of 1e-3 of its range, inwards
                    step = h[i] if xe[i] + h[i] <= box[i, 1] else -h[i]
                    points.append(points[-1 - i].copy())
                    points[-1][n0 + i] += step
                    shifts.append(step)
            done = evaluate_many(_Point(fun, space), points, executor, progress=False)
            runs += len(points) * (len(problem.stages) + len(problem.validation))
            return [
                _rung(
                    problem,
                    space,
                    sizes,
                    sd,
                    noise,
                    r0,
                    Jb,
                    Q,
                    steps,
                    m,
                    points[j * (k + 1)],
                    done[j * (k + 1)],
                    done[1 + j * (k + 1) : (j + 1) * (k + 1)],
                    shifts[j * k : (j + 1) * k],
                    base_prior,
                    base_widths,
                )
                for j, m in enumerate(magnitudes)
            ]

        ladder = rungs(LADDER)
        # named already at the first rung: the limit lies below it; go down until it is not
        # (a limit at the first rung would only be an upper bound)
        while _named(*ladder[0][1:]) and ladder[0][0] / RUNG > MIN_MAGNITUDE:
            lower = tuple(ladder[0][0] / RUNG ** np.arange(3, 0, -1))
            ladder = rungs(lower) + ladder
        out[name] = _limit(ladder, params, null, far)
    return out, runs


def _rung(
    problem, space, sizes, sd, noise, r0, Jb, Q, steps, m, x_at, at, cols, shifts, base_prior, base_widths
) -> tuple:
    """One ladder point: (m, 2 ln B, held-out z) from the runs at the effect's magnitude
    ``m`` (internal point ``x_at``, its runs ``at``) and its Jacobian's steps (``cols``,
    ``shifts``)."""
    if at is None or any(c is None for c in cols):
        return (m, None, None)
    dr = at[0] - r0
    perp = dr - Q @ (Q.T @ dr)
    Je = np.column_stack([(c[0] - at[0]) / shifts[i] for i, c in enumerate(cols)])
    # on records holding the effect at m, each model at its least-squares optimum (linearised): the
    # model with it takes up the effect's change and, with the baseline's parameters and its own,
    # whatever of the baseline's residual their span holds (an effect can also fit part of the
    # baseline's own misfit); the model without it leaves the baseline's residual plus what of the
    # effect's change its parameters cannot take up.  Each is scored under the noise and the
    # form error its own residual leaves (both counted alike: a form error from the change
    # before the refit, or a with-model charged the baseline's whole residual, made the limits
    # 2-7x off, either way).
    Qe = _span(np.column_stack([Jb, Je]))
    r_with, r_wo = r0 - Qe @ (Qe.T @ r0), r0 - perp  # r = (ref - out): the data moved by dout
    a_with, J_with, S_with, a_wo, J_wo, S_wo, row = {}, {}, {}, {}, {}, {}, 0
    for st, n, s, (S_noise, Qo) in zip(problem.stages, sizes, sd, noise):
        sl = slice(row, row + n)
        row += n
        eye = np.eye(len(S_noise))
        a_with[st] = Qo.T @ (r_with[sl] * s)
        J_with[st] = Qo.T @ (np.column_stack([Jb[sl], Je[sl]]) * s)
        S_with[st] = S_noise + form_scale(S_noise, a_with[st]) * eye
        a_wo[st] = Qo.T @ (r_wo[sl] * s)
        J_wo[st] = Qo.T @ (Jb[sl] * s)
        S_wo[st] = S_noise + form_scale(S_noise, a_wo[st]) * eye
    z_with = evidence(a_with, J_with, S_with, space.log_prior_density(x_at), space.widths())[0]
    z_wo = evidence(a_wo, J_wo, S_wo, base_prior, base_widths)[0]
    two_ln_b = 2.0 * (z_with - z_wo) if np.isfinite(z_with) and np.isfinite(z_wo) else None
    return (m, two_ln_b, _held_out_z(problem, at[1], steps, dr))


def limit_text(record: dict) -> str:
    """An effect's limit in words, for tables and logs: "k2 = 0.43"; "at most ..." where
    even the ladder's lowest rung would be named; "not even at its prior's bound"."""
    lim = record.get("detectable_from")
    if not lim:
        return "not even at its prior's bound"
    text = ", ".join(f"{k} = {v:.3g}" for k, v in lim.items())
    return f"at most {text} (the lowest magnitude tried)" if record.get("below_ladder") else text


def _span(J) -> np.ndarray:
    U, S, _ = np.linalg.svd(J, full_matrices=False)
    return U[:, : int(np.sum(S > 1e-8 * S[0]))] if S.size and S[0] > 0 else U[:, :0]


def _base_steps(problem, fit, base, executor) -> dict:
    """The validation tests' responses at the baseline's mode and their derivative with
    respect to its parameters (forward differences, d + 1 runs per validation test), and
    the Gauss-Newton map from an estimation-residual change to the baseline's parameter step."""
    if not problem.validation:
        return {"runs": 0}
    space = ExtendedSpace(base)
    fun = ResidualFunction(problem, (), (), SpacePoint(space, problem.model))
    x0, _, steps, points = derivative_points(space, space.to_parameters(np.asarray(fit.mode.x, float)))
    pts = [x0] + points
    done = evaluate_many(_Point(fun, space), pts, executor, progress=False)
    if any(d is None for d in done):
        return {"runs": len(pts) * len(problem.validation)}
    v0 = done[0][1]
    Jv = {n: np.stack([(d[1][n] - v0[n]) / steps[i] for i, d in enumerate(done[1:])], axis=-1) for n in v0}
    return {
        "runs": len(pts) * len(problem.validation),
        "v0": v0,
        "Jv": Jv,
        "gn": np.linalg.pinv(np.asarray(fit.mode.jacobian, float)),
    }


def _held_out_z(problem, v, steps, dr) -> float | None:
    """The held-out gain's z of a model with the effect against one without, on records
    that hold it: half the noise-weighted norm of the validation tests' change, the
    baseline's parameters moved by their Gauss-Newton step on the estimation change."""
    if "v0" not in steps:
        return None
    dx = -steps["gn"] @ dr
    total = 0.0
    for n, t in problem.validation.items():
        change = (v[n] - steps["v0"][n]) + steps["Jv"][n] @ dx
        sigma = np.asarray(problem.test_noise(n), float)
        total += float(np.sum(change.reshape(len(change), -1) ** 2 / sigma**2))
    return 0.5 * math.sqrt(total)


def _named(two_ln_b, z) -> bool:
    return two_ln_b is not None and two_ln_b > DECISIVE and (z is None or z > SIGNIFICANT_SD)


def _limit(ladder, params, null, far) -> dict:
    """The smallest magnitude on ``ladder`` [(m, 2 ln B, held-out z)] that would be named;
    ``below_ladder`` where even its lowest rung is (the limit is then an upper bound)."""
    named = _named

    def margin(two_ln_b, z):  # > 0 where named: the smaller of the two margins, in log
        if two_ln_b is None:
            return -math.inf
        a = math.log(max(two_ln_b, 1e-3) / DECISIVE)
        return a if z is None else min(a, math.log(max(z, 1e-6) / SIGNIFICANT_SD))

    record = {
        "ladder": [{"magnitude": m, "two_ln_B": b, "held_out_z": z} for m, b, z in ladder],
        "detectable_from": None,
        "magnitude": None,
        "below_ladder": bool(ladder and named(*ladder[0][1:])),
    }
    for i, (m, b, z) in enumerate(ladder):
        if not named(b, z):
            continue
        if i > 0 and ladder[i - 1][1] is not None:
            m0, g0, g1 = ladder[i - 1][0], margin(*ladder[i - 1][1:]), margin(b, z)
            m = math.exp(math.log(m0) + (math.log(m) - math.log(m0)) * (-g0) / (g1 - g0)) if g1 > g0 else m
        record["magnitude"] = float(m)
        record["detectable_from"] = {p.name: float(n + m * (f - n)) for p, n, f in zip(params, null, far)}
        break
    record["text"] = limit_text(record)
    return record
