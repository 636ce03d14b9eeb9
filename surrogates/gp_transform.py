"""The output transform of :class:`~surrogates.gp.GPSurrogate` and its way back.

The GP models ``t(y)`` (``"log"``, ``"sqrt"`` or ``"none"``; why log by default:
:mod:`surrogates.gp`); this mixin holds ``t``, its inverse and the predictions in
the original units of y that go through them (the median, the exact sd of the
back-transformed Gaussian, the predictive interval), apart from the GP because
they are the transform's algebra and need of the fit only
``predict_transformed``.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import norm

__all__ = ["TRANSFORMS", "OutputTransform"]

TRANSFORMS = ("log", "sqrt", "none")


class OutputTransform:
    """``t(y)`` and the predictions mapped back through it; the class using it sets
    ``transform`` and provides ``predict_transformed(X) -> (mu, sd)``."""

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
