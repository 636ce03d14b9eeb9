"""The generic core: parameters and priors, the model contract and its loader.

Nothing here knows the beam (or any other model): a model reaches the core
through the contract of :mod:`bayes_update.core.model` alone.
"""

from bayes_update.core.model import BUILTIN_MODELS, Model, ModelError, ModelSpecError, check_model, load_model
from bayes_update.core.parameters import Parameter, ParameterSet
from bayes_update.core.problem import DatasetError, Problem

__all__ = [
    "BUILTIN_MODELS",
    "DatasetError",
    "Model",
    "ModelError",
    "ModelSpecError",
    "Parameter",
    "ParameterSet",
    "Problem",
    "check_model",
    "load_model",
]
