"""The noise replicates' response to the force noise without a model run each
(:func:`bayes_update.core.likelihood.estimate_likelihood` with
``model_replicates``): a linear time-invariant estimate of the model from one
run, and the control variate that corrects it with a few replicates run on the
model (docs/likelihood.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["ScalesRun", "control_variate_rows", "draw_replicates", "lti_fit", "lti_response"]


@dataclass
class ScalesRun:
    """Picklable runner of the likelihood scales' model runs at ``params``, each a
    task ``(kind, stage, argument)``: ``("force", stage, f)`` the response to force
    f, ``("refined", stage, f)`` the refined model's, ``("output", stage, x)`` the
    stage's compared output at internal point x (the span's differences).  One
    list of tasks for every stage goes to the executor at once, so the workers
    never wait for one stage to finish before the next starts."""

    problem: object
    params: dict
    space: object = None
    refined: object = None

    def __call__(self, task):
        kind, stage, arg = task
        if kind == "force":
            return self.problem.run(self.params, arg)
        if kind == "refined":
            return self.problem.run(self.params, arg, model=self.refined)
        if kind == "output":
            from bayes_update.core.span import StageOutput

            return StageOutput(self.problem, stage, self.space)(arg)
        raise ValueError(f"unknown task {kind!r}")


def lti_response(problem, params, stage: str, v0, amplitude: float, rng):
    """``du -> the model's response change to a small force change du`` as a linear
    time-invariant system: one model run with a white probe of sd ``amplitude``
    added to the recorded force, then :func:`lti_fit`."""
    force = problem.tests[stage].force
    probe = amplitude * rng.standard_normal(force.size)
    return lti_fit(probe, problem.run(params, force + probe) - v0)


def lti_fit(probe, dv):
    """The impulse response g (half the record long) that fits a run's response
    change ``dv`` to a force ``probe`` by least squares, ``dv = g * probe`` causal
    and from rest as the model ran it (LSQR on the convolution, FFT products);
    returns ``du -> g * du``.  Exact for a linear model whose impulse response
    has decayed within half the record; for a nonlinear one it is the
    linearisation about the record, averaged over time."""
    from scipy import signal
    from scipy.sparse.linalg import LinearOperator, lsqr

    n = probe.size
    length = n // 2
    cols = dv[:, None] if dv.ndim == 1 else dv
    reverse = probe[::-1]
    op = LinearOperator(
        (n, length),
        dtype=float,
        matvec=lambda g: signal.fftconvolve(probe, np.ravel(g))[:n],
        rmatvec=lambda y: signal.fftconvolve(np.ravel(y), reverse)[n - 1 : n - 1 + length],
    )
    g = [lsqr(op, cols[:, j], atol=1e-10, btol=1e-10, iter_lim=200)[0] for j in range(cols.shape[1])]

    def response(du):
        out = np.column_stack([signal.fftconvolve(du, gj)[:n] for gj in g])
        return out[:, 0] if dv.ndim == 1 else out

    return response


def control_variate_rows(row, lti, cheap: list, pairs: list, pair_runs: list, v0) -> tuple[np.ndarray, np.ndarray]:
    """The replicates' residual rows and their weights with the force noise's
    response taken from an LTI estimate (:func:`lti_fit`, one model run) and
    corrected by a control variate: the ``k`` ``pairs`` of draws run on the model
    (``pair_runs``) and, with the same noise, on the LTI estimate.  ``cheap``: the
    K draws (force noise, response noise) on the LTI estimate alone; ``row(noise,
    dv)``: a replicate's residual row.  The second moment ``sum_i w_i d_i d_i^T``
    is then ``E_LTI[dd^T]`` from the K cheap rows (weight 1/K) plus
    ``E_model[dd^T] - E_LTI[dd^T]`` from the k pairs (weights +1/k, -1/k):
    unbiased for the model, and precise where the LTI estimate follows the
    model replicate by replicate.  On the beam's default data set (ROM) the
    pairs' rows differ by 1.8 % of their norm at the low level and by 39 % at
    the high one (the linearisation varies along the record there); s_n over
    three seeds: 0.0493-0.0516 % and 0.182-0.205 % against 0.0503-0.0540 % and
    0.179-0.195 % from 96 replicates all run on the model (36 runs against 192)."""
    rows = [row(noise, lti(du)) for du, noise in cheap]
    pairs_model = [row(noise, v - v0) for (_, noise), v in zip(pairs, pair_runs)]
    pairs_lti = [row(noise, lti(du)) for du, noise in pairs]
    D = np.array(rows + pairs_model + pairs_lti)
    k, n = len(pairs), len(cheap)
    w = np.concatenate([np.full(n, 1.0 / n), np.full(k, 1.0 / k), np.full(k, -1.0 / k)])
    return D, w


def draw_replicates(problem, stage: str, n_replicates: int, model_replicates, rng) -> dict:
    """A stage's noise replicates, drawn (no model run): ``cheap``, the (force noise,
    response noise) pairs of the replicates; with ``model_replicates`` k and a noisy
    force, the LTI estimate's white ``probe`` and the k ``pairs`` run on the model as
    well, drawn in that order (:func:`bayes_update.core.replicates.control_variate_rows`);
    ``forces``: the forces the model runs (the probe's first)."""
    test = problem.tests[stage]
    # the measured noise of each channel (bayes_update.data.noise: declared, periods,
    # zero-input sections, quiet band, or the linear test's fit residual carried over)
    est = problem.noise[test.name]
    sig_f = est["force"].sd if est["force"].sd is not None else 0.0
    sig_y = np.array([est[name].sd for name, _ in problem.sensors])
    sig_y = sig_y.reshape(test.response.shape[1:])  # a float for one sensor, one per sensor else
    n, k = test.force.size, len(problem.sensors)
    shape = (n,) if k == 1 else (n, k)  # the shape of Problem.run's response

    def draw():
        return sig_f * rng.standard_normal(n), sig_y * rng.standard_normal(shape)

    plan = {"force": test.force, "estimates": est, "probe": None, "pairs": []}
    if model_replicates is None or sig_f == 0.0:
        plan["cheap"] = [draw() for _ in range(n_replicates)]
        plan["forces"] = [test.force + du for du, _ in plan["cheap"]] if sig_f else []
    else:
        plan["probe"] = sig_f * rng.standard_normal(n)
        plan["cheap"] = [draw() for _ in range(n_replicates)]
        plan["pairs"] = [draw() for _ in range(int(model_replicates))]
        plan["forces"] = [test.force + plan["probe"]] + [test.force + du for du, _ in plan["pairs"]]
    return plan
