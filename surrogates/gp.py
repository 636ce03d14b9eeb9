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
"""

from __future__ import annotations

import re
import warnings
from functools import partial

import numpy as np
from scipy.stats import norm
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

from .design import check_bounds
from .gp_mean import kernel_mean

__all__ = ["TRANSFORMS", "GPSurrogate", "holdout_validation", "validation_metrics"]

TRANSFORMS = ("log", "sqrt", "none")


def _check_X(X, d=None, what="X") -> np.ndarray:
    X = np.asarray(X, dtype=float)
    if X.ndim == 1 and d is not None and d == 1:
        X = X[:, None]
    if X.ndim != 2:
        raise ValueError(f"{what} must have shape (n, d), got shape {X.shape}")
    if d is not None and X.shape[1] != d:
        raise ValueError(f"{what} has {X.shape[1]} columns, the surrogate has {d} inputs")
    if not np.all(np.isfinite(X)):
        raise ValueError(f"{what} contains non-finite values")
    return X


class GPSurrogate:
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

    # -- transforms ---------------------------------------------------------
    def _forward(self, y: np.ndarray) -> np.ndarray:
        if self.transform == "log":
            bad = ~(y > 0)
            if bad.any():
                raise ValueError(
                    f"transform='log' needs y > 0; {bad.sum()} of {y.size} values are not "
                    f"(e.g. {y[bad][:3].tolist()}); use transform='sqrt' or 'none'"
                )
            return np.log(y)
        if self.transform == "sqrt":
            bad = ~(y >= 0)
            if bad.any():
                raise ValueError(f"transform='sqrt' needs y >= 0; {bad.sum()} of {y.size} values are not")
            return np.sqrt(y)
        return y.copy()

    def _inverse(self, z: np.ndarray) -> np.ndarray:
        if self.transform == "log":
            return np.exp(z)
        if self.transform == "sqrt":
            # max(z, 0)^2 is monotone, so quantiles of t(y) map to quantiles of y
            return np.maximum(z, 0.0) ** 2
        return z

    # -- fitting ------------------------------------------------------------
    @property
    def n_inputs(self) -> int | None:
        b = getattr(self, "bounds_", self.bounds)
        return None if b is None else len(b)

    def scale_inputs(self, X) -> np.ndarray:
        """Points (n, d) in input units -> unit-box coordinates (what the GP sees)."""
        self._check_fitted()
        X = _check_X(X, self.n_inputs)
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
        X = _check_X(X, None if self.bounds is None else len(self.bounds))
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

    def predict(self, X, return_std: bool = True):
        """Prediction at ``X`` (n, d) in the original units of y.

        The point prediction is ``t^-1(mu)``: for ``"log"`` the predictive
        median ``exp(mu)`` (not the mean ``exp(mu + sd^2/2)``, which a large
        sd inflates), for ``"sqrt"`` the median ``max(mu, 0)^2``, for ``"none"``
        the mean.  The sd (``return_std=True``) is the exact sd of the
        back-transformed Gaussian: lognormal ``sqrt((exp(sd^2) - 1) exp(2 mu +
        sd^2))`` for ``"log"`` (not a delta-method ``exp(mu) sd``, which
        understates it once sd is not small), the sd of ``max(z, 0)^2`` for
        ``"sqrt"``.  Being a median with the sd of a skewed law, ``median +-
        2 sd`` is not a 95 % band: use :meth:`predict_interval`.

        Returns ``pred`` (n,), or ``(pred, sd)``.
        """
        mu, sd = self.predict_transformed(X)
        pred = self._inverse(mu)
        if not return_std:
            return pred
        return pred, self._back_transformed_sd(mu, sd)

    def _back_transformed_sd(self, mu, sd):
        if self.transform == "none":
            return sd
        if self.transform == "log":
            s2 = sd**2
            return np.sqrt(np.expm1(s2)) * np.exp(mu + s2 / 2)
        # y = max(z, 0)^2, z ~ N(mu, sd^2): raw moments from those of the
        # normal truncated to z > 0 (a = mu/sd, Phi, phi at a)
        with np.errstate(divide="ignore", invalid="ignore"):
            a = np.where(sd > 0, mu / sd, np.sign(mu) * np.inf)
        P, p = norm.cdf(a), norm.pdf(a)
        m2 = (mu**2 + sd**2) * P + mu * sd * p
        m4 = (mu**4 + 6 * mu**2 * sd**2 + 3 * sd**4) * P + (mu**3 * sd + 5 * mu * sd**3) * p
        return np.sqrt(np.maximum(m4 - m2**2, 0.0))

    def predict_interval(self, X, level: float = 0.95):
        """Central predictive interval in original units: ``(low, high)``, each (n,).

        The transformed-space quantiles ``mu -+ z sd`` mapped back through the
        (monotone) inverse transform, so the interval is exact for the GP's
        Gaussian in t(y) whatever the transform.
        """
        if not 0 < level < 1:
            raise ValueError(f"level must be in (0, 1), got {level}")
        mu, sd = self.predict_transformed(X)
        k = norm.ppf(0.5 + level / 2)
        return self._inverse(mu - k * sd), self._inverse(mu + k * sd)

    def score(self, X, y, level: float = 0.95) -> dict:
        """Validation metrics at held-out points (see :func:`validation_metrics`).

        Unlike scikit-learn's ``score`` (a single R^2) this returns a dict.
        """
        X = _check_X(X, self.n_inputs)
        y = np.asarray(y, dtype=float)
        if y.shape != (len(X),):
            raise ValueError(f"y must have shape ({len(X)},), got {y.shape}")
        pred = self.predict(X, return_std=False)
        lo, hi = self.predict_interval(X, level)
        return validation_metrics(y, pred, lo, hi) | {"level": level}

    # -- reporting ----------------------------------------------------------
    def _input_names(self):
        d = self.n_inputs or 0
        return self.names if self.names is not None else [f"x{i}" for i in range(d)]

    def hyperparameters(self) -> dict:
        """Fitted hyperparameters of the default kernel, in readable units.

        ``length_scales_unit`` (d,) in unit-box units, ``length_scales`` (d,)
        in input units, ``signal_sd`` and ``noise_sd`` in units of t(y), and
        the ``log_marginal_likelihood``.  Empty dict for a custom kernel.
        """
        self._check_fitted()
        k = self.gp_.kernel_
        try:
            c, m, w = k.k1.k1, k.k1.k2, k.k2
            ls = np.broadcast_to(np.asarray(m.length_scale, float), (self.n_inputs,))
            # normalize_y divides t(y) by its std (ddof 0; 1 when constant)
            scale = float(np.std(self._forward(self.y_train_))) or 1.0
            return {
                "length_scales_unit": ls.copy(),
                "length_scales": ls * (self.bounds_[:, 1] - self.bounds_[:, 0]),
                "signal_sd": float(np.sqrt(c.constant_value)) * scale,
                "noise_sd": float(np.sqrt(w.noise_level)) * scale,
                "log_marginal_likelihood": float(self.gp_.log_marginal_likelihood_value_),
            }
        except AttributeError:
            return {}

    def __repr__(self) -> str:
        fitted = hasattr(self, "gp_")
        n = f", n_train={len(self.X_train_)}" if fitted else ", not fitted"
        names = f", names={self._input_names()}" if (self.names is not None or fitted) else ""
        return f"GPSurrogate(transform={self.transform!r}{names}{n})"

    def summary(self) -> str:
        """Multi-line description of the fitted kernel: length scale per input
        (in unit-box and input units), signal and noise sd, warnings."""
        if not hasattr(self, "gp_"):
            return repr(self)
        kernel = f"Matern nu={self.nu}" if self.kernel is None else "custom kernel"
        lines = [f"GPSurrogate: transform={self.transform!r}, {len(self.X_train_)} training points, {kernel}"]
        hp = self.hyperparameters()
        if not hp:
            lines.append(f"  kernel: {self.gp_.kernel_}")
        else:
            lines.append(
                f"  signal sd {hp['signal_sd']:.4g}, noise sd {hp['noise_sd']:.3g} (units of "
                f"{'log y' if self.transform == 'log' else 'sqrt y' if self.transform == 'sqrt' else 'y'})"
                f", log marginal likelihood {hp['log_marginal_likelihood']:.4g}"
            )
            names = self._input_names()
            w = max(8, max(len(n) for n in names))
            lines.append(f"  {'input':<{w}} {'low':>11} {'high':>11} {'length scale':>13} {'(unit box)':>11}")
            for i, name in enumerate(names):
                lo, hi = self.bounds_[i]
                lines.append(
                    f"  {name:<{w}} {lo:>11.4g} {hi:>11.4g} {hp['length_scales'][i]:>13.4g} "
                    f"{hp['length_scales_unit'][i]:>11.4g}"
                )
        for msg in self.fit_warnings_:
            lines.append(f"  note: {self._explain(msg)}")
        return "\n".join(lines)

    def _explain(self, msg: str) -> str:
        # sklearn names hyperparameters by their place in the kernel tree
        m = re.search(r"dimension (\d+) of parameter (\S+) is close to the specified (upper|lower) bound", msg)
        if not m or self.kernel is not None:
            return msg
        i, param, side = int(m.group(1)), m.group(2), m.group(3)
        if param.endswith("length_scale"):
            name = self._input_names()[i]
            why = (
                "the function is nearly constant or linear along it"
                if side == "upper"
                else "the function varies faster than the design resolves"
            )
            return f"length scale of {name!r} at its {side} bound: {why}"
        if param.endswith("noise_level"):
            why = "the data look noise-free" if side == "lower" else "the data look noisy or too rough for the kernel"
            return f"white-noise variance at its {side} bound: {why}"
        if param.endswith("constant_value"):
            return f"signal variance at its {side} bound"
        return msg


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


def validation_metrics(y_true, y_pred, low, high) -> dict:
    """Accuracy of predictions against true values, all arrays (n,).

    Returns ``n``, ``median_rel_error`` and ``max_rel_error`` of
    ``|y_pred - y_true| / |y_true|``, and ``coverage``: the fraction of
    ``y_true`` inside ``[low, high]`` (about the band's level if the
    predictive sd is calibrated).
    """
    y_true, y_pred = np.asarray(y_true, float), np.asarray(y_pred, float)
    low, high = np.asarray(low, float), np.asarray(high, float)
    if not (y_true.shape == y_pred.shape == low.shape == high.shape) or y_true.ndim != 1:
        raise ValueError("y_true, y_pred, low and high must be 1-D arrays of one length")
    if y_true.size == 0:
        raise ValueError("no points to validate on")
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.abs(y_pred - y_true) / np.abs(y_true)
    return {
        "n": int(y_true.size),
        "median_rel_error": float(np.median(rel)),
        "max_rel_error": float(np.max(rel)),
        "coverage": float(np.mean((y_true >= low) & (y_true <= high))),
    }


def holdout_validation(gp_factory, X, y, fraction: float = 0.25, seed=0, level: float = 0.95) -> dict:
    """Fit a fresh surrogate on a random part of ``(X, y)`` and score it on the rest.

    Parameters
    ----------
    gp_factory : callable with no argument returning an unfitted surrogate
        (e.g. ``lambda: GPSurrogate(bounds, seed=0)``).
    X, y : (n, d) points and (n,) values.
    fraction : share of points held out (at least one point each side).
    seed : seeds the split.
    level : level of the predictive band whose coverage is reported.

    Returns
    -------
    dict: ``n_train``, ``n_test``, ``median_rel_error``, ``max_rel_error``,
    ``coverage`` (fraction of held-out values inside the ``level`` band),
    ``level``, ``surrogate`` (the fitted one) and ``test_index``.
    """
    X = _check_X(X)
    y = np.asarray(y, dtype=float)
    if y.shape != (len(X),):
        raise ValueError(f"y must have shape ({len(X)},), got {y.shape}")
    if not 0 < fraction < 1:
        raise ValueError(f"fraction must be in (0, 1), got {fraction}")
    n_test = int(round(fraction * len(X)))
    if n_test < 1 or len(X) - n_test < 2:
        raise ValueError(f"fraction={fraction} of {len(X)} points leaves no test point or < 2 training points")
    perm = np.random.default_rng(seed).permutation(len(X))
    test, train = np.sort(perm[:n_test]), np.sort(perm[n_test:])
    sur = gp_factory().fit(X[train], y[train])
    return {
        "n_train": len(train),
        "n_test": n_test,
        **sur.score(X[test], y[test], level),
        "surrogate": sur,
        "test_index": test,
    }
