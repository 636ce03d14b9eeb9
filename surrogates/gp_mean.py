"""A fitted GP's predictive mean as plain numpy, for samplers that call it 10^4-10^5 times.

scikit-learn's kernel objects dispatch through a tree (``C * Matern + White``),
check their arguments and rescale the training points at every call: for the
64 walkers of an emcee step on a 50-point GP that is three quarters of the
call.  :class:`KernelMean` folds the input scaling, the length scales, the
constant and the output normalisation into arrays once, after the fit, and
evaluates ``m(X) + k(X, X_train) @ alpha`` with one ``cdist``.  It reads the
default kernel of :class:`~surrogates.gp.GPSurrogate` only; any other kernel
keeps scikit-learn's path (:func:`kernel_mean` returns None).
"""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial.distance import cdist
from sklearn.gaussian_process.kernels import ConstantKernel, Matern, Product, Sum, WhiteKernel

__all__ = ["KernelMean", "kernel_mean"]


def _matern(dists: np.ndarray, nu: float) -> np.ndarray:
    """Matern correlation of scaled distances, as scikit-learn's ``Matern`` writes it."""
    if nu == 0.5:
        return np.exp(-dists)
    if nu == 1.5:
        k = dists * math.sqrt(3.0)
        return (1.0 + k) * np.exp(-k)
    if nu == 2.5:
        k = dists * math.sqrt(5.0)
        return (1.0 + k + k * k / 3.0) * np.exp(-k)
    return np.exp(-0.5 * dists * dists)       # nu = inf (the squared exponential)


class KernelMean:
    """``mu(X)`` of a fitted ``C * Matern + White`` GP (X in input units, (n, d))
    in the GP's transformed units: the prior mean, plus the normalised GP mean
    ``y_std * C * k(X, X_train) @ alpha + y_mean``.  The white term adds nothing
    away from the training points' own rows, as in scikit-learn's prediction."""

    def __init__(self, lower, width, length_scale, constant, nu, X_train, alpha, y_mean, y_std, prior_mean=None):
        d = len(lower)
        ls = np.broadcast_to(np.asarray(length_scale, float), (d,))
        # the same operations as scikit-learn's, in its order (a GP's alpha can reach 1e5 and
        # amplify a reordered rounding): unit box, then the length scales
        self.lower, self.width, self.ls = np.asarray(lower, float), np.asarray(width, float), ls
        self.X_train = np.asarray(X_train, float) / ls        # unit-box points / length scales
        self.weights = float(constant) * float(y_std) * np.asarray(alpha, float).reshape(-1)
        self.offset = float(y_mean)
        self.nu = float(nu)
        self.prior_mean = prior_mean

    def __call__(self, X) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, float))
        mu = _matern(cdist((X - self.lower) / self.width / self.ls, self.X_train), self.nu) @ self.weights + self.offset
        if self.prior_mean is not None:
            mu = mu + np.asarray(self.prior_mean(X), float).reshape(-1)
        return mu


def kernel_mean(surrogate) -> KernelMean | None:
    """The :class:`KernelMean` of a fitted :class:`~surrogates.gp.GPSurrogate` whose
    kernel has the default form ``C * Matern + White``, else None."""
    gp = surrogate.gp_
    k = gp.kernel_
    if not (isinstance(k, Sum) and isinstance(k.k2, WhiteKernel) and isinstance(k.k1, Product)
            and isinstance(k.k1.k1, ConstantKernel) and type(k.k1.k2) is Matern
            and k.k1.k2.nu in (0.5, 1.5, 2.5, np.inf)):
        return None
    y_mean, y_std = (gp._y_train_mean, gp._y_train_std) if gp.normalize_y else (0.0, 1.0)
    if np.ndim(y_mean) or np.ndim(y_std):          # one output: scalars (shape () or (1,))
        y_mean, y_std = np.ravel(y_mean), np.ravel(y_std)
        if y_mean.size != 1:
            return None
        y_mean, y_std = y_mean[0], y_std[0]
    lo, hi = surrogate.bounds_[:, 0], surrogate.bounds_[:, 1]
    return KernelMean(lo, hi - lo, k.k1.k2.length_scale, k.k1.k1.constant_value, k.k1.k2.nu, gp.X_train_,
                      gp.alpha_, y_mean, y_std, surrogate.prior_mean)
