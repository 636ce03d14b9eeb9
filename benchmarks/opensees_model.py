"""The preloaded-beam rig of :class:`fe.BeamModel` rebuilt in OpenSeesPy (an independent code).

Shared by ``tests/test_fe_opensees.py`` (agreement) and ``benchmarks/bench_opensees.py``
(timing).  Everything is taken from the ``fe`` model it mirrors: the mesh
(``model.node_x``, with nodes at the shaker and the sensor), the rig's section
and material, the boundary conditions, the load and the integrator settings.
Beyond the rig's section properties (EA, EI, mass per length) nothing is
computed with fe's code: the viscosity mapping and the scheme's coefficients
come from their formulas (:func:`kelvin_voigt_beta`, :func:`chung_hulbert`),
and the first-order prediction of the viscosity models' difference
(:func:`kelvin_voigt_perturbation`) from a numpy corotational element
(:class:`_CorotationalBeam`).

Correspondence (ours -> OpenSees):

* beam element, ``formulation="linear"`` (co-rotational frame on the chord,
  chord-only axial strain, Euler-Bernoulli local beam) -> ``elasticBeamColumn``
  with the ``Corotational`` geometric transformation (``CorotCrdTransf2d``: the
  same stretch ``Ln - L``, local rotations ``theta_i - alpha`` and tangent);
* consistent mass (linear axial, Hermite transverse, no rotary inertia, in the
  reference frame) -> ``-mass rho A -cMass`` (the local consistent matrix turned
  by the element's initial orientation);
* bottom clamped -> ``fix(1, 1, 1, 1)``; top: transverse displacement and
  rotation held, axial free -> ``fix(top, 0, 1, 1)``;
* constant compressive force F at the top -> a static load pattern, applied in
  one static Newton step and held with ``loadConst``;
* axial spring k_s and damper c to ground -> one ``zeroLength`` element to a
  fixed ground node with an ``Elastic(k_s, eta=c)`` material (force k_s u + c v);
* Kelvin-Voigt viscosity (ours: beta = eta_b / E on the material stiffness and
  the true local deformation rates of each element) -> stiffness-proportional
  Rayleigh damping with the *initial* stiffness, ``betaK0 = beta``, on the beam
  elements only (a ``region``; the top damper must not get it).  Identical in the
  linearised problem; it misses the nonlinear part of the true Kelvin-Voigt law
  (the damping of the shortening rate, the turning of the element frames);
* shaker force samples, linearly interpolated within a sample -> a ``Path``
  time series with ``-dt 1/fs`` on a transverse nodal load at the shaker node;
* generalized-alpha of Chung and Hulbert (1993) with rho_inf -> OpenSees
  ``HHTGeneralized(alphaI, alphaF, beta, gamma)``, whose alphas are one minus
  Chung-Hulbert's: alphaI = 1 - alpha_m, alphaF = 1 - alpha_f (for one argument,
  ``HHTGeneralized(rho_inf)``, OpenSees sets alphaI = (2 - rho)/(1 + rho),
  alphaF = 1/(1 + rho), beta = 1/(1 + rho)^2, gamma = (3 - rho)/(2 (1 + rho)):
  exactly that).  Not ``GeneralizedAlpha``, which weights the inertia
  differently (docs/design.md#independent-code-pitfalls).  Remaining difference,
  zero for a linear problem: ours averages the internal forces,
  (1 - alpha_f) f(u_{n+1}) + alpha_f f(u_n) (the paper's eq. 4), OpenSees
  evaluates them at the averaged state f((1 - alpha_f) u_{n+1} + alpha_f u_n).

OpenSees keeps one global model per process: every function here starts with
``ops.wipe()``, so do not interleave them with other OpenSees work.
"""

from __future__ import annotations

import os

import numpy as np

import fe

try:  # OpenSeesPy prints a banner and progress to stdout/stderr
    import openseespy.opensees as ops
except Exception as exc:  # ImportError, or a missing system library (liblapack.so.3)
    ops = None
    IMPORT_ERROR = f"{type(exc).__name__}: {exc}"
else:
    IMPORT_ERROR = None

BEAM_TRANSF = 1
TOP_MATERIAL = 1
STATIC_SERIES, STATIC_PATTERN = 1, 1
SHAKER_SERIES, SHAKER_PATTERN = 2, 2


