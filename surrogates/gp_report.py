"""The report of a fitted :class:`~surrogates.gp.GPSurrogate`: its hyperparameters in
readable units, its ``repr`` and ``summary`` and the optimizer's notes explained.

Apart from the GP because it only reads a fit (nothing here changes one).
"""

from __future__ import annotations

import re

import numpy as np

__all__ = ["GPReport"]


class GPReport:
    """What a fitted surrogate says of itself; the class using it provides the fit
    (``gp_``, ``bounds_``, ``X_train_``, ``y_train_``, ``fit_warnings_``), ``names``,
    ``kernel``, ``nu``, ``transform``, ``n_inputs`` and ``_forward``."""

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
