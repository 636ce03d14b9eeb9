"""volterra: discrete-time Volterra series (orders 1-3) in a generalized orthonormal (Kautz) basis.

Turns an input/output record into kernels, a constant h0 and the components
y1, y2, y3 (paper eq. 11-19).  Knows nothing about beams.

::

    basis = KautzBasis.from_modal(freq_hz=37.0, damping_ratio=0.01, fs=1024.0,
                                  n_functions=(2, 2, 6))
    model = fit_volterra(u, y, basis, ridge=0.0)   # or lists of records
    y1, y2, y3 = model.components(u)               # y = model.h0 + y1 + y2 + y3
    print(model.summary())

    basis = KautzBasis.from_data(u_low, y_low, fs)  # every mode of a low-level record
    basis.poles[1]                                  # one KautzPole per mode, dominant first

A basis has one pole pair per mode (:mod:`volterra.gobf`) and, by default,
the input itself as function 0 of every order (``feedthrough=True``), so the
order-1 span holds every proper rational system with the modes' poles.

Conventions: y_n with no 1/n! factor; symmetric kernels are averages over
argument permutations; frequencies in Hz, lags in samples,
``H(f) = sum_n h(n) exp(-j 2 pi f n / fs)``.  See :mod:`volterra.model` for
what the Kautz-basis kernels can and cannot represent (H3 near
f1 + f2 + f3 = fn is not representable).
"""

from .basis import DEFAULT_N_FUNCTIONS, ROBUST_LINEAR_N_FUNCTIONS, KautzBasis
from .distortion import Distortion, distortion
from .fit import FitInfo, fit_volterra
from .frf import estimate_h1, excited_band, periodic_h1
from .gobf import (
    gobf_filter_rows,
    gobf_frequency_response,
    kautz_filter,
    kautz_frequency_response,
    kautz_impulse_responses,
)
from .kautz import KautzPole, RealPole
from .model import VolterraModel
from .modes import ModalEstimate, PoleEstimationError, estimate_modes
from .periods import PeriodLayout, find_periods
from .poles import pole_from_frf, pole_from_modal, refine_bounds, refine_pole
from .projector import VolterraProjector
from .regressors import index_tuples, multiplicity, n_terms
from .sweep_distortion import SweepDistortion, record_distortion, sweep_distortion

__all__ = [
    "Distortion",
    "distortion",
    "record_distortion",
    "sweep_distortion",
    "SweepDistortion",
    "KautzPole",
    "RealPole",
    "KautzBasis",
    "DEFAULT_N_FUNCTIONS",
    "ROBUST_LINEAR_N_FUNCTIONS",
    "fit_volterra",
    "VolterraModel",
    "FitInfo",
    "VolterraProjector",
    "pole_from_modal",
    "pole_from_frf",
    "refine_pole",
    "refine_bounds",
    "PoleEstimationError",
    "estimate_modes",
    "ModalEstimate",
    "find_periods",
    "PeriodLayout",
    "estimate_h1",
    "periodic_h1",
    "excited_band",
    "gobf_filter_rows",
    "gobf_frequency_response",
    "kautz_filter",
    "kautz_impulse_responses",
    "kautz_frequency_response",
    "index_tuples",
    "multiplicity",
    "n_terms",
    "plot_components",
    "plot_h1",
    "plot_h2",
    "plot_stabilisation",
]


def __getattr__(name):
    # plotting imports matplotlib lazily: importing volterra stays cheap
    if name in ("plot_components", "plot_h1", "plot_h2", "plot_stabilisation"):
        from . import plotting

        return getattr(plotting, name)
    raise AttributeError(f"module 'volterra' has no attribute {name!r}")
