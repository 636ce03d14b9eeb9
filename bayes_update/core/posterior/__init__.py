"""The posterior of a model's parameters: surrogate-based (default) or direct.

Pipeline of :func:`sample` (each step's numbers go to the result):

The cost users feel is the number of model runs: every step records its
runs and wall time (``run.json``).  The default sizes take some 230-300 runs
(``benchmarks/runs_per_posterior.py``, an SBC in ``benchmarks/sbc.py``,
docs/posterior.md); :meth:`PosteriorSettings.thorough` (``sample --thorough``)
the former 1200-1400.

1. start: the model's own ``start`` hook (the beam's: the paper's grids; with
   ``coarse_start`` eta and P_eff from the low level, 6 runs), else the
   two-stage calibration on Sobol' designs of ``n_start`` points
   (:mod:`bayes_update.core.calibrate`), unless a start point is given;
2. likelihood scales at the start (:func:`bayes_update.core.likelihood.estimate_likelihood`):
   ``n_replicates`` noise replicates run on the model (or, with
   ``model_replicates``, through a linear time-invariant estimate of the model
   corrected by that many model runs: a control variate), the sensitivity span
   (d runs) and the model error against a refined model, per test; the model
   error measured again at the MAP;
3. MAP by least squares on the metrics' residual vectors (trust-region
   Gauss-Newton on direct model runs, :mod:`bayes_update.core.mode`; from the
   start and from the model's ``extra_starts``, e.g. the beam's c-k_s band;
   ``frugal_map``: from the others only where they beat the first mode) and the
   Laplace covariance from the residuals' Jacobian there;
4. surrogate path: coordinates whitened by the Laplace covariance, a Sobol'
   design in the box of +-``box_sd`` in them (points inside the prior),
   Gaussian processes of z = log(1 + e^2 / s^2) per stage (their prior mean
   the Gauss-Newton z at the MAP, ``gp_mean``), refined in rounds
   where the surrogate posterior has mass (:func:`surrogates.refine`), all
   ``n_rounds`` or, with ``stop_tolerance``, until that posterior stops moving;
   direct path: no surrogate;
5. emcee (stretch move, seeded) on the surrogate's (or the model's)
   posterior, restricted to the local box; ArviZ data (the parameters in their
   units, and derived coordinates such as the beam's P_eff);
6. opt-in diagnostics: model runs at posterior draws (``n_predictive``: bands
   and the surrogate's check) and global Sobol' indices (``n_global``).

Why a local box: a posterior can be far narrower than its prior (the beam's P_eff is ~0.03 % wide, 1e-4 of the prior
range), so a design over the whole prior box would put no point in it.  The
whole prior box is still searched: by the start (Sobol' designs over the prior,
or the beam's grids) and by the global design of the sensitivity analysis.  The
result records the fraction of draws that the box, not the prior, cut
(``box_cut_fraction``); above 1 % the box is re-centred on the draws, 3x
wider, up to ``box_attempts`` times.

Modules: :mod:`.settings` (sizes), :mod:`.target` (log posteriors), :mod:`.laplace`
(MAP, box), :mod:`.design` (surrogates), :mod:`.mcmc` (emcee, ArviZ),
:mod:`.predictive`, :mod:`.sampler` (the pipeline), :mod:`.result` (what it returns).  Writing the results:
:mod:`bayes_update.reports.posterior`.
"""

from bayes_update.core.posterior.result import PosteriorResult
from bayes_update.core.posterior.sampler import sample
from bayes_update.core.posterior.settings import PosteriorSettings

__all__ = ["PosteriorResult", "PosteriorSettings", "sample"]
