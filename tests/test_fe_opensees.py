"""fe against an independent code: the same rig built in OpenSeesPy.

The OpenSees model (``benchmarks/opensees_model.py``) has the same mesh, the
same element (``formulation="linear"``: co-rotational, chord-only axial strain =
``elasticBeamColumn`` + ``Corotational``), the same consistent mass, boundaries,
top spring/damper, load interpolation and the same Chung-Hulbert scheme
(``HHTGeneralized``) at the same step.  What differs by construction, and what
each tolerance below is built from:

1. Viscosity: fe applies Kelvin-Voigt to the true local deformation rates of
   each element; OpenSees gets the closest linear equivalent, initial-stiffness
   Rayleigh damping beta K_0.  Linearised about the preloaded state these differ
   only through the chord length (fe's rates use the compressed length
   L (1 - P/EA), so every modal damping ratio is 2 P/EA = 7.1e-5 higher); in
   the large-amplitude response fe also damps the shortening rate (the
   nonlinear part beta K_0 misses).  ``kelvin_voigt_perturbation`` predicts this
   difference to first order from the missing force along the OpenSees
   trajectory; the tests check the difference *is* that prediction.  The
   prediction uses no code of fe: the corotational element, its Kelvin-Voigt
   force on the local deformation rates, the tangents, the consistent mass and
   the scheme's coefficients are written out in numpy from the textbook
   formulas (``opensees_model._CorotationalBeam``), so a wrong viscosity law in
   fe would show here instead of being predicted by fe itself.  The viscosity's
   mapping eta_b = (2/3)(1 + nu)^2 eta and the OpenSees integrator's
   coefficients are also computed from their formulas, not taken from fe.
2. Integrator, nonlinear terms only: fe averages the internal forces
   ((1 - alpha_f) f(u_{n+1}) + alpha_f f(u_n), the paper's eq. 4), OpenSees
   evaluates them at the averaged state.  Both are second-order consistent, so
   the difference vanishes as dt^2 and is zero for a linear problem.
3. Newton tolerances (fe: 1e-9 (F + max|p|) plus a round-off floor).

Runtime: 42 s with the machine shared (37 s before the prediction was
independent of fe, back to back), most of it OpenSees (about 0.15 ms per step at
20 elements) and the numpy prediction (about 0.3 ms per step).
"""

import sys
from pathlib import Path

import numpy as np
import pytest
from reference import require_reference  # noqa: E402

import fe
from bayes_update.data.signals import chirp

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import opensees_model as osm  # noqa: E402

# The only comparison with an independent code: a missing openseespy (or its
# system libraries) fails these tests unless BAYES_UPDATE_ALLOW_MISSING_REFERENCES=1.
_requires_opensees = require_reference(
    osm.IMPORT_ERROR,
    "openseespy (the independent code of this comparison)",
    "pip install openseespy (the dev extra); it needs the system libraries libblas3 and liblapack3",
)

FS = 1024.0
N_ELEMENTS = 20
SUBSTEPS = 4
PAPER = fe.Parameters()  # eta 3 MPa s, c 15 N s/mm, F 77 N, k_s 180 N/mm
LOW, HIGH = 0.005, 0.1  # chirp amplitudes [N]


