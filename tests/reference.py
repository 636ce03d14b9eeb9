"""Independent references for the FE tests: closed forms and continuum solutions
computed without any code of the package under test."""

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq


def clamped_clamped_frequencies(EI, m, L, P=0.0, n_modes=3, f_max=2000.0):
    """Natural frequencies [Hz] of the continuous Euler-Bernoulli beam, both ends
    clamped (the top may slide axially), under a uniform compressive force P [N]:
    roots of the 2x2 determinant of EI w'''' + P w'' = m w_tt."""

    def det(f):
        w = 2 * np.pi * f
        sq = np.sqrt(P**2 + 4 * EI * m * w**2)
        a = np.sqrt((-P + sq) / (2 * EI))
        b = np.sqrt((P + sq) / (2 * EI))
        ch, sh, c, s = np.cosh(a * L), np.sinh(a * L), np.cos(b * L), np.sin(b * L)
        d = (ch - c) * (a * ch - a * c) - (sh - a / b * s) * (a * sh + b * s)
        return d / np.cosh(a * L) ** 2  # scaled to stay finite

    grid = np.linspace(0.5, f_max, 20000)
    vals = np.array([det(f) for f in grid])
    roots = []
    for i in np.flatnonzero(np.sign(vals[:-1]) != np.sign(vals[1:])):
        roots.append(brentq(det, grid[i], grid[i + 1], xtol=1e-12))
        if len(roots) == n_modes:
            break
    return np.array(roots)


def cantilever_elastica(load_parameter):
    """Tip displacements of an inextensible cantilever under a dead tip load
    perpendicular to its undeformed axis (Bisshopp and Drucker 1945).

    load_parameter = P L^2 / EI.  Returns (transverse tip deflection / L,
    axial tip shortening / L), from theta'' = -k cos(theta), theta(0) = 0,
    theta'(1) = 0 on s in [0, 1] by shooting."""
    k = load_parameter

    def shoot(kappa0):
        sol = solve_ivp(lambda s, y: [y[1], -k * np.cos(y[0]), np.sin(y[0]), np.cos(y[0])],
                        (0, 1), [0.0, kappa0, 0.0, 0.0], rtol=1e-12, atol=1e-12)
        return sol.y[:, -1]

    kappa0 = brentq(lambda q: shoot(q)[1], 1e-9, k + 1e-9, xtol=1e-14)
    end = shoot(kappa0)
    return end[2], 1.0 - end[3]
