"""fe: a fast, verified geometrically nonlinear beam model of the preloaded-beam rig.

>>> from fe import BeamModel, Parameters, simulate
>>> model = BeamModel()                      # paper's rig, default mesh and substeps
>>> result = simulate(model, Parameters(), force, fs=1024.0)
>>> result.sensor_velocity                   # transverse velocity at mid-span [m/s]
>>> rom = ModalROM(rig=model.rig)            # modal reduced-order model, ~1 ms per run
>>> simulate(rom, Parameters(), force, fs=1024.0).sensor_velocity
"""

from . import _numba_cache  # noqa: F401  (first: numba fixes the cache folder at decoration)
from .effects import EFFECTS, AmplitudeDependentDamping, ClampCompliance, Effect, InitialImperfection, ShakerAttachment
from .model import (
    BeamModel,
    BucklingError,
    ConvergenceError,
    Modes,
    SimulationResult,
    StaticState,
    generalized_alpha_accuracy,
    generalized_alpha_coefficients,
)
from .rig import PAPER_PARAMETERS, Parameters, Rig
from .rom import ModalROM

__all__ = [
    "AmplitudeDependentDamping",
    "BeamModel",
    "BucklingError",
    "ClampCompliance",
    "ConvergenceError",
    "EFFECTS",
    "Effect",
    "InitialImperfection",
    "ModalROM",
    "Modes",
    "PAPER_PARAMETERS",
    "Parameters",
    "Rig",
    "ShakerAttachment",
    "SimulationResult",
    "StaticState",
    "generalized_alpha_accuracy",
    "generalized_alpha_coefficients",
    "simulate",
]


def simulate(model, params, force, fs=1024.0, **options):
    """Run any model of the rig (full FE, or a reduced-order model) on a sampled force.

    ``model`` is any object with a ``simulate(params, force, fs, **options)``
    method returning a :class:`SimulationResult`.
    """
    if not hasattr(model, "simulate"):
        raise TypeError(f"{type(model).__name__} is not a model of the rig (no simulate method)")
    return model.simulate(params, force, fs, **options)