def rel_l2(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


def model(rho_inf=0.9, substeps=SUBSTEPS):
    # OpenSees' Path series interpolates the force linearly between samples
    return fe.BeamModel(
        n_elements=N_ELEMENTS, substeps=substeps, rho_inf=rho_inf, formulation="linear", input_interpolation="linear"
    )


# (An earlier fe accepted a Newton predictor already within its tolerance,
# which is set by F, not by the shaker force; at rho_inf = 0.01 such steps
# added up to 1.7e-4 of the 0.005 N response.  fe now always takes one
# correction; the rho_inf = 0.01 cases below guard that.)


# ----------------------------------------------------------------- frequencies
@pytest.mark.parametrize("params", [fe.Parameters(eta=0.0, c=0.0, F=0.0, k_s=0.0), PAPER], ids=["unloaded", "paper"])
def test_frequencies_agree(params):
    # Same discrete eigenproblem (same element, mass, boundaries, spring): the
    # only differences are round-off and the static Newton tolerances (~2e-9 of
    # F; d ln f1 / d ln P ~ -0.7), so 1e-7 is generous and 1e-4 far too loose.
    m = model()
    ours = m.modal_analysis(params, n_modes=3).frequencies_hz
    theirs = osm.opensees_frequencies(m, params, n_modes=3)
    np.testing.assert_allclose(theirs, ours, rtol=1e-7)
    if params.F > 0:  # preloaded: the first mode near 30 Hz (docs/design.md: 29.84 Hz at 40 elements)
        assert 29.8 < ours[0] < 30.1


# ----------------------------------------------------------- linear transient
@pytest.mark.parametrize("rho_inf", [0.9, 0.01])
def test_linear_transient_identical_without_viscosity(rho_inf):
    # 5e-5 N: geometric nonlinearity ~1e-8 relative; eta = 0 removes the one
    # modelling difference.  The two codes then integrate the same linear system
    # with the same scheme: agreement to the Newton tolerance.  1 s of the chirp
    # (through the first resonance near 30 Hz).
    params = fe.Parameters(eta=0.0)
    m = model(rho_inf)
    force = chirp(5e-5)[:1024]
    ours = m.simulate(params, force, FS).sensor_velocity
    theirs = osm.run_opensees_transient(m, params, force, FS)
    assert rel_l2(ours, theirs) < 1e-6  # measured 3e-9 (rho_inf 0.9)


# ----------------------------------------------------- chirps, both levels
_RUNS = {}


def compare(amplitude, rho_inf, substeps=SUBSTEPS, params=PAPER):
    """fe and OpenSees on the chirp, plus the predicted viscosity-model difference."""
    key = (amplitude, rho_inf, substeps, params)
    if key not in _RUNS:
        m = model(rho_inf, substeps)
        force = chirp(amplitude)
        ours = m.simulate(params, force, FS).sensor_velocity
        theirs, states = osm.run_opensees_transient(m, params, force, FS, record_states=True)
        predicted = osm.kelvin_voigt_perturbation(m, params, states, FS)
        _RUNS[key] = (ours, theirs, predicted)
    return _RUNS[key]


def test_independent_element_has_fe_forces():
    """The numpy element of the prediction (textbook corotational formulas) and
    fe's internal force agree at a random state (all dofs, viscosity included):
    measured 9e-16 of the largest force; the tangent against central
    differences of that force, 3e-5 (the rates' dependence on u, left out)."""
    from fe import _kernels as K

    m = model()
    beam = osm._CorotationalBeam(m, PAPER)
    rng = np.random.default_rng(0)
    u, v = 1e-3 * rng.standard_normal(beam.n), 1e-2 * rng.standard_normal(beam.n)
    u[:3] = 0.0
    u[-2:] = 0.0
    a = m._arrays(m.describe(PAPER), PAPER)
    ours = np.empty(beam.n)
    K.internal_force(a["elements"], a["discrete"], u, v, ours)
    theirs = beam.internal_force(u, v)
    assert np.max(np.abs(ours - theirs)) < 1e-12 * np.max(np.abs(theirs))
    k_t, _ = beam.tangents(u, v)
    h = 1e-7
    fd = np.column_stack(
        [(beam.internal_force(u + h * e, v) - beam.internal_force(u - h * e, v)) / (2 * h) for e in np.eye(beam.n)]
    )[np.ix_(beam.free, beam.free)]
    assert np.max(np.abs(k_t - fd)) < 2e-4 * np.max(np.abs(k_t))


@pytest.mark.parametrize("rho_inf", [pytest.param(0.9, marks=pytest.mark.slow), 0.01])  # the budget
def test_low_level_chirp_agrees(rho_inf):
    ours, theirs, predicted = compare(LOW, rho_inf)
    # the codes agree far inside the 0.5 %: measured 5.55e-5 (rho 0.9),
    # 5.52e-5 (rho 0.01)
    assert rel_l2(ours, theirs) < 5e-4
    # and the difference is the viscosity model's linear part (2 P/EA more modal
    # damping in fe), which the independent prediction accounts for: it removes
    # 98.8 % of it at rho 0.9 (5.55e-5 -> 6.6e-7) and 99.6 % at rho 0.01
    # (5.52e-5 -> 2.0e-7); at least 90 % required
    assert rel_l2(ours, theirs + predicted) < 0.1 * rel_l2(ours, theirs)


@pytest.mark.parametrize("rho_inf", [0.9, 0.01])
def test_low_level_difference_is_the_viscosity_model(rho_inf):
    # Remove the predicted viscosity difference: what is left is the integrator's
    # nonlinear difference (scales as amplitude^2 and dt^2; 1.4e-5 at 0.005 N even
    # without viscosity, when the response is 1.5x larger) plus Newton tolerances.
    ours, theirs, predicted = compare(LOW, rho_inf)
    assert rel_l2(ours, theirs + predicted) < 3e-5  # measured 6.6e-7 (rho 0.9), 2.0e-7 (rho 0.01)


def test_high_level_without_viscosity_differs_only_by_the_time_step():
    # eta = 0: the only difference left is (2), O(alpha_f dt^2) in the nonlinear
    # terms.  Halving dt must divide it by 4 (measured 1.59e-3 -> 4.0e-4 -> 1.0e-4
    # for 2, 4, 8 substeps); a modelling difference (element, load, boundary)
    # would not vanish.
    params = fe.Parameters(eta=0.0)
    force = chirp(HIGH)
    diff = {}
    for substeps in (2, 4):
        m = model(0.9, substeps)
        ours = m.simulate(params, force, FS).sensor_velocity
        diff[substeps] = rel_l2(ours, osm.run_opensees_transient(m, params, force, FS))
    assert 3.5 < diff[2] / diff[4] < 4.5
    assert diff[4] < 1e-3


def test_high_level_chirp_agrees_up_to_the_kelvin_voigt_nonlinearity():
    # With viscosity, fe's Kelvin-Voigt also damps the shortening rate, which
    # beta K_0 cannot: the codes differ by 0.84 % at 0.1 N (docs/design.md: ~0.6 % in the
    # planning prototype).  The independent first-order prediction from the
    # missing force accounts for it: the rest (measured 2.4e-4) is below the
    # integrator difference measured without viscosity at this step (4.0e-4,
    # previous test), hence 1e-3 (4x); it removes 97 % of the difference, at
    # least 90 % required.  (No band on the difference's size: it is whatever
    # the independent prediction says.)
    ours, theirs, predicted = compare(HIGH, 0.9)
    assert rel_l2(ours, theirs + predicted) < 1e-3
    assert rel_l2(ours, theirs + predicted) < 0.1 * rel_l2(ours, theirs)
