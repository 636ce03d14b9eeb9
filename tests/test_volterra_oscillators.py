"""Oscillators integrated independently (RK4, T/16 substeps, linearly
interpolated input, sampled at 1024 Hz; see test_volterra_reference.py):

* test 4: Duffing H1 against 1/(k - m w^2 + j c w) sinc^2(f T) near resonance;
  identified y3 against the order-3 term of the perturbation hierarchy;
* test 5: quadratic oscillator H2 at (f, -f) against harmonic probing;
* test 6: limits - H3 near f1 + f2 + f3 = fn (and H2 near f1 + f2 = fn) are not
  representable in a Kautz basis;
* test 7: symmetry - y2 negligible for an odd system, not with a quadratic term;
* pole selection from data (H1 FRF peak / half-power width, residual refinement).

Setup as in docs/kautz_basis_study.md: m = 0.02 kg, fn = 30 Hz,
zeta = 0.01, chirp 20 -> 50 Hz for 2 s then 2 s free decay, 0.1 N at the top
level, levels 1/3, 2/3, 1 stacked, 40 dB output noise (seeded).
"""

import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from test_volterra_reference import Oscillator, chirp, sinc2  # noqa: E402

from volterra import KautzBasis, KautzPole, fit_volterra, pole_from_frf, refine_pole  # noqa: E402

FS = 1024.0
FN, ZETA = 30.0, 0.01
D = ZETA * FN  # half-power half-width [Hz]
U0 = chirp(0.1)  # top level [N]
LEVELS = (1 / 3, 2 / 3, 1.0)
F_RES = np.linspace(FN - 3 * D, FN + 3 * D, 41)  # "near resonance": fn (1 +- 3 zeta)


def add_noise(y, rng, snr_db=40.0):
    return y + np.std(y) * 10 ** (-snr_db / 20) * rng.standard_normal(y.size)


def nonlinear_coefficient(kind, share):
    """k2 or k3 giving ||x2||/||x1|| or ||x3||/||x1|| = share at the top chirp
    (the hierarchy term is linear in the coefficient)."""
    if kind == "k3":
        r = Oscillator(fn=FN, zeta=ZETA, k3=1.0).simulate(U0, FS)
        return share / (np.linalg.norm(r["x3"]) / np.linalg.norm(r["x1"]))
    r = Oscillator(fn=FN, zeta=ZETA, k2=1.0).simulate(U0, FS)
    return share / (np.linalg.norm(r["x2"]) / np.linalg.norm(r["x1"]))


def h1_error(model, osc):
    ref = osc.H1(F_RES) * sinc2(F_RES, FS)
    return np.max(np.abs(model.H1(F_RES) - ref) / np.abs(ref))


def h1_gain_error(model, osc):
    """Re(mean of H1 / reference) - 1 near resonance: the gain error, where the
    sinc^2 factor (1 - 0.28 % at 30 Hz, flat over F_RES) shows whole, while the
    noise's and the basis's errors vary along F_RES and partly cancel."""
    ref = osc.H1(F_RES) * sinc2(F_RES, FS)
    return float(np.mean(model.H1(F_RES) / ref).real - 1)


@pytest.fixture(scope="module")
def duffing():
    osc = Oscillator(fn=FN, zeta=ZETA, k3=nonlinear_coefficient("k3", 0.10))
    rng = np.random.default_rng(1001)
    recs = [osc.simulate(a * U0, FS) for a in LEVELS]
    ys = [add_noise(r["x"], rng) for r in recs]
    low_u = np.sqrt(0.03) * U0  # y3/y1 = 0.3 %
    low = osc.simulate(low_u, FS)
    return dict(
        osc=osc,
        recs=recs,
        us=[a * U0 for a in LEVELS],
        ys=ys,
        low_u=low_u,
        low=low,
        low_y=add_noise(low["x"], rng),
        low_v=add_noise(low["v"], rng),
    )


@pytest.fixture(scope="module")
def quadratic():
    osc = Oscillator(fn=FN, zeta=ZETA, k2=nonlinear_coefficient("k2", 0.03))
    rng = np.random.default_rng(1002)
    recs = [osc.simulate(a * U0, FS) for a in LEVELS]
    return dict(osc=osc, recs=recs, us=[a * U0 for a in LEVELS], ys=[add_noise(r["x"], rng) for r in recs])


def default_basis(J=(2, 2, 6), feedthrough=False):
    """The numbers of this module were measured without the feed-through
    (today's Kautz functions); with it, see test_volterra_multimode.py."""
    return KautzBasis.from_modal(freq_hz=FN, damping_ratio=ZETA, fs=FS, n_functions=J, feedthrough=feedthrough)


