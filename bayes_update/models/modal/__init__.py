"""A modal superposition model of the contract (docs/models.md): :class:`ModalModel`.

Physics.  Mode m (frequency f_m [Hz], w_m = 2 pi f_m, damping ratio zeta_m [-])
has the generalised displacement q_m [m], driven by the measured force u [N]::

    q_m'' + 2 zeta_m w_m q_m' + w_m^2 q_m + f_nl,m(q_m, q_m') = b_m u(t),   b_m = 1 [1/kg]

(each mode scaled to a unit modal mass, so that b_m = 1), and sensor s measures::

    y_s = sum_m c_ms q_m^(p_s) + d_s r_s(t)

with p_s = 0, 1, 2 derivatives for a displacement [m], velocity [m/s] or
acceleration [m/s^2] sensor and real, dimensionless coefficients c_ms: a
proportionally damped structure's modes are real (its mode shapes need no
phase), so one real coefficient per mode and sensor holds its shape and
participation.  A structure whose damping couples its modes has complex
modes; this model then fits their real approximation.  The residual term
stands for the modes outside the band: r_s = u for a displacement (residual
flexibility of the modes above, d_s [m/N]) and for an acceleration (the mass
line of the modes below, d_s [1/kg]); r_s = u' for a velocity (residual
flexibility, d_s [m/N]).  Modes just above the band are not quasi-static:
``residual_modes=k`` in :meth:`ModalModel.from_modes` adds k modes above the
record's band, fitted to it and never updated (:mod:`.residual_modes`).  Every
mode starts from rest at the first sample.

Nonlinear elements, their coefficients parameters with the null value 0:
``k2`` x^2 [1/(m s^2)], ``k3`` x^3 [1/(m^2 s^2)] (quadratic and cubic
stiffness), ``c3`` x'^3 [s/m^2] (cubic damping), ``friction`` F tanh(x'/v0)
[m/s^2] (a smooth Coulomb friction: no stick stiffness, so its equivalent
damping falls with amplitude, unlike a joint's micro-slip), ``clearance`` kc (x - gap) for
x > gap, kc (x + gap) for x < -gap, 0 between [1/s^2] (a contact spring beyond
a symmetric gap, a backlash) and ``jenkins`` -kt z [1/s^2] (a Jenkins element: a
spring kt in series with a slider that slips when the spring's stretch x - z
reaches +-slip, z the slider's travel; the mode's linear stiffness holds kt, so
the element adds nothing while it sticks and takes kt away as it slips: a joint's
micro-slip, its frequency falling and its damping rising with amplitude, the
loop's area 4 kt slip (X - slip) a cycle of amplitude X) and ``iwan`` (an Iwan
element: four Jenkins sliders of kt / 4 each, slipping at a quarter, half, three
quarters and all of its slip: a slip spread over a range of levels), per unit modal mass;
the friction's v0 [m/s], the clearance's gap [m] and the Jenkins element's slip
[m] are constants the user gives (``Nonlinearity("friction", at="acc1",
v0=1e-3)``), not parameters (:meth:`ModalModel.coordinate_rms` gives their
scale: a coordinate's rms at each test's level).  An
element in a mode (``Nonlinearity("k3", 1)``) acts on that mode's coordinate,
x = q_m.  An element at a sensor (``Nonlinearity("k3", at="acc1")``) is a
joint at the point that sensor measures: x_j = sum_m c_mj q_m, the point's
displacement whatever the sensor's kind, and its force enters every mode's
equation times c_mj / c_md (an element between two sensors' points,
``Nonlinearity("k3", at="store", to="mid")``, acts on their relative displacement:
c_mj becomes c_m,store - c_m,mid), d the *driving point* (``driving_point=``: the
sensor where the force acts, whose coefficients c_md = phi_dm^2 x 1 kg are
positive, phi_dm the mass-normalised shape there).  Its coefficient is the joint's physical one per kg, numerically
in N/m^2, N/m^3, N s^3/m^3, N, N/m (:mod:`.joints` derives it).

The force between samples is linear (docs/models.md, "What the samples of
the force mean": a low-pass of sinc^2(f / fs); at about ten samples per
period of the highest mode, interpolate the force before passing it).  A
linear mode is advanced by its exact discretisation for that input; a mode
with an element by RK4 with substeps, the modes a joint couples together
(:mod:`.dynamics`).

Parameters: ``f<k>`` [Hz] and ``zeta<k>`` [-] of each updated mode (k
1-based), then ``<element>_<k>`` (``k3_1``) or ``<element>_at_<sensor>``
(``k3_at_acc1``).  Build a model from known
constants (:class:`ModalModel`), from modes and a record
(:meth:`ModalModel.from_modes`: the output coefficients and residual terms by
least squares, :mod:`.fit`) or from a data set (:meth:`ModalModel.from_dataset`:
the modes the first look at its linear test finds).  Modules: :mod:`.spec`
(the checks and the declared parameters), :mod:`.dynamics`, :mod:`.fit`, :mod:`.residual_modes`,
:mod:`.joints` (elements at a point), :mod:`.signature` (the modes' level dependence, model against
records: the discrepancy workflow's diagnostics), :mod:`.model`, and the compiled loops in ``_kernels``.
"""

from .model import ModalModel
from .spec import ELEMENTS, KINDS, Nonlinearity

__all__ = ["ELEMENTS", "KINDS", "ModalModel", "Nonlinearity"]
