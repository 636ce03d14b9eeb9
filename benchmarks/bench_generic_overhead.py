"""What the generic framework adds to the beam's cost per likelihood evaluation.

``sample`` spends its time in evaluations: one model run per test plus the
projection of the response on the Volterra regressors.  This benchmark times,
in one run, the same evaluation of the embedded default data set two ways:

* **by hand**: ``fe.simulate`` on each test's force, the projector's
  components, the relative errors (what a beam-only code would do);
* **through the framework**: ``bayes_update.core.posterior.target.Evaluate`` on
  the beam's problem (:func:`bayes_update.core.calibrate.problem_for` with the
  beam as a model of the contract: internal coordinates -> parameters,
  ``Problem.run``, the metric set).

Median of 9 runs after warm-up, one BLAS thread, for the modal ROM and the
full FE.  The difference is the generic layer's overhead per evaluation, and
so (evaluations being almost all of it) per ``sample``.

    python benchmarks/bench_generic_overhead.py
"""

import sys
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).parent))
from _machine import machine, median_time  # noqa: E402

import fe  # noqa: E402
from bayes_update.core.calibrate import problem_for  # noqa: E402
from bayes_update.core.posterior.target import Evaluate  # noqa: E402
from bayes_update.models.beam.model import Beam  # noqa: E402
from bayes_update.models.beam.rig import rig_of  # noqa: E402
from bayes_update.models.beam.virtual_rig import load_default_dataset  # noqa: E402


def main():
    data = load_default_dataset()
    rig = rig_of(data)
    print(f"machine: {machine()}")
    print(f"{'model':>6} {'by hand [ms]':>14} {'framework [ms]':>15} {'overhead':>9}")
    for name, model in (("rom", fe.ModalROM(rig=rig)), ("fe", fe.BeamModel(rig=rig))):
        problem = problem_for(data, Beam(model))
        space = problem.space
        params = fe.Parameters(eta=3.0e6, c=15.7e3, F=76.0, k_s=122.0e3)
        x = space.to_internal(Beam(model).theta_of(params))
        stages = problem.stages
        evaluate = Evaluate(problem, space, stages)
        projectors = {st: problem.projector(st) for st in stages}
        refs = {st: problem.output(st, problem.reference_components(st)) for st in stages}

        def by_hand():
            out = {}
            for st in stages:
                test = problem.tests[st]
                v = fe.simulate(
                    model, params, test.force, fs=problem.fs, positions=[rig.sensor_position_m]
                ).sensor_velocity
                comps = projectors[st].components(v)
                y = comps[1] if st == "linear" else comps[2] + comps[3]
                out[st] = np.linalg.norm(refs[st] - y) / np.linalg.norm(refs[st])
            return out

        def framework():
            return evaluate(x)

        a, b = by_hand(), framework()
        assert all(abs(a[st] - b["e_lin" if st == "linear" else "e_nlin"]) < 1e-12 for st in stages), (a, b)
        with threadpool_limits(1):
            t_hand = median_time(by_hand, repeats=9)
            t_frame = median_time(framework, repeats=9)
        print(f"{name:>6} {1e3 * t_hand:>14.2f} {1e3 * t_frame:>15.2f} {100 * (t_frame / t_hand - 1):>8.1f} %")


if __name__ == "__main__":
    main()
