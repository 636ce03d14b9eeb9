"""bayes_update: probabilistic updating of nonlinear structural models with Volterra
series (after Bussetta, Shiki and da Silva, 2017).

A model is any object with declared ``parameters`` (:class:`Parameter`) and
``simulate(theta, force, fs)``; see :mod:`bayes_update.core` and docs/models.md.
"""

from bayes_update.core import Model, ModelError, ModelSpecError, Parameter, ParameterSet, Problem, check_model, load_model

__all__ = ["Model", "ModelError", "ModelSpecError", "Parameter", "ParameterSet", "Problem", "check_model",
           "load_model"]
__version__ = "0.1.0"
