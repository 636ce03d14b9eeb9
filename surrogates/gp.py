"""Gaussian-process surrogate of a scalar function of a point in a box.

:class:`GPSurrogate` wraps scikit-learn's ``GaussianProcessRegressor`` with
what emulating an expensive positive metric needs:

* inputs scaled to the unit box, so that length scales are comparable across
  inputs of different units and the hyperparameter bounds mean the same thing
  for every problem;
* an output transform (``"log"`` by default): a relative error that spans
  decades and has a narrow valley is far closer to a stationary Gaussian
  process in log space than in its own units, and the back-transformed
  predictions stay positive;
* an anisotropic kernel ``C * Matern(nu=2.5, one length scale per input) +
  White``: Matern 5/2 is twice differentiable (a valley has a curvature) but
  less over-smooth than the squared exponential, which extrapolates
  overconfidently; the white term absorbs the numerical noise of the model
  (time stepping, Newton tolerances) and keeps the kernel matrix invertible;
* seeded optimizer restarts, so that a fit is reproducible.

The output transform and the predictions mapped back through it are
:mod:`surrogates.gp_transform`, the report of a fit :mod:`surrogates.gp_report`,
the checks of points and of held-out accuracy :mod:`surrogates.gp_validation`;
this module holds the surrogate itself: its kernel, fit and transformed-space
predictions.
"""

from __future__ import annotations

import warnings
from functools import partial

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

from .design import check_bounds
from .gp_mean import kernel_mean
from .gp_report import GPReport
from .gp_transform import TRANSFORMS, OutputTransform
from .gp_validation import check_X, holdout_validation, validation_metrics

__all__ = ["TRANSFORMS", "GPSurrogate", "holdout_validation", "validation_metrics"]