# ------------------------------------------------------------ test 4
def test_duffing_shares_are_as_designed(duffing):
    top = duffing["recs"][-1]
    assert np.linalg.norm(top["x3"]) / np.linalg.norm(top["x1"]) == pytest.approx(0.10, rel=1e-9)
    low = duffing["low"]
    assert np.linalg.norm(low["x3"]) / np.linalg.norm(low["x1"]) == pytest.approx(0.003, rel=1e-6)


def test_h1_of_a_linear_record_carries_the_sinc2_factor(duffing):
    """The Duffing's noise-free linear part x1 (the hierarchy's first order): a
    linear system whose H1 lies in the J1 = 2 span.  Measured max error against
    H1 sinc^2(f T) 0.034 % (the feed-through T^2 / (6 m) and the basis); without
    the sinc^2 factor it would be 0.30 %.  Tolerance 0.1 %, 2.9x the measured."""
    model = fit_volterra(duffing["low_u"], duffing["low"]["x1"], default_basis((2,)))
    assert h1_error(model, duffing["osc"]) < 1e-3


# Measured on the seeded records below (max error near resonance / gain error):
# low level J = (2,) 0.271 % / +0.023 %, J = (2, 2, 6) 0.141 % / +0.093 %;
# without the sinc^2 factor in the reference the gain errors would be -0.259 %
# and -0.190 %.  The gain tolerances (0.10 % and 0.14 %, 4.3x and 1.5x the
# measured) are what makes a dropped sinc^2 factor fail; the max-error ones
# (0.40 % and 0.25 %, 1.5x and 1.8x) bound the rest.  (docs/verification.md: "0.14-0.27 %").
H1_LOW_TOLERANCE = {(2,): (4.0e-3, 1.0e-3), (2, 2, 6): (2.5e-3, 1.4e-3)}


@pytest.mark.parametrize("J", [(2,), (2, 2, 6)])
def test_duffing_h1_from_low_level_record(duffing, J):
    model = fit_volterra(duffing["low_u"], duffing["low_y"], default_basis(J))
    err = h1_error(model, duffing["osc"])
    gain = h1_gain_error(model, duffing["osc"])
    print(f"H1 low level, J = {J}: max error {100 * err:.3f} % near resonance, gain {100 * gain:+.3f} %")
    max_tol, gain_tol = H1_LOW_TOLERANCE[J]
    assert err < max_tol
    assert abs(gain) < gain_tol


@pytest.mark.parametrize("n_levels", [2, 3])
def test_duffing_h1_from_stacked_levels(duffing, n_levels):
    """Measured max error 0.233 % (2 levels) and 0.185 % (3); tolerance 0.35 %
    (1.5x / 1.9x).  The top level's cubic share (y3/y1 = 10 %) leaves a gain
    bias of +0.15 to +0.19 % in H1, the size of the sinc^2 factor, so this test
    checks the stacking, not the factor (the low-level tests above do)."""
    us, ys = duffing["us"][-n_levels:], duffing["ys"][-n_levels:]  # top level y3/y1 = 10 %
    model = fit_volterra(us, ys, default_basis())
    err = h1_error(model, duffing["osc"])
    print(f"H1 from {n_levels} stacked levels (y3/y1 up to 10 %): max error {100 * err:.3f} %")
    assert err < 3.5e-3


@pytest.mark.parametrize("stacked", [False, True])
def test_duffing_y3_against_perturbation_hierarchy(duffing, stacked):
    """Chirp at y3/y1 = 10 %.  (The identified y3 and the hierarchy's x3 are both
    homogeneous of degree 3 in u, so the relative error is the same at every level.)"""
    us, ys = (duffing["us"], duffing["ys"]) if stacked else (duffing["us"][-1:], duffing["ys"][-1:])
    model = fit_volterra(us, ys, default_basis())
    top = duffing["recs"][-1]
    y1, y2, y3 = model.components(U0)
    e3 = np.linalg.norm(y3 - top["x3"]) / np.linalg.norm(top["x3"])
    e1 = np.linalg.norm(y1 - top["x1"]) / np.linalg.norm(top["x1"])
    print(
        f"{'stacked' if stacked else 'top level only'}: ||y3 - x3||/||x3|| = {100 * e3:.1f} %, "
        f"||y1 - x1||/||x1|| = {100 * e1:.2f} %"
    )
    assert e3 < 0.15
    assert e1 < 0.02


