"""Declared parameters and their prior: the one place where names, ranges and units live.

A model declares its parameters as a sequence of :class:`Parameter`; the prior
is uniform on ``[low, high]`` (log-uniform when ``log=True``).  Values are
always in the parameter's own ``unit``: what the user writes in a prior, what
the model receives in ``theta``, what the reports print.

:class:`ParameterSet` turns the declaration into the arrays the inference
works on.  It samples in *internal coordinates* ``x``: the logarithm for a
log-scale parameter, or the model's own reparameterisation when it has one
(``to_internal`` / ``from_internal``, e.g. the beam's effective preload,
which straightens a ridge); the log prior in ``x`` carries the Jacobian.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

__all__ = ["Parameter", "ParameterSet"]


@dataclass(frozen=True)
class Parameter:
    """One uncertain parameter of a model.

    Parameters
    ----------
    name : a Python identifier (the key in ``theta``).
    low, high : the prior's bounds, in ``unit`` (finite, low < high).
    unit : free text shown in tables and plots (e.g. ``"N/mm"``).
    log : log-uniform prior (then 0 < low).
    null : for a candidate effect's parameter, the value that switches the
        effect off (inside [low, high]); None for a model parameter.
    """

    name: str
    low: float
    high: float
    unit: str = ""
    log: bool = False
    null: float | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"Parameter name must be a Python identifier, got {self.name!r}")
        lo, hi = self.low, self.high
        if not all(isinstance(v, (int, float)) and math.isfinite(v) for v in (lo, hi)) or not lo < hi:
            raise ValueError(f"Parameter {self.name!r}: need finite low < high, got [{lo!r}, {hi!r}]")
        if self.log and lo <= 0:
            raise ValueError(f"Parameter {self.name!r}: a log-uniform prior needs low > 0, got {lo!r}")
        if self.null is not None and not lo <= self.null <= hi:
            raise ValueError(
                f"Parameter {self.name!r}: null = {self.null!r} lies outside "
                f"[{lo!r}, {hi!r}]; an effect must be able to switch off"
            )

    @property
    def label(self) -> str:
        """``name [unit]`` for tables and axes."""
        return f"{self.name} [{self.unit}]" if self.unit else self.name

    def contains(self, value: float) -> bool:
        return self.low <= value <= self.high


class ParameterSet:
    """The parameters of one inference, their prior, and the internal coordinates.

    Parameters
    ----------
    parameters : the declared :class:`Parameter` objects (names unique).
    model : optional object with ``to_internal(theta) -> x``,
        ``from_internal(x) -> theta`` and ``log_jacobian(x)`` =
        ``log |det d theta / d x|`` (a bijection on the prior box). Without it,
        x is theta, with log-scale parameters in natural log.

    Arrays ``X`` of shape (n, d) or (d,) hold internal coordinates in the
    order of ``names``.
    """

    def __init__(self, parameters: Sequence[Parameter], model=None):
        parameters = tuple(parameters)
        if not parameters:
            raise ValueError("no parameters declared: a model needs at least one Parameter")
        bad = [p for p in parameters if not isinstance(p, Parameter)]
        if bad:
            raise TypeError(f"parameters must be bayes_update.Parameter objects, got {bad[0]!r}")
        names = [p.name for p in parameters]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"duplicate parameter names {dup}")
        self.parameters = parameters
        self.names = tuple(names)
        self.low = np.array([p.low for p in parameters], float)
        self.high = np.array([p.high for p in parameters], float)
        self.is_log = np.array([p.log for p in parameters])
        transform = model if model is not None and hasattr(model, "to_internal") else None
        if transform is not None:
            missing = [m for m in ("from_internal", "log_jacobian") if not hasattr(transform, m)]
            if missing:
                raise TypeError(
                    f"{type(model).__name__} has to_internal but not {missing}: the "
                    "reparameterisation needs its inverse and its log-Jacobian"
                )
        self._transform = transform

    def __len__(self) -> int:
        return len(self.parameters)

    def __getitem__(self, name: str) -> Parameter:
        return self.parameters[self.names.index(name)]

    def __repr__(self) -> str:
        return f"ParameterSet({', '.join(p.label for p in self.parameters)})"

    # -- theta (a mapping in the parameters' units) <-> arrays --------------
    def theta_array(self, theta: Mapping[str, float]) -> np.ndarray:
        missing = [n for n in self.names if n not in theta]
        if missing:
            raise KeyError(f"theta lacks {missing}; the parameters are {list(self.names)}")
        return np.array([float(theta[n]) for n in self.names])

    def theta(self, values) -> dict:
        return dict(zip(self.names, map(float, np.asarray(values, float))))

    def contains(self, theta: Mapping[str, float]) -> bool:
        t = self.theta_array(theta)
        return bool(np.all((t >= self.low) & (t <= self.high)))

    def check(self, theta: Mapping[str, float], what: str = "theta") -> None:
        """Raise ValueError naming each value outside its prior range."""
        out = [
            f"{p.name} = {theta[p.name]:g} {p.unit} not in [{p.low:g}, {p.high:g}]".rstrip()
            for p in self.parameters
            if not p.contains(float(theta[p.name]))
        ]
        if out:
            raise ValueError(f"{what} outside the prior: " + "; ".join(out))

    # -- internal coordinates ----------------------------------------------
    def to_internal(self, theta: Mapping[str, float]) -> np.ndarray:
        if self._transform is not None:
            return np.asarray(self._transform.to_internal(dict(theta)), float)
        t = self.theta_array(theta)
        return np.where(self.is_log, np.log(np.where(self.is_log, t, 1.0)), t)

    def from_internal(self, x) -> dict:
        x = np.asarray(x, float)
        if self._transform is not None:
            return {k: float(v) for k, v in self._transform.from_internal(x).items()}
        t = x.copy()
        t[self.is_log] = np.exp(x[self.is_log])  # exp of the log-scale coordinates only: no overflow elsewhere
        return self.theta(t)

    def _log_jacobian(self, x: np.ndarray) -> float:
        if self._transform is not None:
            return float(self._transform.log_jacobian(x))
        return float(np.sum(x[self.is_log]))  # d theta / d log theta = theta

    def log_prior(self, X) -> np.ndarray:
        """Log density of the prior in internal coordinates (up to a constant),
        -inf outside the box.  The prior is uniform in theta (log-uniform for a
        ``log=True`` parameter), so its density in x is
        ``prod p(theta_i) |d theta / d x|``: the log-Jacobian minus
        ``sum log theta_i`` over the log-scale parameters (0 when x is theta
        with those parameters in natural log). X: (n, d) or (d,)."""
        X = np.atleast_2d(np.asarray(X, float))
        out = np.full(len(X), -np.inf)
        finite = np.all(np.isfinite(X), axis=1)
        if self._transform is None:  # element-wise: all points at once
            T = np.where(self.is_log, np.exp(np.where(self.is_log, X, 0.0)), X)
            ok = finite & np.all((T >= self.low) & (T <= self.high), axis=1)
            out[ok] = np.sum(np.where(self.is_log, X - np.log(np.where(self.is_log, T, 1.0)), 0.0), axis=1)[ok]
            return out
        many = getattr(self._transform, "from_internal_many", None)
        if callable(many) and callable(getattr(self._transform, "log_jacobian_many", None)):
            # a transform over arrays (optional): all points at once (the beam's: an MCMC on the
            # surrogates spent 64 % of its time in the per-point loop below)
            all_finite = bool(finite.all())
            Xf = X if all_finite else np.where(finite[:, None], X, 0.0)
            thetas = many(Xf)
            T = np.column_stack([np.asarray(thetas[n], float) for n in self.names])
            ok = np.all((T >= self.low) & (T <= self.high), axis=1)
            ok = ok if all_finite else ok & finite
            lp = np.asarray(self._transform.log_jacobian_many(Xf), float)
            if self.is_log.any():
                lp = lp - np.log(np.where(self.is_log[None, :] & ok[:, None], T, 1.0)).sum(axis=1)
            out[ok] = lp[ok]
            return out
        # a model's transform takes one point at a time: plain floats, since an MCMC on the
        # surrogates asks for the prior of some 10^5 points (numpy's per-call cost on 4-vectors
        # took half of its time)
        low, high, names = self.low.tolist(), self.high.tolist(), self.names
        logs = [i for i, v in enumerate(self.is_log) if v]
        for i in np.flatnonzero(finite):
            x = X[i]
            theta = self._transform.from_internal(x)
            t = [float(theta[n]) for n in names]
            if all(lo <= v <= hi for v, lo, hi in zip(t, low, high)):
                out[i] = float(self._transform.log_jacobian(x)) - sum(math.log(t[j]) for j in logs)
        return out

    def _log_density(self, x, t) -> float:
        """The prior's log density in x, up to its normaliser, without the support check."""
        return self._log_jacobian(x) - float(np.sum(np.log(t[self.is_log])))

    def log_normalised_prior(self, x) -> float:
        """The prior's normalised log density at internal point x (the density
        formula, also just outside the support: a Laplace evidence integrates a
        Gaussian there, and a least-squares mode in the internal box may sit
        where a reparameterised parameter, the beam's F, is a hair outside its
        range): :meth:`log_prior`'s density minus the log of the box's volume in
        theta (in log theta for a log-scale parameter)."""
        x = np.asarray(x, float)
        widths = np.where(self.is_log, np.log(self.high / np.where(self.is_log, self.low, 1.0)), self.high - self.low)
        t = self.theta_array(self.from_internal(x))
        with np.errstate(divide="ignore", invalid="ignore"):
            return self._log_density(x, t) - float(np.sum(np.log(widths)))

    def box(self, n_probe: int = 256) -> np.ndarray:
        """(d, 2) bounding box of the prior in internal coordinates: exact for a
        transform that is monotone in each parameter (the box's corners), else
        the hull of the corners and ``n_probe`` Sobol' points of the box."""
        from scipy.stats import qmc

        d = len(self)
        corners = np.array(np.meshgrid(*[[0.0, 1.0]] * d, indexing="ij")).reshape(d, -1).T
        unit = (
            corners
            if self._transform is None
            else np.vstack([corners, qmc.Sobol(d, scramble=True, seed=0).random(n_probe)])
        )
        X = np.array([self.to_internal(self.theta(self.from_unit(u))) for u in unit])
        return np.column_stack([X.min(axis=0), X.max(axis=0)])

    def from_unit(self, U) -> np.ndarray:
        """Points of the unit cube (n, d) -> parameter values, uniform (or log-uniform)
        per parameter: the prior's quantile transform."""
        U = np.asarray(U, float)
        lin = self.low + U * (self.high - self.low)
        with np.errstate(divide="ignore"):
            log = np.exp(
                np.log(np.where(self.is_log, self.low, 1.0))
                + U * (np.log(np.where(self.is_log, self.high, 1.0)) - np.log(np.where(self.is_log, self.low, 1.0)))
            )
        return np.where(self.is_log, log, lin)

    def sample_prior(self, n: int, seed=None) -> np.ndarray:
        """(n, d) draws from the prior, in internal coordinates."""
        U = np.random.default_rng(seed).random((n, len(self)))
        return np.array([self.to_internal(self.theta(self.from_unit(u))) for u in U])

    def center(self) -> dict:
        """theta at the middle of each range (the geometric middle for log scale)."""
        return self.theta(self.from_unit(np.full(len(self), 0.5)))

    def to_dict(self) -> dict:
        return {
            p.name: {
                "low": p.low,
                "high": p.high,
                "unit": p.unit,
                "log": p.log,
                **({"null": p.null} if p.null is not None else {}),
            }
            for p in self.parameters
        }

    # -- names and units of what the inference reports ------------------------
    @property
    def coordinate_names(self) -> tuple:
        """Names of the internal coordinates: the parameters' (``log_<name>`` for a
        log-scale one), or a reparameterising model's ``internal_names``."""
        if self._transform is not None:
            return tuple(getattr(self._transform, "internal_names", [f"x{i}" for i in range(len(self))]))
        return tuple(f"log_{p.name}" if p.log else p.name for p in self.parameters)

    @property
    def units(self) -> dict:
        """Unit of each internal coordinate (a log-scale one's is the log of its
        unit; a reparameterising model's from its ``internal_units``)."""
        if self._transform is not None:
            given = getattr(self._transform, "internal_units", {})
            return {c: given.get(c, "") for c in self.coordinate_names}
        return {
            c: (f"log({p.unit})" if p.unit else "") if p.log else p.unit
            for c, p in zip(self.coordinate_names, self.parameters)
        }

    def to_parameters(self, x) -> dict:
        """theta at internal point x: what the model's ``simulate`` receives."""
        return self.from_internal(x)

    @property
    def derived_names(self) -> tuple:
        """Internal coordinates of a reparameterising model that are not parameters
        (the beam's P_eff): reported beside the parameters."""
        return tuple(c for c in self.coordinate_names if c not in self.names) if self._transform is not None else ()

    def report(self, X) -> dict:
        """{name: values} at internal points X (n, d): every parameter in its unit,
        then the :attr:`derived_names` coordinates."""
        X = np.atleast_2d(np.asarray(X, float))
        many = getattr(self._transform, "from_internal_many", None)
        if self._transform is None:  # element-wise: exp of the log-scale coordinates
            T = np.where(self.is_log, np.exp(np.where(self.is_log, X, 0.0)), X)
        elif callable(many):  # a transform over arrays: all draws at once
            thetas = many(X)
            T = np.column_stack([np.asarray(thetas[n], float) for n in self.names])
        else:
            T = np.array([self.theta_array(self.from_internal(x)) for x in X])
        out = {n: T[:, i] for i, n in enumerate(self.names)}
        for c in self.derived_names:
            out[c] = X[:, self.coordinate_names.index(c)]
        return out

    @property
    def report_units(self) -> dict:
        """Unit of each variable of :meth:`report`."""
        units = self.units
        return {**{p.name: p.unit for p in self.parameters}, **{c: units[c] for c in self.derived_names}}
