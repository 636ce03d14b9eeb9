"""The model side of a :class:`~bayes_update.core.problem.Problem`: running its model.

:class:`ProblemModel`, the base class of :class:`~bayes_update.core.problem.Problem`,
runs the model at a point (through the run store when one is attached, every
response checked by :func:`~bayes_update.core.model.check_response`), finds the
refined model of the model-error term, and says what identifies the model.  It
is apart from the comparison (the basis, the projections and the metrics, in
:mod:`bayes_update.core.problem`): nothing here knows a stage's metric.
"""

from __future__ import annotations

import hashlib
import pickle

import numpy as np

from bayes_update.core.model import ModelError, check_response, run_error


class ProblemModel:
    """Runs of a problem's model, its refined model and its identity.

    The base of :class:`~bayes_update.core.problem.Problem`, which sets what it
    reads: ``model``, ``fs``, ``sensors``, ``tests`` and ``stages`` (and
    ``space`` once a builder has set it).
    """

    #: exceptions that mean "the model cannot run at this point": the point gets
    #: NaN metrics (and a message) instead of stopping a design
    failures: tuple = (ModelError,)
    #: where model runs are kept and found (:class:`bayes_update.core.runs.RunStore`), or None
    run_store = None

    def run(self, params, force, model=None) -> np.ndarray:
        """Response of ``model`` (default: the problem's) at ``params`` to ``force``
        sampled at the data's rate: ``model.simulate(theta, force, fs)``, (n,)
        for one sensor, (n, n_sensors) for several."""
        model = self.model if model is None else model
        store = self.run_store
        if store is not None:
            kept = store.get(model, force, self.fs, params)
            if isinstance(kept, Exception):
                raise kept
            if kept is not None:
                return self._checked(model, params, kept, len(force))
        try:
            y = model.simulate(params, force, self.fs)
        except self.failures as exc:
            if store is not None:
                store.put(model, force, self.fs, params, error=str(exc))
            raise  # this point cannot run: the caller gives it NaN metrics
        except Exception as exc:  # a bug of the model, not a region of its parameters
            raise run_error(
                model,
                params,
                f"raised {type(exc).__name__}: {exc}",
                "fix the model there, or, where it cannot run, raise bayes_update.ModelError "
                "(that point then gets no likelihood and the run goes on)",
            ) from exc
        y = self._checked(model, params, y, len(force))
        if store is not None:
            store.put(model, force, self.fs, params, response=y)
        return y

    def _checked(self, model, params, y, n: int) -> np.ndarray:
        """A model's response as (n,) or (n, n_sensors), or a :class:`~bayes_update.core.model.ModelRunError`
        naming the model, the theta and the remedy (:func:`~bayes_update.core.model.check_response`)."""
        return check_response(model, params, y, n, len(self.sensors))

    # ------------------------------------------------ what a model may refine
    def default_space(self):
        """The prior when none is given: the model's declared parameters."""
        from bayes_update.core.parameters import ParameterSet

        return ParameterSet(self.model.parameters, self.model)

    def refined_model(self):
        """The finer model of the same physics for the model-error term: the
        model's ``refined()``, else the model at twice the sampling rate where it
        runs there as a discretisation (:mod:`bayes_update.core.refinement`), else
        None (the term is then zero); :meth:`refinement_source` says which."""
        return self._refinement()[0]

    def refinement_source(self) -> str:
        """What the model error is measured against, or why it is zero (for the log)."""
        return self._refinement()[1]

    def _refinement(self):
        if getattr(self, "_refined", None) is None:
            if hasattr(self.model, "refined"):
                self._refined = (self.model.refined(), f"{type(self.model).__name__}.refined()")
            else:
                from bayes_update.core.refinement import twice_the_rate

                test = self.tests[self.stages[0]]
                # probed inside the prior in use (a run outside a prior the user narrowed can fail)
                space = getattr(self, "space", None) or self.default_space()
                self._refined = twice_the_rate(self.model, space.center(), test.force, self.fs)
        return self._refined

    def describe_model(self) -> dict:
        """What identifies the model in a cache key and a report: the model's own
        ``describe()``, else its class and a hash of its pickled state (its constants)."""
        if callable(getattr(self.model, "describe", None)):
            return self.model.describe()
        state = hashlib.sha256(pickle.dumps(self.model)).hexdigest()[:16]
        return {"kind": type(self.model).__name__, "state_sha256": state}