# ------------------------------------------------------------ test 5
def test_quadratic_h2_at_f_minus_f(quadratic):
    osc = quadratic["osc"]
    model = fit_volterra(quadratic["us"], quadratic["ys"], default_basis())
    f = np.array([FN - D, FN, FN + D])
    ref = osc.H2(f, -f) * sinc2(f, FS) * sinc2(-f, FS)
    err = np.abs(model.H2(f, -f) - ref) / np.abs(ref)
    print("H2(f, -f) errors at fn - d, fn, fn + d:", np.round(100 * err, 2), "%")
    assert err.max() < 0.05


# ------------------------------------------------------------ test 6
RIDGE_TRIPLES = np.array(
    [[FN, FN, -FN], [FN + D, FN, -FN], [FN - D, FN + D, -FN], [FN - 2, FN + 2, -FN], [FN - 5, FN + 5, -FN]]
).T  # all sum to ~fn


def test_limit_h3_ridge_not_representable_even_by_best_projection():
    """Noise-free and data-free: the l2-optimal approximation in the Kautz basis of the
    exact order-3 kernel h3(n1,n2,n3) = -sum_t h(t) h(n1-t) h(n2-t) h(n3-t) (h in the span of
    J = 2, the discrete Duffing structure).  Its coefficients are C_ijm = -sum_t h(t) g_i g_j g_m,
    g_i(t) = sum_k h(k) psi_i(k + t); ||h3||^2 = sum_d R(d)^4 (R: autocorrelation of h).
    Along the ridge f1 + f2 + f3 = fn, away from the triple resonance peak, the best
    approximation misses H3 by ~75-90 % for every J3 up to 16, and the captured energy
    converges slowly."""
    from scipy.signal import fftconvolve

    L = 1 << 15
    b1 = KautzBasis.from_modal(FN, ZETA, FS, {1: 2}, feedthrough=False)
    w = np.array([1.0, 0.6])
    h = b1.impulse_responses(1, L) @ w
    Hd = lambda f: b1.frequency_response(1, f) @ w  # noqa: E731
    exact = lambda f1, f2, f3: -Hd(f1) * Hd(f2) * Hd(f3) * Hd(f1 + f2 + f3)  # noqa: E731
    R = fftconvolve(h, h[::-1])
    energy = np.sum(R**4)
    rows = []
    for J3 in (4, 6, 8, 12, 16):
        b3 = KautzBasis.from_modal(FN, ZETA, FS, {3: J3}, feedthrough=False)
        psi = b3.impulse_responses(3, L)
        g = np.stack([fftconvolve(psi[:, i], h[::-1])[L - 1 :] for i in range(J3)], axis=-1)
        C = -np.einsum("t,ti,tj,tm->ijm", h, g, g, g, optimize=True)
        P = [b3.frequency_response(3, f) for f in RIDGE_TRIPLES]
        H3 = np.einsum("pi,pj,pk,ijk->p", *P, C, optimize=True)
        err = np.abs(H3 / exact(*RIDGE_TRIPLES) - 1)
        rows.append((J3, np.sum(C**2) / energy, err))
        print(
            f"J3 = {J3:2d}: energy captured {100 * rows[-1][1]:.1f} %, H3 error on the ridge "
            f"(fn,fn,-fn) {100 * err[0]:.0f} %, (fn-2,fn+2,-fn) {100 * err[3]:.0f} %, "
            f"(fn-5,fn+5,-fn) {100 * err[4]:.0f} %"
        )
    for J3, captured, err in rows:
        assert captured < 0.99  # slow convergence: 77 % ... 97 %
        assert err[3] > 0.5 and err[4] > 0.5  # measured 73-88 %


def test_limit_h3_identified_from_duffing_record_is_not_the_true_kernel(duffing):
    """The fit matches y3 in time (test above) but its H3 on the ridge is far from
    harmonic probing: y3 of a fit is not a pointwise kernel estimate."""
    model = fit_volterra(duffing["us"], duffing["ys"], default_basis())
    ref = duffing["osc"].H3(*RIDGE_TRIPLES) * np.prod([sinc2(t, FS) for t in RIDGE_TRIPLES], axis=0)
    err = np.abs(model.H3(*RIDGE_TRIPLES) / ref - 1)
    print("identified H3 errors on the ridge:", np.round(100 * err), "%")
    assert err.min() > 0.3  # measured 63 % ... 4200 % (52 % with another seed)


def test_limit_h2_with_sum_on_resonance(quadratic):
    osc = quadratic["osc"]
    model = fit_volterra(quadratic["us"], quadratic["ys"], default_basis())
    pairs = np.array([[FN / 2, FN / 2], [FN / 2 - 1, FN / 2 + 1]]).T
    ref = osc.H2(*pairs) * sinc2(pairs[0], FS) * sinc2(pairs[1], FS)
    err = np.abs(model.H2(*pairs) / ref - 1)
    print("H2 errors with f1 + f2 = fn:", np.round(100 * err), "%")
    assert err.min() > 0.5  # measured ~100 %


