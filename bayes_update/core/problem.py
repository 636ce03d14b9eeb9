"""The metrics of a data set on any model: :class:`Problem` (which part of
each test's expansion a metric compares: :mod:`bayes_update.core.metrics`).
Reference and model responses are expanded in the *same* Kautz basis under the
*same recorded input*: the basis (poles and J per order) is fixed once per data
set from the reference linear test, and the model is driven by the recorded
input of each test, so the regressors are factored once per test
(:class:`volterra.VolterraProjector`) and an evaluation costs one model run per
test plus two small matrix-vector products.

Running the model (through the run store, each response checked), its refined
model and its identity are the base class's (:mod:`bayes_update.core.problem_model`);
the roles a data set's tests must have are :mod:`bayes_update.core.roles`'s."""

from __future__ import annotations

import math
import uuid
from dataclasses import dataclass

import numpy as np

import volterra
from bayes_update.core.basis import DEFAULT_N_FUNCTIONS, FEEDTHROUGH, basis_from_reference, describe_basis
from bayes_update.core.metrics import (
    METRIC_SETS,
    STAGE_ORDERS,
    STAGES,
    metric_key,
    n_compared_regressors,
    relative_error,
    stage_name,
    stage_output,
    stage_role,
)
from bayes_update.core.problem_model import ProblemModel
from bayes_update.core.roles import require_roles
from bayes_update.core.weights import effective_noise, linear_gain, representation_floor
from bayes_update.data.checks import require_live_force
from bayes_update.data.dataset import DatasetError
from bayes_update.data.modes import without_offsets
from bayes_update.data.noise import dataset_noise

__all__ = ["Problem", "require_roles"]


@dataclass(frozen=True)
class _Test:
    name: str
    force: np.ndarray
    response: np.ndarray  # (n,), or (n, n_sensors)

    @property
    def velocity(self) -> np.ndarray:
        """The response under the beam's name for it (its sensor measures velocity)."""
        return self.response


#: factored projectors of the problems a worker process has seen (token -> {stage: projector})
_WORKER_PROJECTORS: dict = {}


