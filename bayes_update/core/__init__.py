"""The generic core: parameters and priors, the model contract and its loader.

Nothing here knows the beam (or any other model): a model reaches the core
through the contract of :mod:`bayes_update.core.model` alone.
"""

from .model import BUILTIN_MODELS, Model, ModelSpecError, check_model, load_model
from .parameters import Parameter, ParameterSet

__all__ = ["BUILTIN_MODELS", "Model", "ModelSpecError", "Parameter", "ParameterSet", "check_model",
           "load_model"]