# ------------------------------------------------------------ test 7
def test_symmetry_odd_system_has_negligible_y2(duffing):
    model = fit_volterra(duffing["us"], duffing["ys"], default_basis())
    y1, y2, y3 = model.components(U0)
    ratio = np.linalg.norm(y2) / np.linalg.norm(y3)
    print(f"Duffing: ||y2||/||y3|| = {ratio:.4f}")
    assert ratio < 0.05


def test_symmetry_quadratic_term_gives_y2():
    osc = Oscillator(fn=FN, zeta=ZETA, k2=0.5 * nonlinear_coefficient("k2", 0.03), k3=nonlinear_coefficient("k3", 0.10))
    rng = np.random.default_rng(1003)
    recs = [osc.simulate(a * U0, FS) for a in LEVELS]
    model = fit_volterra([a * U0 for a in LEVELS], [add_noise(r["x"], rng) for r in recs], default_basis())
    y1, y2, y3 = model.components(U0)
    top = recs[-1]
    ratio, true_ratio = (np.linalg.norm(y2) / np.linalg.norm(y3), np.linalg.norm(top["x2"]) / np.linalg.norm(top["x3"]))
    e2 = np.linalg.norm(y2 - top["x2"]) / np.linalg.norm(top["x2"])
    print(f"k2 + k3: ||y2||/||y3|| = {ratio:.3f} (hierarchy {true_ratio:.3f}), ||y2 - x2||/||x2|| = {100 * e2:.1f} %")
    assert ratio > 0.1
    assert ratio == pytest.approx(true_ratio, rel=0.25)
    assert e2 < 0.15


# ------------------------------------------------------------ pole selection
@pytest.mark.parametrize("output", ["x", "v"])
def test_pole_from_frf_and_refinement(output):
    osc = Oscillator(fn=33.3, zeta=0.02)  # off the FFT grid on purpose
    rng = np.random.default_rng(1004)
    u = 0.05 * U0
    y = add_noise(osc.simulate(u, FS)[output], rng)
    # the whole-record estimate (leakage free on this transient record); the default averages
    pole = pole_from_frf(u, y, FS, f_range=(20.0, 50.0), nperseg=u.size, window="boxcar")
    print(output, pole)
    assert pole.freq_hz == pytest.approx(33.3, abs=0.1 * 0.02 * 33.3)  # within 0.1 zeta fn
    assert pole.damping_ratio == pytest.approx(0.02, rel=0.1)
    refined = refine_pole(u, y, pole)
    print(output, "refined", refined)
    assert refined.freq_hz == pytest.approx(33.3, abs=0.05 * 0.02 * 33.3)
    assert refined.damping_ratio == pytest.approx(0.02, rel=0.05)
    if output == "x":
        # J1 = 2 with the refined pole: measured max error 0.086 % (0.39 % without
        # the sinc^2 factor in the reference); tolerance 0.2 %, 2.3x the measured
        model = fit_volterra(u, y, KautzBasis(refined, (2,), feedthrough=False))
        f = np.linspace(33.3 * (1 - 0.06), 33.3 * (1 + 0.06), 41)
        ref = osc.H1(f) * sinc2(f, FS)
        assert np.max(np.abs(model.H1(f) - ref) / np.abs(ref)) < 2e-3


def test_basis_from_low_level_duffing_data(duffing):
    basis = KautzBasis.from_data(duffing["low_u"], duffing["low_y"], FS, n_functions=(2, 2, 6), f_range=(20.0, 50.0))
    assert basis.pole(1).freq_hz == pytest.approx(FN, abs=0.1 * D)
    model = fit_volterra(duffing["us"], duffing["ys"], basis)
    assert h1_error(model, duffing["osc"]) < 4.5e-3  # measured 0.315 % (1.4x)


def test_pole_from_frf_bad_range():
    u = 0.05 * U0
    y = Oscillator().simulate(u, FS)["x"]
    whole = dict(nperseg=u.size, window="boxcar")
    with pytest.raises(ValueError, match="half-power points"):
        pole_from_frf(u, y, FS, f_range=(29.9, 30.1), **whole)
    with pytest.raises(ValueError, match="f_min < f_max"):
        pole_from_frf(u, y, FS, f_range=(40.0, 20.0), **whole)
    assert isinstance(pole_from_frf(u, y, FS), KautzPole)