def _require():
    if ops is None:
        raise ImportError(f"openseespy is not usable: {IMPORT_ERROR}")


def _node_tag(i: int) -> int:
    return i + 1


def _find_node(model: fe.BeamModel, x: float) -> int:
    hit = np.flatnonzero(np.isclose(model.node_x, x, rtol=0.0, atol=1e-12))
    if hit.size != 1:
        raise ValueError(f"the mesh has no node at x = {x} m")
    return int(hit[0])


def _roundoff_force(model: fe.BeamModel) -> float:
    # the internal forces carry a round-off of a few eps EA L / L_element (the
    # stretch is a small difference of lengths): the same floor as fe uses
    shortest = np.diff(model.node_x).min()
    return 8 * np.finfo(float).eps * model.rig.EA * model.rig.length_m / shortest


def build_opensees_rig(
    model: fe.BeamModel, params: fe.Parameters, kelvin_voigt: bool = True, quiet: bool = True
) -> dict:
    """Build the rig of ``model`` at ``params`` in OpenSees and solve the preloaded state.

    Returns a dict with the node tags of interest ('shaker', 'sensor', 'top')
    and the beam element tags.  The static preload is applied in one static
    Newton step and held constant (``loadConst``, time reset to 0), so the
    domain is ready for an eigen analysis or a transient.

    ``kelvin_voigt``: add the viscosity as initial-stiffness-proportional
    Rayleigh damping on the beam elements (betaK0 = eta_b / E).
    ``quiet``: send OpenSees' messages to the null device (failures still raise).
    """
    _require()
    if model.effects:
        raise ValueError("the OpenSees mirror has no model effects; use a model without effects")
    rig = model.rig
    x = np.asarray(model.node_x, float)
    n_nodes = x.size
    ops.wipe()
    if quiet:
        ops.logFile(os.devnull, "-noEcho")
    ops.model("basic", "-ndm", 2, "-ndf", 3)
    for i, xi in enumerate(x):
        ops.node(_node_tag(i), float(xi), 0.0)
    top = _node_tag(n_nodes - 1)
    ops.fix(_node_tag(0), 1, 1, 1)  # clamp
    ops.fix(top, 0, 1, 1)  # guide: transverse and rotation held, axial free

    # beam: E, A, I with EI = rig.EI (includes the bending stiffness factor)
    E = rig.youngs_modulus_pa
    A = rig.area
    Iz = rig.EI / E
    ops.geomTransf("Corotational", BEAM_TRANSF)
    beam_tags = []
    for e in range(n_nodes - 1):
        tag = e + 1
        ops.element(
            "elasticBeamColumn",
            tag,
            _node_tag(e),
            _node_tag(e + 1),
            A,
            E,
            Iz,
            BEAM_TRANSF,
            "-mass",
            rig.mass_per_length,
            "-cMass",
        )
        beam_tags.append(tag)

    # top spring and damper to ground (parallel): Elastic material, force k_s u + c v
    if params.k_s > 0 or params.c > 0:
        ground = _node_tag(n_nodes)
        ops.node(ground, float(x[-1]), 0.0)
        ops.fix(ground, 1, 1, 1)
        ops.uniaxialMaterial("Elastic", TOP_MATERIAL, params.k_s, params.c)
        ops.element("zeroLength", n_nodes, ground, top, "-mat", TOP_MATERIAL, "-dir", 1)

    # Kelvin-Voigt -> betaK0 Rayleigh damping on the beam elements only (the mapping
    # eta -> eta_b from its formula here, so that fe's rig.beam_viscosity is checked)
    beta = kelvin_voigt_beta(rig) * params.eta
    if kelvin_voigt and beta > 0:
        ops.region(1, "-ele", *beam_tags, "-rayleigh", 0.0, 0.0, beta, 0.0)

    # static preload: F compressive (toward the clamp), one Newton step, then held
    ops.timeSeries("Linear", STATIC_SERIES)
    ops.pattern("Plain", STATIC_PATTERN, STATIC_SERIES)
    ops.load(top, -params.F, 0.0, 0.0)
    ops.system("BandGeneral")
    ops.numberer("Plain")
    ops.constraints("Plain")
    tol = model.newton_rtol * params.F + _roundoff_force(model)
    ops.test("NormUnbalance", tol, model.max_newton_iterations, 0, 2)
    ops.algorithm("Newton")
    ops.integrator("LoadControl", 1.0)
    ops.analysis("Static")
    if ops.analyze(1) != 0:
        raise RuntimeError("OpenSees: static preload step did not converge")
    ops.loadConst("-time", 0.0)
    ops.wipeAnalysis()
    return {
        "shaker": _node_tag(_find_node(model, rig.shaker_position_m)),
        "sensor": _node_tag(_find_node(model, rig.sensor_position_m)),
        "top": top,
        "beam_elements": beam_tags,
    }


