"""surrogates: designs of experiments, Gaussian-process surrogates, sequential
refinement and a disk cache of evaluations, for any expensive function of a
point in a box.

The package knows nothing about beams, finite elements or Volterra series: a
model is a picklable callable of one point (a 1-D array), evaluated through
:func:`surrogates.evaluation.evaluate_many` and so through any
``concurrent.futures.Executor`` (a local process pool, or a Dask
``Client.get_executor()`` for a cluster).

* :func:`design` - scrambled Sobol' / Latin hypercube designs in a box.
* :class:`GPSurrogate` - anisotropic Matern-5/2 GP on unit-box inputs with a
  log (or sqrt, or no) output transform; :func:`holdout_validation`.
* :func:`propose_points`, :func:`refine` - batches of new points where
  ``weight**0.5 * sd`` is high (e.g. a tempered posterior density times the
  surrogate's sd), spread by a kriging-believer update and a minimum distance.
* :class:`EvaluationCache`, :func:`cached_evaluate` - netCDF cache keyed by the
  point and a configuration dictionary, so an interrupted DOE resumes.
* :class:`CurvedValley` - a synthetic valley-shaped metric with a known
  posterior, for tests and benchmarks.
"""

from .cache import EvaluationCache, cached_evaluate, config_hash
from .design import DESIGN_METHODS, check_bounds, design, from_unit, to_unit
from .evaluation import default_executor, evaluate_many
from .gp import TRANSFORMS, GPSurrogate, holdout_validation, validation_metrics
from .refine import RefinementResult, propose_points, refine
from .synthetic import CurvedValley

__all__ = [
    "DESIGN_METHODS",
    "TRANSFORMS",
    "CurvedValley",
    "EvaluationCache",
    "GPSurrogate",
    "RefinementResult",
    "cached_evaluate",
    "check_bounds",
    "config_hash",
    "default_executor",
    "design",
    "evaluate_many",
    "from_unit",
    "holdout_validation",
    "propose_points",
    "refine",
    "to_unit",
    "validation_metrics",
]