class Problem(ProblemModel):
    """Reference data + a model + a fixed Kautz basis -> metrics.

    Parameters
    ----------
    dataset : the measured (or synthetic) data set (``tests`` with roles,
        ``sampling_rate_hz``); it must hold a test with role ``linear`` and,
        for e_nlin, one with role ``nonlinear``.  Every test of these roles is
        a stage of the estimation (:data:`~bayes_update.core.metrics.STAGES`):
        the first of each role the stage of its name, each further one
        ``role:test name`` (:func:`~bayes_update.core.metrics.stage_name`),
        in the data set's order.
    model : a model of the contract (:mod:`bayes_update.core.model`):
        ``simulate(theta, force, fs) -> response``.
    n_functions : J per kernel order, used when ``basis`` is not given.
    basis : a fixed :class:`volterra.KautzBasis`; default: from the reference
        linear test (:func:`basis_from_reference`).
    metrics : the metric set, ``"paper"`` or ``"full"`` (:data:`METRIC_SETS`);
        default: the model's ``default_metrics``, else ``"full"``.
    noise : ``{test name: {channel: NoiseEstimate}}``, the measurement noise of
        every channel (default: :func:`bayes_update.data.noise.dataset_noise`,
        which raises, saying what to add, when a sensor offers no estimate).

    Tests with role ``validation`` are kept for :meth:`prediction_errors`;
    the metrics never see them.

    The object pickles without its factored projectors (they are rebuilt
    lazily), so it can be shipped to worker processes.  Its model's runs
    (:meth:`run`), refined model and identity come from its base,
    :class:`~bayes_update.core.problem_model.ProblemModel`.
    """

    #: names of the parameters the linear test moves, once a screen has found them
    #: (:func:`bayes_update.core.calibrate.problem_for`), and their sensitivities; None before
    linear_parameters: tuple | None = None
    linear_sensitivity: dict | None = None
    #: the prior the problem was built for (:func:`bayes_update.core.calibrate.problem_for`)
    space = None
    #: model runs the builder's screen took
    n_screen_runs: int = 0
    #: the candidate effects the builder checked, for the discrepancy workflow ({} otherwise)
    effects: dict | None = None

    def __init__(self, dataset, model, n_functions=DEFAULT_N_FUNCTIONS, basis=None, metrics=None, noise=None):
        if not hasattr(model, "simulate"):
            raise TypeError(f"{type(model).__name__} is not a model (no simulate method)")
        if callable(getattr(model, "check_dataset", None)):
            model.check_dataset(dataset)  # the model's own word on the data (the beam: its rig)
        self.fs = float(dataset.sampling_rate_hz)
        self.model = model
        # a record's mean is a sensor offset, not physics: it is removed from the input
        # (the model never sees it) and from the response, unless the model says its
        # records carry none (the beam's virtual rig: its numbers stay the paper study's)
        self.remove_offsets = bool(getattr(model, "remove_offsets", True))
        self.source = dataset.source or dataset.name
        self.sensors = tuple(dataset.sensors)
        self.data_fingerprint = dataset.fingerprint()
        metrics = getattr(model, "default_metrics", "full") if metrics is None else metrics
        if metrics not in METRIC_SETS:
            raise ValueError(f"metrics must be one of {sorted(METRIC_SETS)}, got {metrics!r}")
        self.metrics = metrics
        require_roles(dataset)
        self.tests = {
            stage_name(role, t.name, i == 0): self._test(t)
            for role in STAGES
            for i, t in enumerate(dataset.by_role(role))
        }
        self.validation = {t.name: self._test(t) for t in dataset.by_role("validation")}
        found_linear = dataset.by_role("linear")
        lin = self.tests["linear"]
        if basis is None:
            # the poles are the structure's: every sensor shows them, fitted jointly; orders 2-3 on
            # the mode the nonlinear test needs (nonlinear_mode_for: 1.19x -> 1.02x a direct fit's error)
            high = self.tests.get("nonlinear")
            basis = basis_from_reference(
                lin.force,
                lin.response,
                self.fs,
                n_functions,
                FEEDTHROUGH[metrics],
                period_samples=getattr(found_linear[0], "period_samples", None),
                nonlinear=None if high is None else (high.force, high.response),
            )
        if not isinstance(basis, volterra.KautzBasis):
            raise TypeError("basis must be a volterra.KautzBasis")
        if basis.fs != self.fs:
            raise ValueError(f"basis sampling rate {basis.fs} Hz differs from the data's {self.fs} Hz")
        if not {1, 2, 3} <= set(basis.orders):
            raise ValueError(f"the basis needs orders 1, 2 and 3, got {basis.orders}")
        self.basis = basis
        # the measurement noise of every channel of every test, found once per data set
        self.noise = noise if noise is not None else dataset_noise(dataset)
        self._gain = None
        self._projectors = {}
        self._reference = {}
        self._sensor_noise = {}
        self._token = uuid.uuid4().hex  # identifies this problem's projectors in worker processes

    def _test(self, record) -> _Test:
        require_live_force(record)
        return _Test(record.name, *without_offsets(record.force, record.response, self.remove_offsets))

    # ------------------------------------------------------------ pickling
    def __getstate__(self):
        state = self.__dict__.copy()
        state["_projectors"] = {}
        return state

    def __setstate__(self, state):
        # a worker process receives this problem once per task; the factored
        # projectors (~0.5 s to build, ten FE runs) are kept per process and
        # problem, so only the first task of a worker builds them
        self.__dict__.update(state)
        token = state.get("_token")
        if token is not None:
            if token not in _WORKER_PROJECTORS and len(_WORKER_PROJECTORS) >= 8:
                _WORKER_PROJECTORS.pop(next(iter(_WORKER_PROJECTORS)))
            self._projectors = _WORKER_PROJECTORS.setdefault(token, {})

    # ---------------------------------------------------------- components
    @property
    def stages(self) -> tuple:
        """Stages the data support: ('linear',), ('linear', 'nonlinear'), and a stage
        ``role:test name`` per further test of a role, the linear ones first."""
        return tuple(self.tests)  # built role by role, in the order of STAGES

    def stages_of(self, role: str) -> tuple:
        """The stages of one role (``"linear"``: the low-level tests)."""
        return tuple(s for s in self.stages if stage_role(s) == role)

    def stage_rows(self, stages=None) -> dict:
        """``{stage: slice}``: each stage's rows in a residual of ``stages`` (default all)
        concatenated in their order (the stages' compared outputs differ in length when
        their records do)."""
        out, start = {}, 0
        for st in self.stages if stages is None else stages:
            n = self.output(st, self.reference_components(st)).size
            out[st], start = slice(start, start + n), start + n
        return out

    def compared_orders(self, stage: str) -> tuple:
        """The kernel orders the stage's metric compares (:data:`METRIC_SETS`)."""
        return METRIC_SETS[self.metrics][stage_role(stage)]

    def _check_stage(self, stage):
        stage_role(stage)
        if stage not in self.tests:
            raise DatasetError(
                f"{self.source}: no test has role {stage!r}, so e_nlin cannot be "
                "computed; add the high-level test with role 'nonlinear'"
            )

    def projector(self, stage: str) -> volterra.VolterraProjector:
        self._check_stage(stage)
        if stage not in self._projectors:
            basis = self.basis.subset(STAGE_ORDERS[stage_role(stage)])
            self._projectors[stage] = volterra.VolterraProjector(self.tests[stage].force, basis)
        return self._projectors[stage]

    def components(self, stage: str, response, projector=None) -> dict:
        """{order: y_n} of a response record under the stage's recorded force
        (orders :data:`STAGE_ORDERS` of the stage; ``projector``: another input's).

        Several sensors (response (n, n_sensors)): each sensor's components,
        divided by that sensor's measured noise (:meth:`sensor_noise`), one
        after the other; the metrics then weigh the sensors by their noise."""
        proj = self.projector(stage) if projector is None else projector
        y = np.asarray(response, float)
        if y.ndim == 1:
            return proj.components(y)
        per = [proj.components(y[:, j]) for j in range(y.shape[1])]
        w = 1.0 / self.sensor_noise(stage)
        return {n: np.concatenate([w[j] * c[n] for j, c in enumerate(per)]) for n in per[0]}

    def sensor_noise(self, stage: str) -> np.ndarray:
        """Measurement noise of each sensor of the stage's test [sensor unit]: its
        own noise and the force channel's through the structure
        (:func:`bayes_update.core.weights.effective_noise`; the estimates in
        :attr:`noise`)."""
        if stage not in self._sensor_noise:
            self._check_stage(stage)
            self._sensor_noise[stage] = self.test_noise(self.tests[stage].name)
        return self._sensor_noise[stage]

    def test_noise(self, name: str) -> np.ndarray:
        """:meth:`sensor_noise` of any test of the data set, by name."""
        if self._gain is None:
            lin = self.tests["linear"]
            self._gain = linear_gain(lin.force, lin.response, self.basis)
        return effective_noise(self.noise[name], self.sensors, self._gain)

    def representation_floor(self, stage: str) -> float:
        """The share of the stage's reference rms its own Volterra fit (orders
        :data:`STAGE_ORDERS`) leaves unexplained beyond the noise [-]
        (:func:`bayes_update.core.weights.representation_floor`): what orders
        1-3 in this basis cannot represent, never folded into the weights."""
        y = self.tests[stage].response
        y2 = y[:, None] if y.ndim == 1 else y
        proj = self.projector(stage)
        fitted = np.column_stack([sum(proj.components(y2[:, j]).values()) for j in range(y2.shape[1])])
        return representation_floor(y2, fitted, self.sensor_noise(stage))

    def reference_components(self, stage: str) -> dict:
        if stage not in self._reference:
            self._reference[stage] = self.components(stage, self.tests[stage].response)
        return self._reference[stage]

    def simulate(self, params, stage: str) -> np.ndarray:
        """Model response under the stage's recorded force."""
        self._check_stage(stage)
        return self.run(params, self.tests[stage].force)

    # ------------------------------------------------------------- metrics
    def output(self, stage: str, comps: dict) -> np.ndarray:
        """The part of a stage's components its metric compares (:data:`METRIC_SETS`)."""
        return stage_output(stage, comps, self.metrics)

    @property
    def output_unit(self) -> str:
        """Unit of the compared outputs: the sensor's (one sensor), else each
        sensor's noise sd (several sensors: the outputs are noise-weighted)."""
        from bayes_update.data.dataset import RESPONSE_UNITS

        return RESPONSE_UNITS[self.sensors[0][1]] if len(self.sensors) == 1 else "noise sd"

    @property
    def response_unit(self) -> str:
        """Unit of the records' responses: the sensors' common unit, else each sensor's
        (``"acc1: m/s^2, disp: m"``)."""
        from bayes_update.data.dataset import RESPONSE_UNITS

        units = [RESPONSE_UNITS[kind] for _, kind in self.sensors]
        if len(set(units)) == 1:
            return units[0]
        return ", ".join(f"{name}: {u}" for (name, _), u in zip(self.sensors, units))

    @property
    def sensor_keys(self) -> tuple:
        """A JSON key per sensor naming it and its unit, ``<name>_<unit>`` with the
        unit's ``/`` as ``_`` and no ``^``: ``velocity_m_s``, ``displacement_m``,
        ``tip_acc_m_s2``."""
        from bayes_update.data.dataset import RESPONSE_UNITS

        return tuple(f"{name}_{RESPONSE_UNITS[kind].replace('/', '_').replace('^', '')}" for name, kind in self.sensors)

    def n_regressors(self, stage: str) -> int:
        """Coefficients behind the stage's metric (the noise's directions in it)."""
        return n_compared_regressors(self.projector(stage).basis, stage, self.metrics)

    def metric(self, stage: str, response) -> float:
        """The stage's metric (:func:`~bayes_update.core.metrics.metric_key`: e_lin on
        stage 'linear', e_nlin on 'nonlinear') of a model response."""
        return relative_error(
            self.output(stage, self.reference_components(stage)), self.output(stage, self.components(stage, response))
        )

    def noise_sd(self, stage: str) -> float:
        """The measurement noise of the stage's compared output, per sample: the
        sensor's (:meth:`sensor_noise`, its unit) for one sensor; 1 for several
        (their components are divided by their own noise)."""
        self._check_stage(stage)
        noise = self.sensor_noise(stage)
        return float(noise[0]) if len(noise) == 1 else 1.0

    def compared_response(self, y) -> np.ndarray:
        """A model response as it is compared with a record's: without its mean (each
        sensor's) when the records' means are removed as sensor offsets
        (``remove_offsets``).  The record's mean is gone, so the model's must go too:
        a displacement's physical mean (a quadratic spring's static shift) would
        otherwise count as error of a model that is exact."""
        y = np.asarray(y, float)
        return y - y.mean(axis=0) if self.remove_offsets else y

    def prediction_errors(self, params, model=None) -> dict:
        """Direct output error of the model on every validation test:
        ``{test name: ||y - y_model|| / ||y||}`` (the record's means removed, and the
        model output's, :meth:`compared_response`; several sensors: the rms over the
        sensors of each one's relative error, so that no sensor's unit outweighs
        another's); NaN where the model cannot run."""
        out = {}
        for name, t in self.validation.items():
            try:
                y = self.compared_response(self.run(params, t.force, model=model))
            except self.failures:
                out[name] = math.nan
                continue
            if t.response.ndim == 1:
                out[name] = relative_error(t.response, y)
            else:
                out[name] = float(
                    np.sqrt(
                        np.mean([relative_error(t.response[:, j], y[:, j]) ** 2 for j in range(t.response.shape[1])])
                    )
                )
        return out

    def evaluate(self, params, stages=None) -> dict:
        """Metrics at one parameter point (``stages``: default all of :attr:`stages`).

        Returns ``{"e_lin": float, "e_nlin": float, "error": None}`` (only the
        requested stages; a further test's metric under its
        :func:`~bayes_update.core.metrics.metric_key`); a model failure (buckling, Newton divergence) gives
        NaN metrics and the message in ``"error"`` instead of raising, so that
        one bad point does not stop a grid.
        """
        stages = self.stages if stages is None else (stages,) if isinstance(stages, str) else stages
        for s in stages:
            self._check_stage(s)
        out = {}
        try:
            for s in stages:
                out[metric_key(s)] = self.metric(s, self.simulate(params, s))
            out["error"] = None
        except self.failures as exc:
            for s in stages:
                out[metric_key(s)] = math.nan
            out["error"] = f"{type(exc).__name__}: {exc}"
        return out

    def describe(self) -> dict:
        """JSON-ready description of how the metrics are computed."""
        return {
            "basis": describe_basis(self.basis),
            "metric_set": self.metrics,
            "orders_fitted": {s: list(STAGE_ORDERS[stage_role(s)]) for s in self.tests},
            "orders_compared": {s: list(self.compared_orders(s)) for s in self.tests},
            "tests": {s: t.name for s, t in self.tests.items()},
            "model": self.describe_model(),
        }