def opensees_frequencies(
    model: fe.BeamModel, params: fe.Parameters, n_modes: int = 3, quiet: bool = True
) -> np.ndarray:
    """Undamped natural frequencies [Hz] about the preloaded state (eigen after loadConst)."""
    build_opensees_rig(model, params, quiet=quiet)
    ops.system("BandGeneral")
    ops.numberer("Plain")
    ops.constraints("Plain")
    lam = np.asarray(ops.eigen("-fullGenLapack", n_modes), float)
    ops.wipe()
    return np.sqrt(lam) / (2 * np.pi)


def run_opensees_transient(
    model: fe.BeamModel,
    params: fe.Parameters,
    force,
    fs: float = 1024.0,
    kelvin_voigt: bool = True,
    quiet: bool = True,
    record_states: bool = False,
):
    """Mid-span (sensor) transverse velocity [m/s], one value per force sample.

    Same time step as ``model.simulate``: ``model.substeps`` HHTGeneralized steps
    per sample, dt = 1 / (fs substeps), Chung-Hulbert parameters of
    ``model.rho_inf``; full Newton to the same residual tolerance as ``fe``.
    Starts from the static preloaded state at rest (first value 0).
    With ``record_states``, also returns {'u', 'v', 'dt'}: the displacements and
    velocities of all beam dofs (fe's ordering, 3 per node) at every time step
    (one analyze call per step: slower).
    """
    force = np.ascontiguousarray(force, dtype=float)
    nodes = build_opensees_rig(model, params, kelvin_voigt=kelvin_voigt, quiet=quiet)
    am, af, gam, bet = chung_hulbert(model.rho_inf)  # closed forms, not fe's
    dt = 1.0 / (fs * model.substeps)
    ops.timeSeries("Path", SHAKER_SERIES, "-dt", 1.0 / fs, "-values", *force.tolist())
    ops.pattern("Plain", SHAKER_PATTERN, SHAKER_SERIES)
    ops.load(nodes["shaker"], 0.0, 1.0, 0.0)
    ops.system("BandGeneral")
    ops.numberer("Plain")
    ops.constraints("Plain")
    tol = model.newton_rtol * (params.F + np.abs(force).max()) + _roundoff_force(model)
    ops.test("NormUnbalance", tol, model.max_newton_iterations, 0, 2)
    ops.algorithm("Newton")
    # OpenSees' alphas are one minus Chung-Hulbert's
    ops.integrator("HHTGeneralized", 1.0 - am, 1.0 - af, bet, gam)
    ops.analysis("Transient")
    out = np.empty(force.size)
    sensor = nodes["sensor"]
    out[0] = ops.nodeVel(sensor, 2)
    if record_states:
        n_steps = (force.size - 1) * model.substeps
        tags = [_node_tag(i) for i in range(model.node_x.size)]
        U = np.empty((n_steps + 1, 3 * len(tags)))
        V = np.empty_like(U)

        def grab(j):
            for i, tag in enumerate(tags):
                U[j, 3 * i : 3 * i + 3] = ops.nodeDisp(tag)
                V[j, 3 * i : 3 * i + 3] = ops.nodeVel(tag)

        grab(0)
    for k in range(1, force.size):
        if record_states:
            for j in range(model.substeps):
                ok = ops.analyze(1, dt)
                if ok != 0:
                    break
                grab((k - 1) * model.substeps + j + 1)
        else:
            ok = ops.analyze(model.substeps, dt)
        if ok != 0:
            ops.wipe()
            raise RuntimeError(f"OpenSees transient failed in the sample ending at {k} (t = {k / fs:.4f} s)")
        out[k] = ops.nodeVel(sensor, 2)
    ops.wipe()
    if record_states:
        return out, {"u": U, "v": V, "dt": dt}
    return out