class GPSurrogate(OutputTransform, GPReport):
    """Gaussian-process regressor of ``y = f(x)``, x in a box of d inputs.

    Parameters
    ----------
    bounds : array-like (d, 2) of ``(low, high)`` in input units, or None to
        take the training points' range at :meth:`fit`.  The box only sets the
        input scaling (points outside it are accepted).
    transform : ``"log"`` (default; needs y > 0), ``"sqrt"`` (needs y >= 0) or
        ``"none"``: the GP models ``t(y)``.
    names : input names for :meth:`summary` (default ``x0, x1, ...``).
    nu : Matern smoothness (0.5, 1.5, 2.5 or inf).
    length_scale_bounds : bounds of the length scales, in unit-box units.
    noise_level, noise_level_bounds : initial value and bounds of the white
        noise variance, in units of the variance of the (standardized) t(y).
    n_restarts_optimizer : extra optimizer starts, drawn with ``seed``.
    seed : int or None; the same seed and data give the same fit.
    kernel : a scikit-learn kernel on unit-box inputs replacing the default
        one (``summary`` then prints it as it is).
    optimize : False keeps the kernel's hyperparameters as given (no fit of
        them), e.g. to reproduce a known posterior.
    max_iterations : at most this many L-BFGS-B iterations per optimisation (None:
        scikit-learn's default, 15000); a fit warm-started from the last round's
        hyperparameters needs few.
    fast : optimise the default kernel's hyperparameters with :mod:`surrogates.gp_fit`
        (the same objective, optimiser and starts as scikit-learn's, so the same optimum;
        its gradient in numpy, one BLAS thread), then condition scikit-learn's regressor
        on them.
    prior_mean : None (a constant mean), or a picklable ``m(X) -> (n,)`` in the
        transformed units, X in input units: the GP models ``t(y) - m(X)`` and
        predicts ``m(X)`` plus its mean (e.g. a Gauss-Newton model of a misfit,
        :class:`bayes_update.core.posterior.design.GaussNewtonMean`: far from the
        design points the prediction falls back on it, not on a constant).

    Attributes (after fit)
    ----------------------
    gp_ : the fitted ``GaussianProcessRegressor`` (on unit-box inputs and
        standardized t(y)).
    bounds_ : (d, 2) the box used for scaling.
    X_train_, y_train_ : training data in original units.
    fit_warnings_ : the optimizer's convergence warnings (first lines), e.g. a
        length scale at its upper bound (the function is nearly constant or
        linear along that input); :meth:`summary` explains them.
    """

    def __init__(
        self,
        bounds=None,
        *,
        transform: str = "log",
        names=None,
        nu: float = 2.5,
        length_scale_bounds=(1e-2, 1e2),
        noise_level: float = 1e-6,
        noise_level_bounds=(1e-10, 1e-1),
        n_restarts_optimizer: int = 4,
        seed=0,
        kernel=None,
        optimize: bool = True,
        prior_mean=None,
        max_iterations: int | None = None,
        fast: bool = False,
    ):
        if transform not in TRANSFORMS:
            raise ValueError(f"transform must be one of {TRANSFORMS}, got {transform!r}")
        if nu not in (0.5, 1.5, 2.5, np.inf):
            raise ValueError(f"nu must be 0.5, 1.5, 2.5 or inf, got {nu!r}")
        if int(n_restarts_optimizer) != n_restarts_optimizer or n_restarts_optimizer < 0:
            raise ValueError(f"n_restarts_optimizer must be a non-negative integer, got {n_restarts_optimizer!r}")
        self.bounds = None if bounds is None else check_bounds(bounds)
        self.transform = transform
        self.names = None if names is None else [str(n) for n in names]
        if self.bounds is not None and self.names is not None and len(self.names) != len(self.bounds):
            raise ValueError(f"{len(self.names)} names for {len(self.bounds)} inputs")
        self.nu = nu
        self.length_scale_bounds = tuple(length_scale_bounds)
        self.noise_level = float(noise_level)
        self.noise_level_bounds = tuple(noise_level_bounds)
        self.n_restarts_optimizer = int(n_restarts_optimizer)
        self.seed = seed
        self.kernel = kernel
        self.optimize = bool(optimize)
        if max_iterations is not None and (int(max_iterations) != max_iterations or max_iterations < 1):
            raise ValueError(f"max_iterations must be None or a positive integer, got {max_iterations!r}")
        self.max_iterations = max_iterations
        self.fast = bool(fast)
        if prior_mean is not None and not callable(prior_mean):
            raise TypeError(f"prior_mean must be None or a callable m(X), got {type(prior_mean).__name__}")
        self.prior_mean = prior_mean

    def _mean(self, X) -> np.ndarray | float:
        """The prior mean m(X) (n,) in the transformed units, 0 without one."""
        if self.prior_mean is None:
            return 0.0
        m = np.asarray(self.prior_mean(np.atleast_2d(X)), float).reshape(-1)
        if m.shape != (len(np.atleast_2d(X)),) or not np.all(np.isfinite(m)):
            raise ValueError("prior_mean must return one finite value per point")
        return m

    # -- fitting ------------------------------------------------------------
    @property
    def n_inputs(self) -> int | None:
        b = getattr(self, "bounds_", self.bounds)
        return None if b is None else len(b)

    def scale_inputs(self, X) -> np.ndarray:
        """Points (n, d) in input units -> unit-box coordinates (what the GP sees)."""
        self._check_fitted()
        X = check_X(X, self.n_inputs)
        lo, hi = self.bounds_[:, 0], self.bounds_[:, 1]
        return (X - lo) / (hi - lo)

    def _default_kernel(self, d: int):
        return ConstantKernel(1.0, (1e-4, 1e4)) * Matern(
            length_scale=np.full(d, 0.3), length_scale_bounds=self.length_scale_bounds, nu=self.nu
        ) + WhiteKernel(self.noise_level, self.noise_level_bounds)

    def warm_from(self, previous: "GPSurrogate") -> "GPSurrogate":
        """A copy of this (unfitted) surrogate whose fit starts from ``previous``'s
        fitted hyperparameters, one optimisation and no restarts (a refinement
        round adds a few points to a design the last fit already described)."""
        import copy

        if not hasattr(previous, "gp_"):
            return self
        warm = copy.copy(self)
        warm.kernel, warm.n_restarts_optimizer = previous.gp_.kernel_, 0
        return warm

    def _optimizer(self):
        if getattr(self, "max_iterations", None) is None:
            return "fmin_l_bfgs_b"
        return partial(_lbfgs, max_iterations=int(self.max_iterations))

    def fit(self, X, y) -> "GPSurrogate":
        """Fit to points ``X`` (n, d) in input units and values ``y`` (n,).

        ``y`` must be finite (drop failed model runs first) and compatible
        with the transform.  Returns self.
        """
        X = check_X(X, None if self.bounds is None else len(self.bounds))
        y = np.asarray(y, dtype=float)
        if y.ndim != 1 or len(y) != len(X):
            raise ValueError(f"y must have shape ({len(X)},), got {y.shape}")
        if len(X) < 2:
            raise ValueError("need at least 2 training points")
        if not np.all(np.isfinite(y)):
            raise ValueError(
                f"y has {np.sum(~np.isfinite(y))} non-finite values (failed runs?); "
                "fit on the finite ones, e.g. X[np.isfinite(y)]"
            )
        if self.bounds is None:
            lo, hi = X.min(axis=0), X.max(axis=0)
            flat = np.flatnonzero(hi <= lo)
            if flat.size:
                raise ValueError(f"inputs {flat.tolist()} are constant in X: pass bounds")
            self.bounds_ = np.column_stack([lo, hi])
        else:
            self.bounds_ = self.bounds
        d = X.shape[1]
        if self.names is not None and len(self.names) != d:
            raise ValueError(f"{len(self.names)} names for {d} inputs")
        z = self._forward(y) - self._mean(X)
        kernel = self.kernel if self.kernel is not None else self._default_kernel(d)
        lo, hi = self.bounds_[:, 0], self.bounds_[:, 1]
        optimize = self.optimize
        if optimize and getattr(self, "fast", False) and _default_form(kernel):
            from .gp_fit import fit_matern52

            std = float(np.std(z)) or 1.0
            theta, _ = fit_matern52(
                (X - lo) / (hi - lo),
                (z - np.mean(z)) / std,
                kernel.theta,
                kernel.bounds,
                self.n_restarts_optimizer,
                self.seed,
                getattr(self, "max_iterations", None),
            )
            kernel, optimize = kernel.clone_with_theta(theta), False
        self.gp_ = GaussianProcessRegressor(
            kernel=kernel,
            normalize_y=True,
            optimizer=self._optimizer() if optimize else None,
            n_restarts_optimizer=self.n_restarts_optimizer,
            random_state=self.seed,
        )
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            self.gp_.fit((X - lo) / (hi - lo), z)
            if optimize is not self.optimize and hasattr(self.gp_.kernel_, "_check_bounds_params"):
                # the fast fit optimised outside scikit-learn: its notes of a hyperparameter at a
                # bound, which summary() reports, from the same check
                self.gp_.kernel_._check_bounds_params()
        # the optimizer's warnings are routine here (an inert input puts its
        # length scale at the upper bound, a noise-free model the noise at the
        # lower one, a restart from a poor start stops early): keep them for
        # summary() instead of flooding a refinement loop; re-raise the rest
        self.fit_warnings_ = []
        for w in caught:
            if issubclass(w.category, ConvergenceWarning):
                msg = str(w.message).splitlines()[0].strip()
                if msg not in self.fit_warnings_:
                    self.fit_warnings_.append(msg)
            else:
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        self.X_train_, self.y_train_ = X.copy(), y.copy()
        self._kernel_mean = False  # mean_transformed's plain-numpy mean, built on first use
        return self

    def _check_fitted(self):
        if not hasattr(self, "gp_"):
            raise RuntimeError("GPSurrogate is not fitted yet: call fit(X, y) first")

    # -- prediction ---------------------------------------------------------
    def predict_transformed(self, X):
        """Predictive mean and sd of ``t(y)`` at ``X`` (n, d): two arrays (n,).

        This Gaussian is what a likelihood written in the transformed metric
        should use (e.g. ``log e ~ N(mu, sd^2 + sigma_model^2)``).  The sd
        includes the fitted white-noise term, i.e. it is the predictive sd of
        a new model run, not only of the latent mean.
        """
        self._check_fitted()
        U = self.scale_inputs(X)
        mu, sd = self.gp_.predict(U, return_std=True)
        return np.asarray(mu, float) + self._mean(X), np.asarray(sd, float)

    def mean_transformed(self, X) -> np.ndarray:
        """The predictive mean of ``t(y)`` at ``X`` (n, d) alone, as
        :meth:`predict_transformed` gives it, without the sd's triangular solves
        or scikit-learn's checks and kernel dispatch (:mod:`surrogates.gp_mean`),
        which is what an MCMC on the surrogate calls tens of thousands of times.
        No check of ``X``: the caller's points are finite, (n, d)."""
        self._check_fitted()
        fast = getattr(self, "_kernel_mean", False)
        if fast is False:  # built once per fit (None: a kernel it does not read)
            fast = self._kernel_mean = kernel_mean(self)
        if fast is not None:
            return fast(X)
        gp = self.gp_
        X = np.atleast_2d(X)
        mu = gp.kernel_(self.scale_inputs(X), gp.X_train_) @ gp.alpha_
        if gp.normalize_y:
            mu = gp._y_train_std * mu + gp._y_train_mean
        return np.asarray(mu, float).reshape(-1) + self._mean(X)

    def score(self, X, y, level: float = 0.95) -> dict:
        """Validation metrics at held-out points (see :func:`validation_metrics`).

        Unlike scikit-learn's ``score`` (a single R^2) this returns a dict.
        """
        X = check_X(X, self.n_inputs)
        y = np.asarray(y, dtype=float)
        if y.shape != (len(X),):
            raise ValueError(f"y must have shape ({len(X)},), got {y.shape}")
        pred = self.predict(X, return_std=False)
        lo, hi = self.predict_interval(X, level)
        return validation_metrics(y, pred, lo, hi) | {"level": level}


def _default_form(kernel) -> bool:
    """Whether ``kernel`` is ``C * Matern(nu=2.5) + White`` (what :mod:`surrogates.gp_fit` fits)."""
    from sklearn.gaussian_process.kernels import Product, Sum

    return (
        isinstance(kernel, Sum)
        and isinstance(kernel.k2, WhiteKernel)
        and isinstance(kernel.k1, Product)
        and isinstance(kernel.k1.k1, ConstantKernel)
        and type(kernel.k1.k2) is Matern
        and kernel.k1.k2.nu == 2.5
    )


def _lbfgs(obj_func, initial_theta, bounds, max_iterations: int):
    """scikit-learn's L-BFGS-B optimiser with an iteration cap (its own has 15000)."""
    from scipy.optimize import minimize

    res = minimize(
        obj_func, initial_theta, method="L-BFGS-B", jac=True, bounds=bounds, options={"maxiter": max_iterations}
    )
    return res.x, res.fun
