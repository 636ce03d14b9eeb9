"""bayes_update: probabilistic updating of nonlinear structural models with Volterra
series (after Bussetta, Shiki and da Silva, 2017).

A model is any object with declared ``parameters`` (:class:`Parameter`) and
``simulate(theta, force, fs)`` (:mod:`bayes_update.core.model`, docs/models.md).
The verbs::

    import bayes_update as bu
    data = bu.read_dataset("my_rig/")          # dataset.json + one CSV per test
    cal = bu.calibrate(data, model)            # the two-stage deterministic calibration
    post = bu.sample(data, model)              # the posterior (post.idata: ArviZ)
    disc = bu.find_discrepancy(data, model)    # the effect the model misses, named and added
    bu.write_posterior(post, "out/")           # and write_calibration, write_discrepancy

``bu.beam_model(data)`` is the preloaded beam of the paper as such a model.
"""

from bayes_update.core.calibrate import Calibration
from bayes_update.core.calibrate import calibrate_model as calibrate
from bayes_update.core.discrepancy import DiscrepancyResult, DiscrepancySettings, find_discrepancy
from bayes_update.core.model import Model, ModelError, ModelRunError, ModelSpecError, check_model, load_model
from bayes_update.core.parameters import Parameter, ParameterSet
from bayes_update.core.posterior import PosteriorResult, PosteriorSettings, sample
from bayes_update.core.problem import Problem
from bayes_update.data.dataset import Dataset, DatasetError, Record
from bayes_update.data.folder import read_dataset, write_dataset
from bayes_update.reports.calibration import write_calibration
from bayes_update.reports.discrepancy import write_discrepancy
from bayes_update.reports.posterior import write_posterior

__all__ = [
    "Calibration",
    "Dataset",
    "DatasetError",
    "DiscrepancyResult",
    "DiscrepancySettings",
    "Model",
    "ModelError",
    "ModelRunError",
    "ModelSpecError",
    "Parameter",
    "ParameterSet",
    "PosteriorResult",
    "PosteriorSettings",
    "Problem",
    "Record",
    "beam_model",
    "calibrate",
    "check_model",
    "find_discrepancy",
    "load_model",
    "read_dataset",
    "sample",
    "write_calibration",
    "write_dataset",
    "write_discrepancy",
    "write_posterior",
]
__version__ = "0.2.0"


def __getattr__(name):
    # the beam needs the fe package: loaded on first use, so that a model of your own never loads it
    if name == "beam_model":
        from bayes_update.models.beam.model import beam_model

        return beam_model
    raise AttributeError(f"module 'bayes_update' has no attribute {name!r}")