def chung_hulbert(rho_inf: float) -> tuple:
    """(alpha_m, alpha_f, gamma, beta) of Chung and Hulbert (1993), from their
    closed forms (not from fe)."""
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    return am, af, 0.5 - am + af, 0.25 * (1.0 - am + af) ** 2


def kelvin_voigt_beta(rig) -> float:
    """Stiffness-proportional factor beta = eta_b / E per unit paper eta [s / (Pa s)]:
    the paper's deviatoric eta mapped to uniaxial stress by dissipation
    equivalence, eta_b = (2/3) (1 + nu)^2 eta (docs/design.md#kelvin-voigt-viscosity-on-the-beam), from the rig's
    nu here, not from fe."""
    return 2.0 / 3.0 * (1.0 + rig.poisson_ratio) ** 2 / rig.youngs_modulus_pa


class _CorotationalBeam:
    """Numpy model of the OpenSees mirror (``elasticBeamColumn`` + ``Corotational``
    on the straight mesh of ``model``, consistent mass, top spring and damper),
    written from the element's textbook formulas (Crisfield 1991 vol. 1 ch. 7;
    Battini 2002; docs/design.md#independent-code-checks), with no code of ``fe``: global dofs
    (u_x, u_y, theta) per node, elements along x.

    Local deformations of element (1, 2): stretch u_l = (Ln^2 - L^2) / (Ln + L),
    end rotations t_i = theta_i - alpha (alpha the chord's rotation), with
    B = d(u_l, t1, t2)/d(dofs) = [r; e3 - z/Ln; e6 - z/Ln],
    r = (-c, -s, 0, c, s, 0), z = (s, -c, 0, -s, c, 0); local forces
    (N, M1, M2) = K_l (u_l, t1, t2), K_l = [[EA/L, 0, 0], [0, 4EI/L, 2EI/L],
    [0, 2EI/L, 4EI/L]]; global force B^T (N, M1, M2); tangent
    B^T K_l B + (N/Ln) z z^T + ((M1 + M2)/Ln^2) (r z^T + z r^T).  The Kelvin-Voigt
    force is beta B^T K_l B v (the local deformation rates); in the tangents its
    local forces enter the geometric terms, the rates' own dependence on u is
    left out (a 3e-5 relative term of K_t: second order in the prediction)."""

    def __init__(self, model, params):
        rig = model.rig
        self.x = np.asarray(model.node_x, float)
        self.L = np.diff(self.x)
        self.ne = self.L.size
        self.n = 3 * self.x.size
        self.EA, self.EI = rig.EA, rig.EI
        self.kax = self.EA / self.L
        self.kb = self.EI / self.L
        self.beta = kelvin_voigt_beta(rig) * params.eta
        self.k_s, self.c_top = params.k_s, params.c
        self.top = self.n - 3
        fixed = np.zeros(self.n, bool)
        fixed[:3] = True
        fixed[self.n - 2 :] = True  # top: transverse and rotation held
        self.free = np.flatnonzero(~fixed)
        where = np.full(self.n, -1)
        where[self.free] = np.arange(self.free.size)
        # scatter of the element matrices into the free-dof matrix; elements of one
        # parity share no dof, so one fancy-indexed += per parity is safe
        self._scatter = []
        for parity in (0, 1):
            rows, cols, ee, ii, jj = [], [], [], [], []
            for e in range(parity, self.ne, 2):
                for i in range(6):
                    for j in range(6):
                        gi, gj = where[3 * e + i], where[3 * e + j]
                        if gi >= 0 and gj >= 0:
                            rows.append(gi), cols.append(gj), ee.append(e), ii.append(i), jj.append(j)
            self._scatter.append(tuple(np.array(a) for a in (rows, cols, ee, ii, jj)))
        self.top_free = int(where[self.top])
        # consistent mass (linear axial, Hermite transverse, no rotary inertia)
        m = rig.mass_per_length
        M = np.zeros((self.n, self.n))
        for e, L in enumerate(self.L):
            i = 3 * e
            ax = m * L / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
            tr = (
                m
                * L
                / 420.0
                * np.array(
                    [
                        [156.0, 22 * L, 54.0, -13 * L],
                        [22 * L, 4 * L * L, 13 * L, -3 * L * L],
                        [54.0, 13 * L, 156.0, -22 * L],
                        [-13 * L, -3 * L * L, -22 * L, 4 * L * L],
                    ]
                )
            )
            a, t = [i, i + 3], [i + 1, i + 2, i + 4, i + 5]
            M[np.ix_(a, a)] += ax
            M[np.ix_(t, t)] += tr
        self.M = M[np.ix_(self.free, self.free)]

    def state(self, u, v):
        """Everything per element at (u, v): r, z (ne, 6), Ln, B's rows b1, b2
        (ne, 6), local elastic and viscous forces (ne, 3)."""
        U = u.reshape(-1, 3)
        Vn = v.reshape(-1, 3)
        d = np.concatenate([U[:-1], U[1:]], axis=1)
        ve = np.concatenate([Vn[:-1], Vn[1:]], axis=1)
        dx = self.L + d[:, 3] - d[:, 0]
        dy = d[:, 4] - d[:, 1]
        Ln = np.hypot(dx, dy)
        c, s = dx / Ln, dy / Ln
        alpha = np.arctan2(dy, dx)
        zero = np.zeros_like(c)
        r = np.stack([-c, -s, zero, c, s, zero], axis=1)
        z = np.stack([s, -c, zero, -s, c, zero], axis=1)
        b1 = -z / Ln[:, None]
        b2 = b1.copy()
        b1[:, 2] += 1.0
        b2[:, 5] += 1.0
        ul = (Ln * Ln - self.L**2) / (Ln + self.L)
        t1, t2 = d[:, 2] - alpha, d[:, 5] - alpha
        q0 = np.sum(r * ve, axis=1)
        q1 = np.sum(b1 * ve, axis=1)
        q2 = np.sum(b2 * ve, axis=1)
        elastic = np.stack([self.kax * ul, self.kb * (4 * t1 + 2 * t2), self.kb * (2 * t1 + 4 * t2)], axis=1)
        viscous = self.beta * np.stack(
            [self.kax * q0, self.kb * (4 * q1 + 2 * q2), self.kb * (2 * q1 + 4 * q2)], axis=1
        )
        return r, z, Ln, b1, b2, elastic, viscous

    def _to_global(self, r, b1, b2, loc):
        fe_ = r * loc[:, :1] + b1 * loc[:, 1:2] + b2 * loc[:, 2:3]
        out = np.zeros(self.n)
        out[:-3] += fe_[:, :3].ravel()
        out[3:] += fe_[:, 3:].ravel()
        return out

    def _material(self, r, b1, b2):
        """B^T K_l B per element (ne, 6, 6)."""
        o = np.einsum
        return self.kax[:, None, None] * o("ei,ej->eij", r, r) + self.kb[:, None, None] * (
            4 * o("ei,ej->eij", b1, b1)
            + 4 * o("ei,ej->eij", b2, b2)
            + 2 * o("ei,ej->eij", b1, b2)
            + 2 * o("ei,ej->eij", b2, b1)
        )

    def _free_matrix(self, ke):
        out = np.zeros((self.free.size, self.free.size))
        for rows, cols, ee, ii, jj in self._scatter:
            out[rows, cols] += ke[ee, ii, jj]
        return out

    def kelvin_voigt_force(self, u, v, st=None):
        """Viscous force of the true Kelvin-Voigt law (beta K_l on the local
        deformation rates B(u) v), all dofs."""
        r, z, Ln, b1, b2, elastic, viscous = st if st is not None else self.state(u, v)
        return self._to_global(r, b1, b2, viscous)

    def internal_force(self, u, v):
        """Elastic + Kelvin-Voigt force with the top spring and damper, all dofs."""
        r, z, Ln, b1, b2, elastic, viscous = self.state(u, v)
        f = self._to_global(r, b1, b2, elastic + viscous)
        f[self.top] += self.k_s * u[self.top] + self.c_top * v[self.top]
        return f

    def rayleigh_matrix(self):
        """beta K_0 on the free dofs: the material stiffness of the undeformed beam
        (OpenSees' initial stiffness of the beam elements)."""
        r, z, Ln, b1, b2, *_ = self.state(np.zeros(self.n), np.zeros(self.n))
        return self.beta * self._free_matrix(self._material(r, b1, b2))

    def tangents(self, u, v, st=None):
        """(K_t, C_t) on the free dofs: d f / d u (material + geometric) and d f / d v."""
        r, z, Ln, b1, b2, elastic, viscous = st if st is not None else self.state(u, v)
        loc = elastic + viscous
        material = self._material(r, b1, b2)
        rz = np.einsum("ei,ej->eij", r, z)
        geometric = (loc[:, 0] / Ln)[:, None, None] * np.einsum("ei,ej->eij", z, z) + ((loc[:, 1] + loc[:, 2]) / Ln**2)[
            :, None, None
        ] * (rz + rz.transpose(0, 2, 1))
        K = self._free_matrix(material + geometric)
        C = self.beta * self._free_matrix(material)
        K[self.top_free, self.top_free] += self.k_s
        C[self.top_free, self.top_free] += self.c_top
        return K, C


