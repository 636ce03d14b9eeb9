"""The preloaded-beam rig of :class:`fe.BeamModel` rebuilt in OpenSeesPy (an independent code).

Shared by ``tests/test_fe_opensees.py`` (agreement) and ``benchmarks/bench_opensees.py``
(timing).  Everything is taken from the ``fe`` model it mirrors: the mesh
(``model.node_x``, with nodes at the shaker and the sensor), the rig's section
and material, the boundary conditions, the load and the integrator settings.

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
  differently (DESIGN.md, "Independent-code pitfall").  Remaining difference,
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


def build_opensees_rig(model: fe.BeamModel, params: fe.Parameters,
                       kelvin_voigt: bool = True, quiet: bool = True) -> dict:
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
        ops.element("elasticBeamColumn", tag, _node_tag(e), _node_tag(e + 1), A, E, Iz,
                    BEAM_TRANSF, "-mass", rig.mass_per_length, "-cMass")
        beam_tags.append(tag)

    # top spring and damper to ground (parallel): Elastic material, force k_s u + c v
    if params.k_s > 0 or params.c > 0:
        ground = _node_tag(n_nodes)
        ops.node(ground, float(x[-1]), 0.0)
        ops.fix(ground, 1, 1, 1)
        ops.uniaxialMaterial("Elastic", TOP_MATERIAL, params.k_s, params.c)
        ops.element("zeroLength", n_nodes, ground, top, "-mat", TOP_MATERIAL, "-dir", 1)

    # Kelvin-Voigt -> betaK0 Rayleigh damping on the beam elements only
    beta = rig.beam_viscosity(params.eta) / E
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


def opensees_frequencies(model: fe.BeamModel, params: fe.Parameters, n_modes: int = 3,
                         quiet: bool = True) -> np.ndarray:
    """Undamped natural frequencies [Hz] about the preloaded state (eigen after loadConst)."""
    build_opensees_rig(model, params, quiet=quiet)
    ops.system("BandGeneral")
    ops.numberer("Plain")
    ops.constraints("Plain")
    lam = np.asarray(ops.eigen("-fullGenLapack", n_modes), float)
    ops.wipe()
    return np.sqrt(lam) / (2 * np.pi)


def run_opensees_transient(model: fe.BeamModel, params: fe.Parameters, force, fs: float = 1024.0,
                           kelvin_voigt: bool = True, quiet: bool = True,
                           record_states: bool = False):
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
    am, af, gam, bet = fe.generalized_alpha_coefficients(model.rho_inf)
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
                U[j, 3 * i:3 * i + 3] = ops.nodeDisp(tag)
                V[j, 3 * i:3 * i + 3] = ops.nodeVel(tag)

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


def kelvin_voigt_perturbation(model: fe.BeamModel, params: fe.Parameters, states: dict,
                              fs: float = 1024.0) -> np.ndarray:
    """First-order prediction of (fe - OpenSees) in the sensor velocity [m/s] per sample,
    from the one modelling difference of the viscosity.

    Along the OpenSees trajectory (``states`` from ``run_opensees_transient(...,
    record_states=True)``) the missing force is

        g(u, v) = [f_fe(u, v) - f_fe(u, 0)] - (beta K_0 v + c v_top),

    fe's Kelvin-Voigt force on the true local deformation rates minus OpenSees'
    constant initial-stiffness Rayleigh force (the top damper cancels).  The
    difference d = x_fe - x_OpenSees then obeys, to first order,
    M d'' + C_t(t) d' + K_t(t) d = -g(t) with fe's tangents along the trajectory;
    it is integrated here with the same generalized-alpha scheme and step.
    Uses fe's private kernels (an independent check of the discrepancy, not of fe).
    """
    from fe import _kernels as K
    from fe.model import KD, hermite_weights

    system = model.describe(params)
    a = model._arrays(system, params)
    n = system.n_dof
    free = ~a["fixed"]
    idx = np.flatnonzero(free)
    U, V, dt = states["u"], states["v"], states["dt"]
    if U.shape[1] != n:
        raise ValueError("states do not match the model's dofs")
    # dense helpers
    rows, cols = np.nonzero(np.abs(np.arange(n)[:, None] - np.arange(n)[None, :]) <= KD)
    band_pos = (rows, KD + cols - rows)

    def dense(band):
        d = np.zeros((n, n))
        d[rows, cols] = band[band_pos]
        return d[np.ix_(idx, idx)]

    M = dense(a["m_band"])
    args = (a["X"], a["Y"], a["L0"], a["c0"], a["s0"], a["t0"], a["EA"], a["EI"], a["beta"], a["shallow"],
            a["d_dof"], a["d_law"], a["d_p1"], a["d_p2"])
    fint = np.empty(n)
    band = np.zeros((n, 2 * KD + 1))

    def tangents(u, v):
        band[:] = 0.0
        K.assemble(*args, u, v, fint, True, 1.0, 0.0, band, KD)
        k = dense(band)
        band[:] = 0.0
        K.assemble(*args, u, v, fint, True, 1.0, 1.0, band, KD)
        return k, dense(band) - k

    # beta K_0: fe's material stiffness of the unloaded, undeformed beam (no springs)
    p0 = fe.Parameters(eta=0.0, c=0.0, F=0.0, k_s=0.0)
    a0 = model._arrays(model.describe(p0), p0)
    band[:] = 0.0
    K.assemble(a0["X"], a0["Y"], a0["L0"], a0["c0"], a0["s0"], a0["t0"], a0["EA"], a0["EI"], 0.0, a0["shallow"],
               a0["d_dof"], a0["d_law"], a0["d_p1"], a0["d_p2"], np.zeros(n), np.zeros(n), fint,
               True, 1.0, 0.0, band, KD)
    beta = a["beta"]
    k0 = np.zeros((n, n))
    k0[rows, cols] = band[band_pos]
    c_os = beta * k0
    c_os[model.top_axial_dof, model.top_axial_dof] += params.c
    f_v = np.empty(n)
    f_0 = np.empty(n)

    def missing(u, v):
        K.internal_force(*args, u, v, f_v)
        K.internal_force(*args, u, np.zeros(n), f_0)
        return (f_v - f_0 - c_os @ v)[idx]

    am, af, gam, bet = fe.generalized_alpha_coefficients(model.rho_inf)
    n_steps = U.shape[0] - 1
    substeps = model.substeps
    w = hermite_weights(model.node_x, model.rig.sensor_position_m)[idx]
    m_free = idx.size
    du = np.zeros(m_free)
    dv = np.zeros(m_free)
    g_old = missing(U[0], V[0])
    k_old, c_old = tangents(U[0], V[0])
    da = np.linalg.solve(M, -g_old)
    out = np.zeros(n_steps // substeps + 1)
    for j in range(n_steps):
        g_new = missing(U[j + 1], V[j + 1])
        k_new, c_new = tangents(U[j + 1], V[j + 1])
        pu = du + dt * dv + dt * dt * (0.5 - bet) * da
        pv = dv + dt * (1.0 - gam) * da
        S = (1.0 - am) * M + (1.0 - af) * (bet * dt * dt * k_new + gam * dt * c_new)
        rhs = (-am * (M @ da) - (1.0 - af) * (k_new @ pu + c_new @ pv + g_new)
               - af * (k_old @ du + c_old @ dv + g_old))
        da_new = np.linalg.solve(S, rhs)
        du = pu + bet * dt * dt * da_new
        dv = pv + gam * dt * da_new
        da = da_new
        g_old, k_old, c_old = g_new, k_new, c_new
        if (j + 1) % substeps == 0:
            out[(j + 1) // substeps] = w @ dv
    return out
