"""The posterior of a model's parameters: surrogate-based (default) or direct.

Pipeline of :func:`sample` (each step's numbers go to the result):

1. start: the model's own ``start`` hook (the beam's: the paper's grids),
   else the two-stage calibration (:mod:`bayes_update.core.calibrate`),
   unless a start point is given;
2. likelihood scales at the start (:func:`bayes_update.core.likelihood.estimate_likelihood`:
   noise replicates and the model error against a refined model);
3. MAP by least squares on the metrics' residual vectors (trust-region
   Gauss-Newton on direct model runs, :mod:`bayes_update.core.mode`; from the
   start and from the model's ``extra_starts``, e.g. the beam's c-k_s band) and the
   Laplace covariance from the residuals' Jacobian there;
4. surrogate path: coordinates whitened by the Laplace covariance, a Sobol'
   design in the box of +-``box_sd`` in them (points inside the prior), Gaussian processes of
   z = log(1 + e^2 / s^2) per stage, refined in rounds where the surrogate
   posterior has mass (:func:`surrogates.refine`, candidates from short MCMC
   runs on the current surrogate); direct path: no surrogate;
5. emcee (stretch move, seeded) on the surrogate's (or the model's)
   posterior, restricted to the local box; ArviZ data (the parameters in their
   units, and derived coordinates such as the beam's P_eff).

Why a local box: a posterior can be far narrower than its prior (the beam's P_eff is ~0.03 % wide, 1e-4 of the prior
range), so a design over the whole prior box would put no point in it.  The
whole prior box is still searched: by the start (Sobol' designs over the prior,
or the beam's grids) and by the global design of the sensitivity analysis.  The
result records the fraction of draws that the box, not the prior, cut
(``box_cut_fraction``); above 1 % the box is re-centred on the draws, 3x
wider, up to ``box_attempts`` times.

Modules: :mod:`.settings` (sizes), :mod:`.target` (log posteriors), :mod:`.laplace`
(MAP, box), :mod:`.design` (surrogates), :mod:`.mcmc` (emcee, ArviZ),
:mod:`.predictive`, :mod:`.sampler` (the pipeline).  Writing the results:
:mod:`bayes_update.reports.posterior`.
"""

from bayes_update.core.posterior.sampler import PosteriorResult, sample
from bayes_update.core.posterior.settings import PosteriorSettings

__all__ = ["PosteriorResult", "PosteriorSettings", "sample"]
