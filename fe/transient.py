"""The transient of :class:`fe.BeamModel`: the generalized-alpha scheme (Chung and
Hulbert 1993), its coefficients and accuracy, and :meth:`BeamTransient.simulate`,
the model interface of :func:`fe.simulate`.

Apart from :mod:`fe.model` because time stepping is its own algorithm: the model
assembles the system, this module integrates it in time (the compiled Newton loop
is ``fe._kernels.transient``).  :class:`BeamTransient` is mixed into
:class:`fe.BeamModel`.
"""

from __future__ import annotations

import math

import numpy as np

from . import _kernels as K
from .excitation import upsample
from .mesh import hermite_weights
from .results import ConvergenceError, SimulationResult
from .rig import Parameters


def generalized_alpha_coefficients(rho_inf: float) -> tuple[float, float, float, float]:
    """(alpha_m, alpha_f, gamma, beta) of Chung and Hulbert (1993), paper eq. 7-10."""
    if not (math.isfinite(rho_inf) and 0.0 <= rho_inf <= 1.0):
        raise ValueError(f"rho_inf must lie in [0, 1], got {rho_inf}")
    alpha_m = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    alpha_f = rho_inf / (rho_inf + 1.0)
    gamma = 0.5 - alpha_m + alpha_f
    beta = 0.25 * (1.0 - alpha_m + alpha_f) ** 2
    return alpha_m, alpha_f, gamma, beta


def generalized_alpha_accuracy(rho_inf: float, omega_dt: float) -> tuple[float, float]:
    """Algorithmic damping ratio and relative period error of the scheme for an
    undamped mode at omega * dt (from the principal roots of its amplification
    matrix).  Returns (damping_ratio, period_elongation), both dimensionless."""
    am, af, g, b = generalized_alpha_coefficients(rho_inf)
    w2 = omega_dt**2
    lhs = np.array([[w2 * (1 - af), 0, 1 - am], [1, 0, -b], [0, 1, -g]])
    rhs = np.array([[-w2 * af, 0, -am], [1, 1, 0.5 - b], [0, 1, 1 - g]])
    lam = np.linalg.eigvals(np.linalg.solve(lhs, rhs))
    principal = lam[np.argmax(lam.imag)]
    phase = np.angle(principal)
    zeta = -np.log(abs(principal)) / phase
    # damped phase per step -> undamped numerical frequency
    omega_num = np.hypot(phase, np.log(abs(principal)))
    return float(zeta), float(omega_dt / omega_num - 1.0)


class BeamTransient:
    """The transient of :class:`fe.BeamModel` (mixed into it; uses the model's
    settings, ``describe``, ``_arrays`` and ``static_equilibrium``)."""

    # ---------------------------------------------------------------- transient
    def simulate(
        self,
        params: Parameters,
        force,
        fs: float = 1024.0,
        positions=None,
        initial_displacement=None,
        initial_velocity=None,
    ) -> SimulationResult:
        """Transient response to a sampled shaker force.

        Parameters
        ----------
        params : the updated parameters (SI).
        force : shaker force samples [N], spacing 1/fs, interpolated between
            samples as ``input_interpolation`` says.
        fs : output sampling rate [Hz]; the integrator takes ``substeps`` steps
            per sample.
        positions : transverse output positions from the clamp [m]
            (default: the sensor position).
        initial_displacement, initial_velocity : optional initial state, added
            to the static preloaded equilibrium / replacing the zero velocity
            (length n_dof; for verification studies).

        The transient starts from the static preloaded equilibrium.
        """
        force = np.ascontiguousarray(force, dtype=float)
        if force.ndim != 1 or force.size < 2:
            raise ValueError("force must be a 1-D array with at least 2 samples")
        if not np.all(np.isfinite(force)):
            raise ValueError("force contains NaN or inf")
        if not (fs > 0 and math.isfinite(fs)):
            raise ValueError(f"fs must be a positive sampling rate in Hz, got {fs}")
        positions = np.atleast_1d(self.rig.sensor_position_m if positions is None else positions)
        positions = positions.astype(float)
        state = self.static_equilibrium(params)
        system = self.describe(params)
        a = self._arrays(system, params)
        n = system.n_dof
        u = state.u.copy()
        v = np.zeros(n)
        if initial_displacement is not None:
            u += np.asarray(initial_displacement, float)
        if initial_velocity is not None:
            v[:] = np.asarray(initial_velocity, float)
        u[a["fixed"]] = 0.0
        v[a["fixed"]] = 0.0
        W = np.array([hermite_weights(self.node_x, p) for p in positions])
        am, af, gam, bet = generalized_alpha_coefficients(self.rho_inf)
        dt = 1.0 / (fs * self.substeps)
        tol = self.newton_rtol * (params.F + np.abs(force).max()) + self._roundoff_force
        ns = force.size
        if self.input_interpolation == "linear":
            fine, m = force, 1  # the kernel interpolates linearly between samples
        else:
            # one step per point of the upsampled force; every substeps-th is a sample
            fine, m = upsample(force, self.substeps, self.input_interpolation), self.substeps
        out_d = np.empty((fine.size, positions.size))
        out_v = np.empty((fine.size, positions.size))
        out_a = np.empty(fine.size)
        status, failed, iters = K.transient(
            a["elements"],
            a["discrete"],
            a["fixed"],
            a["m_band"],
            (a["f_const"], a["b_load"], fine),
            self.substeps // m,
            (dt, am, af, gam, bet),
            u,
            v,
            (tol, self.max_newton_iterations),
            W,
            self.top_axial_dof,
            (out_d, out_v, out_a),
        )
        out_d, out_v, out_a = out_d[::m], out_v[::m], out_a[::m]
        failed = -(-failed // m)
        if status != 0:
            what = "did not converge" if status == 1 else "hit a singular Newton matrix"
            raise ConvergenceError(
                f"Newton {what} in the time step ending at sample {failed} "
                f"(t = {failed / fs:.4f} s); the response may be diverging or the "
                "step too large: try more substeps"
            )
        return SimulationResult(
            time=np.arange(ns) / fs,
            force=force,
            positions=positions,
            displacement=out_d,
            velocity=out_v,
            axial_top=out_a,
            newton_iterations=int(iters),
            final_displacement=u,
            final_velocity=v,
        )
