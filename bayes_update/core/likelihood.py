"""The likelihood of a model's parameters given its metrics e_lin and e_nlin.

Derivation (docs/likelihood.md has the long form)
-------------------------------------------------
Each metric compares Volterra components of the measured and the simulated
velocity projected on the same regressors: ``e = ||Phi (theta_ref -
theta_mod(x))|| / ||y_ref||``, where ``Phi`` holds the p regressors of the
stage (p = J1 = 2 for e_lin; the 59 order-2 and order-3 products for e_nlin).
At the true parameters the difference ``Phi (theta_ref - theta_mod)`` is
noise: the output noise projected on the regressors, and, larger here, the
response to the *input* noise, since the model is driven by the recorded
(noisy) force while the structure felt the true one.  If that difference is
Gaussian with variance ``s_n^2 ||y_ref||^2`` in each of ``nu`` effective
directions,

    e^2 / s_n^2 ~ chi^2_nu    and    log L(x) = -e(x)^2 / (2 s_n^2) + const,

so the metric (not its log, and not with a variance marginalised away) enters
as a squared distance.  Two facts decide this form on this problem:

* the noise scale cannot be read from the misfit at the optimum: for the
  linear stage p = 2 coefficients meet 2 parameters (P_eff, eta), so e_lin
  reaches ~1e-7 at its minimum (measured), and a likelihood with the noise
  variance marginalised (``-n_eff log e``) would put infinite density there;
* the regression residual underestimates it 17-fold (0.027 % against 0.46 %
  for e_lin at the truth of the default data set), because most of the
  metric's noise is the input-noise response, which lies inside the span of
  the regressors.

So ``s_n`` and ``nu`` come from a parametric bootstrap at the estimate
(:func:`estimate_likelihood`): the white noise levels of both channels are
read from their spectra above the excited band, the model at the estimate is
taken as truth, K replicates of the measurement (the recorded force plus
force noise drives the model, projected on the recorded force's regressors; the model's response
to the clean force plus velocity noise is the "measurement") give K residual
vectors; their mean square per direction of the span of the parameter
sensitivities (:mod:`bayes_update.core.span`) is ``s_n^2``.  ``nu`` (from
``mean(e^2) = nu s_n^2``, ``var(e^2) = 2 nu s_n^4``) is reported only: its
estimate from K values wanders by 2x between seeds.

Model error: the updating model is a discretisation (or a reduction); its
error at the estimate, ``e_model``, is measured against a refined model
(:meth:`bayes_update.core.problem.Problem.refined_model`: the model's
``refined()``; the beam's is a finer mesh) and added as ``s^2 = s_n^2 + e_model^2``.  The bias is
deterministic and mostly in one direction (a frequency error moves P_eff), so
it is budgeted as one standard deviation in *any* direction, not spread over
nu of them: a bias of that size then shifts any parameter by at most one
posterior sd.

The code lives apart by job: the likelihood as an object
(:mod:`bayes_update.core.likelihood_scales`), its scales measured at the
estimate (:mod:`bayes_update.core.noise_bootstrap`) and its model errors
measured again at the mode (:mod:`bayes_update.core.mode_errors`); this module
is the one entry every importer uses.
"""

from __future__ import annotations

from bayes_update.core.likelihood_scales import Likelihood, StageScale
from bayes_update.core.mode_errors import FORM_DRAWS, errors_at_mode
from bayes_update.core.noise_bootstrap import (
    SPECTRUM_REPLICATES,
    estimate_likelihood,
    likelihood_runs,
    noise_scale_from_replicates,
)

__all__ = [
    "FORM_DRAWS",
    "SPECTRUM_REPLICATES",
    "Likelihood",
    "StageScale",
    "errors_at_mode",
    "estimate_likelihood",
    "likelihood_runs",
    "noise_scale_from_replicates",
]