def kelvin_voigt_perturbation(
    model: fe.BeamModel, params: fe.Parameters, states: dict, fs: float = 1024.0
) -> np.ndarray:
    """First-order prediction of (fe - OpenSees) in the sensor velocity [m/s] per sample,
    from the one modelling difference of the viscosity.

    Along the OpenSees trajectory (``states`` from ``run_opensees_transient(...,
    record_states=True)``) the missing force is

        g(u, v) = f_KV(u, v) - beta K_0 v,

    the true Kelvin-Voigt force on the local deformation rates minus OpenSees'
    constant initial-stiffness Rayleigh force (the top damper is the same in both).
    The difference d = x_fe - x_OpenSees then obeys, to first order,
    M d'' + C_t(t) d' + K_t(t) d = -g(t) with the tangents along the trajectory;
    it is integrated with the Chung-Hulbert scheme at the same step.

    Independent of fe: the missing force, the tangents, the mass and the scheme's
    coefficients come from :class:`_CorotationalBeam` and :func:`chung_hulbert`
    (textbook formulas, numpy); only the mesh (``model.node_x``), the rig's
    constants and the settings (``rho_inf``, ``substeps``) are taken from
    ``model``.  So a wrong Kelvin-Voigt law in fe is not reproduced here.
    """
    beam = _CorotationalBeam(model, params)
    U, V, dt = states["u"], states["v"], states["dt"]
    if U.shape[1] != beam.n:
        raise ValueError("states do not match the model's dofs")
    free = beam.free
    c_os = beam.rayleigh_matrix()

    def missing_and_tangents(u, v):
        st = beam.state(u, v)
        return (beam.kelvin_voigt_force(u, v, st)[free] - c_os @ v[free],) + beam.tangents(u, v, st)

    am, af, gam, bet = chung_hulbert(model.rho_inf)
    M = beam.M
    n_steps = U.shape[0] - 1
    substeps = model.substeps
    sensor = int(np.flatnonzero(np.isclose(beam.x, model.rig.sensor_position_m, rtol=0.0, atol=1e-12))[0])
    out_dof = int(np.flatnonzero(free == 3 * sensor + 1)[0])
    m_free = free.size
    du = np.zeros(m_free)
    dv = np.zeros(m_free)
    g_old, k_old, c_old = missing_and_tangents(U[0], V[0])
    da = np.linalg.solve(M, -g_old)
    out = np.zeros(n_steps // substeps + 1)
    for j in range(n_steps):
        g_new, k_new, c_new = missing_and_tangents(U[j + 1], V[j + 1])
        pu = du + dt * dv + dt * dt * (0.5 - bet) * da
        pv = dv + dt * (1.0 - gam) * da
        S = (1.0 - am) * M + (1.0 - af) * (bet * dt * dt * k_new + gam * dt * c_new)
        rhs = -am * (M @ da) - (1.0 - af) * (k_new @ pu + c_new @ pv + g_new) - af * (k_old @ du + c_old @ dv + g_old)
        da_new = np.linalg.solve(S, rhs)
        du = pu + bet * dt * dt * da_new
        dv = pv + gam * dt * da_new
        da = da_new
        g_old, k_old, c_old = g_new, k_new, c_new
        if (j + 1) % substeps == 0:
            out[(j + 1) // substeps] = dv[out_dof]
    return out
