"""Structures with known modes for the front-end corpus (``front_end_corpus.py``).

None of these is a form the front end fits (it fits discrete Kautz filters
and rational FRFs): every response here comes from the continuous system.

* :class:`Linear`: a continuous linear system in complex modal form,
  ``q_k' = lam_k q_k + u(t)``, displacement ``x_s = sum_k 2 Re(r_sk q_k)``,
  velocity and acceleration as its derivatives (``lam^p`` on the residue and
  the feed-through a collocated accelerometer has).  Responses are exact for
  an input that is piecewise linear between the samples of a fine grid
  (first-order hold; the grid is the generator's, ``OVERSAMPLING`` times
  the record's rate), one complex recursion per mode (``scipy.signal.lfilter``).
* Linear systems from physics: :func:`beam` (an Euler-Bernoulli beam,
  pinned-pinned or cantilever, truncated at many modes), :func:`plate` (a
  simply supported rectangular plate: its modes come in close pairs near a
  square), :func:`lumped` (a random chain of masses and springs whose damping
  matrix is not proportional: complex modes, from the first-order state
  space's eigenvalues), :func:`modal_draw` (modes drawn in a band, close
  pairs on request).
* :func:`nonlinear_sdof`: a single-degree-of-freedom oscillator with a
  cubic or quadratic spring, Bouc-Wen hysteresis, regularised Coulomb
  friction or a clearance (contact springs beyond a gap), integrated by
  ``scipy.integrate.solve_ivp`` (DOP853) on the same fine grid; its modes are
  those of the linearisation about rest.

Frequencies Hz, damping ratios [-], SI units (m, m/s, m/s^2, N, kg).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize, signal
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline

KINDS = ("displacement", "velocity", "acceleration")
_POWER = {"displacement": 0, "velocity": 1, "acceleration": 2}


@dataclass(frozen=True)
class Linear:
    """Complex modal form of a linear structure (module docstring).

    lam : (M,) continuous poles [rad/s], upper half plane
    residues : (M, S) displacement residues of the sensors [m/N/s]
    kinds : (S,) response kind of each sensor
    """

    lam: np.ndarray
    residues: np.ndarray
    kinds: tuple

    @property
    def freq_hz(self) -> np.ndarray:
        return np.abs(self.lam) / (2 * np.pi)

    @property
    def zeta(self) -> np.ndarray:
        return -self.lam.real / np.abs(self.lam)

    def frf(self, f_hz) -> np.ndarray:
        """(L, S) FRF of every sensor in its own kind at ``f_hz``."""
        s = 2j * np.pi * np.asarray(f_hz, float)[:, None, None]
        lam, r = self.lam[None, :, None], self.residues[None]
        hd = np.sum(r / (s - lam) + np.conj(r) / (s - np.conj(lam)), axis=1)
        p = np.array([_POWER[k] for k in self.kinds])
        return hd * (s[:, 0, :] ** p)

    def respond(self, u_fine: np.ndarray, h: float) -> np.ndarray:
        """(n, S) response to the piecewise-linear input ``u_fine`` (steps of ``h`` s), from rest."""
        u = np.asarray(u_fine, float)
        out = np.zeros((u.size, len(self.kinds)))
        p = np.array([_POWER[k] for k in self.kinds])
        for k, lam in enumerate(self.lam):
            x = lam * h
            phi1, phi2 = _phi(x)
            e = np.exp(x)
            b1 = h * phi2  # weight of u[n]  (end of the step)
            b0 = h * phi1 - b1  # weight of u[n-1]
            q = signal.lfilter([b1, b0], [1.0, -e], u.astype(complex))
            for s in range(out.shape[1]):
                out[:, s] += 2.0 * np.real(self.residues[k, s] * lam ** p[s] * q)
        # the direct terms of s^p r / (s - lam): acceleration's r lam (velocity's r is zero when the
        # displacement falls as 1/s^2, which every system here satisfies)
        for s in range(out.shape[1]):
            if p[s] == 2:
                out[:, s] += 2.0 * np.real(np.sum(self.residues[:, s] * self.lam)) * u
        return out


def _phi(x: complex):
    """(phi1, phi2) = ((e^x - 1) / x, (e^x - 1 - x) / x^2), by series for small |x| (no cancellation)."""
    if abs(x) < 0.05:
        terms = x ** np.arange(14) / np.cumprod(np.concatenate([[1.0], np.arange(2, 15)]))
        phi1 = np.sum(terms)
        phi2 = np.sum(x ** np.arange(13) / np.cumprod(np.arange(2, 15)))
        return complex(phi1), complex(phi2)
    e = np.exp(x)
    return (e - 1) / x, (e - 1 - x) / x**2


def _real_modes(freq_hz, zeta, shapes_f, shapes_s, kinds) -> Linear:
    """Linear of mass-normalised real modes: force at shape value ``shapes_f`` (M,),
    sensors at ``shapes_s`` (M, S)."""
    w = 2 * np.pi * np.asarray(freq_hz, float)
    z = np.asarray(zeta, float)
    lam = -z * w + 1j * w * np.sqrt(1 - z**2)
    r = np.asarray(shapes_f, float)[:, None] * np.asarray(shapes_s, float) / (2j * lam.imag[:, None])
    return Linear(lam, r, tuple(kinds))


# ----------------------------------------------------------------- physics
def beam(rng, n_modes: int, f1_hz: float, support: str, force_x: float, sensor_x, kinds, zeta) -> Linear:
    """Euler-Bernoulli beam of unit length and mass, ``n_modes`` modes, the first at
    ``f1_hz``: ``support`` "pinned" (sin shapes, f_k = k^2 f1) or "cantilever"
    (clamped-free, beta_k from cos cosh = -1); force and sensors at relative
    positions; modal damping ``zeta`` (M,)."""
    x = np.concatenate([[force_x], np.asarray(sensor_x, float)])
    if support == "pinned":
        k = np.arange(1, n_modes + 1)
        shapes = np.sqrt(2) * np.sin(np.outer(k, np.pi * x))
        freq = f1_hz * k**2
    elif support == "cantilever":
        betas = np.array(
            [
                optimize.brentq(
                    lambda b: np.cos(b) * np.cosh(b) + 1, (j - 0.5) * np.pi - 0.5 + 0.1, (j - 0.5) * np.pi + 0.6
                )
                for j in range(1, n_modes + 1)
            ]
        )
        sig = (np.cosh(betas) + np.cos(betas)) / (np.sinh(betas) + np.sin(betas))
        bx = np.outer(betas, x)
        # the far-field form sin/sinh - sigma (cos - cosh): cosh and sinh nearly cancel for high modes
        shapes = np.cosh(bx) - np.cos(bx) - sig[:, None] * (np.sinh(bx) - np.sin(bx))
        shapes /= np.sqrt(np.mean(_cantilever_grid(betas, sig) ** 2, axis=1))[:, None]
        freq = f1_hz * (betas / betas[0]) ** 2
    else:
        raise ValueError(f"support must be 'pinned' or 'cantilever', got {support!r}")
    return _real_modes(freq, zeta, shapes[:, 0], shapes[:, 1:], kinds)


def _cantilever_grid(betas, sig):
    g = np.linspace(0, 1, 2001)
    bx = np.outer(betas, g)
    return np.cosh(bx) - np.cos(bx) - sig[:, None] * (np.sinh(bx) - np.sin(bx))


def plate(aspect: float, n_side: int, f11_hz: float, force_xy, sensor_xy, kinds, zeta_of) -> Linear:
    """Simply supported plate a x b = 1 x ``aspect``, modes (m, n) up to ``n_side`` each,
    f_mn = f11 ((m^2 + (n/aspect)^2) / (1 + 1/aspect^2)); shapes 2 sin(m pi x) sin(n pi y / aspect);
    ``zeta_of(freq)`` the modal damping."""
    m, n = np.meshgrid(np.arange(1, n_side + 1), np.arange(1, n_side + 1), indexing="ij")
    m, n = m.ravel(), n.ravel()
    freq = f11_hz * (m**2 + (n / aspect) ** 2) / (1 + 1 / aspect**2)
    order = np.argsort(freq)
    m, n, freq = m[order], n[order], freq[order]
    pts = np.vstack([np.asarray(force_xy, float)[None], np.asarray(sensor_xy, float)])
    shapes = 2 * np.sin(np.pi * np.outer(m, pts[:, 0])) * np.sin(np.pi * np.outer(n, pts[:, 1]) / aspect)
    return _real_modes(freq, zeta_of(freq), shapes[:, 0], shapes[:, 1:], kinds)


def lumped(rng, n_dof: int, f_first_hz: float, zeta_range, force_dof: int, sensor_dofs, kinds) -> Linear:
    """A chain of ``n_dof`` random masses and springs (grounded at one end, a spring to
    ground at the other), non-proportional damping: modal damping drawn in
    ``zeta_range`` plus a local dashpot on one random spring; scaled so that the
    first mode is near ``f_first_hz``.  Complex modes from the first-order
    state space x' = A x + B u (scipy.linalg.eig)."""
    mass = rng.uniform(0.5, 2.0, n_dof)
    ks = rng.uniform(0.4, 2.5, n_dof + 1)
    K = np.zeros((n_dof, n_dof))
    for i in range(n_dof + 1):  # spring i between dof i-1 and dof i (ground outside)
        a, b = i - 1, i
        for p, q, sgn in ((a, a, 1), (b, b, 1), (a, b, -1), (b, a, -1)):
            if 0 <= p < n_dof and 0 <= q < n_dof:
                K[p, q] += sgn * ks[i]
    M = np.diag(mass)
    w2, phi = linalg.eigh(K, M)
    scale = (2 * np.pi * f_first_hz) ** 2 / w2[0]
    K *= scale
    w = np.sqrt(w2 * scale)
    z = np.exp(rng.uniform(np.log(zeta_range[0]), np.log(zeta_range[1]), n_dof))
    C = M @ phi @ np.diag(2 * z * w) @ phi.T @ M
    j = int(rng.integers(0, n_dof))
    C[j, j] += 0.5 * C[j, j]  # a local dashpot: the modes become complex
    A = np.block([[np.zeros((n_dof, n_dof)), np.eye(n_dof)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
    B = np.zeros(2 * n_dof)
    B[n_dof + force_dof] = 1.0 / mass[force_dof]
    lam, V = linalg.eig(A)
    keep = lam.imag > 0
    if keep.sum() != n_dof:
        raise ValueError("an overdamped mode: draw again")
    beta = np.linalg.solve(V, B)
    # displacement of dof d: sum over all 2n eigenvalues V[d] beta / (s - lam); pairs are conjugate
    r = V[np.asarray(sensor_dofs)][:, keep].T * beta[keep][:, None]
    return Linear(lam[keep], r, tuple(kinds))


def modal_draw(freq_hz, zeta, rng, n_sensors: int, kinds, complex_modes: bool) -> Linear:
    """Modes at ``freq_hz`` with ``zeta``, random mass-normalised shapes at the force and
    the sensors (magnitudes 0.3-1: every mode observable), optionally complex
    (the residues turned by up to +-25 degrees, the displacement still falling
    as 1/s^2: the residues' real parts sum to zero)."""
    M = len(freq_hz)
    sign = rng.choice([-1.0, 1.0], size=(M, n_sensors + 1))
    shp = sign * rng.uniform(0.3, 1.0, size=(M, n_sensors + 1))
    lin = _real_modes(freq_hz, zeta, shp[:, 0], shp[:, 1:], kinds)
    if not complex_modes:
        return lin
    r = lin.residues * np.exp(1j * np.deg2rad(rng.uniform(-25, 25, size=lin.residues.shape)))
    r = r - np.mean(r.real, axis=0, keepdims=True)  # sum of real parts zero per sensor
    return Linear(lin.lam, r, lin.kinds)


# --------------------------------------------------------------- nonlinear
NONLINEAR_FORMS = ("cubic", "quadratic", "bouc_wen", "friction", "clearance")
#: "linear": the same integrator with no nonlinear force (a linear SDOF solved by solve_ivp)
FORMS = ("linear",) + NONLINEAR_FORMS


@dataclass(frozen=True)
class NonlinearSDOF:
    """m x'' + c x' + k x + g(x, x', z) = u(t); ``form`` one of :data:`NONLINEAR_FORMS`;
    ``scale`` [m] the displacement at which the nonlinearity is of the order of the
    linear spring (the cubic and quadratic coefficients, the yield, the
    friction's sliding velocity / frequency, the gap)."""

    mass: float
    freq_hz: float
    zeta: float
    form: str
    scale: float
    kind: str

    @property
    def k(self):
        return self.mass * (2 * np.pi * self.freq_hz) ** 2

    @property
    def c(self):
        return 2 * self.zeta * np.sqrt(self.k * self.mass)

    def linearised(self) -> Linear:
        """The modes about rest: Bouc-Wen and the regularised friction add stiffness / damping."""
        k, c = self.k, self.c
        if self.form == "bouc_wen":
            k = self.k  # alpha k + (1 - alpha) k A with A = 1
        if self.form == "friction":
            c = c + self._mu() / self._v0()
        w = np.sqrt(k / self.mass)
        z = c / (2 * np.sqrt(k * self.mass))
        return _real_modes([w / (2 * np.pi)], [z], [1 / np.sqrt(self.mass)], [[1 / np.sqrt(self.mass)]], (self.kind,))

    def _mu(self):
        return 0.1 * self.k * self.scale  # friction force [N]

    def _v0(self):
        # the regularisation velocity [m/s]: linearised, the friction adds a damping ratio of 0.01
        return 5.0 * 2 * np.pi * self.freq_hz * self.scale

    def _force(self, x, v, z):
        k, s = self.k, self.scale
        if self.form == "linear":
            return 0.0 * x
        if self.form == "cubic":
            return k * x * (x / s) ** 2
        if self.form == "quadratic":
            return 0.3 * k * x * x / s  # the well ends at x = -s / 0.3: beyond the high level
        if self.form == "bouc_wen":
            return -0.6 * k * x + 0.6 * k * z  # alpha = 0.4 of k elastic, the rest hysteretic
        if self.form == "friction":
            return self._mu() * np.tanh(v / self._v0())
        if self.form == "clearance":
            over = np.logaddexp(0.0, (np.abs(x) - s) / (0.02 * s)) * 0.02 * s  # softplus(|x| - gap)
            return 4.0 * k * np.sign(x) * over
        raise ValueError(self.form)

    def respond(self, u_fine: np.ndarray, h: float) -> np.ndarray:
        """(n, 1) response from rest to ``u_fine`` (steps of ``h`` s), by solve_ivp (DOP853).

        The continuous input is the cubic spline through the fine samples (C2: a
        piecewise-linear input's kinks at every sample would hold the adaptive
        steps to a fraction of one), evaluated from its coefficients in the
        right-hand side."""
        u = np.asarray(u_fine, float)
        n = u.size
        t = np.arange(n) * h
        c3, c2, c1, c0 = (row.tolist() for row in CubicSpline(t, u).c)
        m, k, c, s = self.mass, self.k, self.c, self.scale
        nonlinear = self._force
        bw = self.form == "bouc_wen"
        beta = 0.5 / s

        def rhs(tt, st):
            x, v, z = st
            i = min(int(tt / h), n - 2)
            d = tt - i * h
            f = ((c3[i] * d + c2[i]) * d + c1[i]) * d + c0[i]
            zd = v - beta * abs(v) * z - beta * v * abs(z) if bw else 0.0
            return (v, (f - c * v - k * x - nonlinear(x, v, z)) / m, zd)

        sol = solve_ivp(
            rhs,
            (0.0, t[-1]),
            [0.0, 0.0, 0.0],
            method="DOP853",
            t_eval=t,
            rtol=1e-9,
            atol=[1e-12 * s, 1e-12 * s * 2 * np.pi * self.freq_hz, 1e-12 * s],
        )
        if not sol.success:
            raise RuntimeError(f"solve_ivp: {sol.message}")
        x, v, z = sol.y
        if self.kind == "displacement":
            return x[:, None]
        if self.kind == "velocity":
            return v[:, None]
        return ((u - c * v - k * x - self._force(x, v, z)) / m)[:, None]
