"""volterra on records nobody tuned it for (issue 23): the zeroth-order term h0,
sensor offsets, the averaged H1 and its band, the bounded pole refinement and
its errors.

Systems and constants of this module only (no other test uses them):

* Wiener system at fs = 610 Hz: a second-order discrete filter whose poles are
  the Kautz pole (47 Hz, zeta 0.035; numerator 1 - 0.3 z^-1, so it is in the
  span of J = 2), then y = x + a2 x^2 + a3 x^3 (a2 = 0.45, a3 = 0.17), white
  Gaussian input, 40 dB output noise.  Exact kernels (symmetric, no 1/n!, as
  in test_volterra_fit.py): H1 = G, H2 = a2 G(f1) G(f2), H3 = a3 G G G.
* Duffing oscillator m = 0.037 kg, fn = 41.5 Hz, zeta = 0.018, fs = 1187.5 Hz,
  chirp 20 -> 60 Hz in 3 s then 2 s of free decay, y3/y1 = 5 %, 40 dB noise.
* Linear oscillator fn = 73.5 Hz, zeta = 0.027 at fs = 610 Hz, driven by
  band-limited Gaussian noise (4th-order Butterworth band), 40 dB noise.

The pole tolerances come from what J1 = 2 needs (a pole off by a quarter of
the half-power half-width costs 13-17 % of H1, docs/kautz_basis_study.md); the kernel
tolerances are the issue's targets.  Measured values are in the comments.
"""

import math
import pathlib
import sys

import numpy as np
import pytest
from scipy.signal import butter, lfilter, sosfilt
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from test_volterra_reference import Oscillator, kautz_ref_pole  # noqa: E402

from volterra import (  # noqa: E402
    KautzBasis,
    KautzPole,
    PoleEstimationError,
    VolterraProjector,
    excited_band,
    fit_volterra,
    refine_bounds,
    refine_pole,
)

W_FS, W_FN, W_ZETA = 610.0, 47.0, 0.035
W_NUM = np.array([1.0, -0.3])
A2, A3 = 0.45, 0.17
W_N = 1 << 14


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    # hundreds of small fits: BLAS threads only contend on a shared machine
    with threadpool_limits(1):
        yield


def add_noise(y, rng, snr_db=40.0):
    return y + np.std(y) * 10 ** (-snr_db / 20) * rng.standard_normal(y.size)


def rel_err(a, b):
    return float(np.max(np.abs(a / b - 1)))


# ------------------------------------------------------------ Wiener system
def wiener_den():
    Z = kautz_ref_pole(W_FN, W_ZETA, W_FS)  # independent of the package
    return np.array([1.0, -2 * Z.real, abs(Z) ** 2])


def G(f):
    """Frequency response of the Wiener system's linear filter."""
    e = np.exp(-2j * np.pi * np.asarray(f, float) / W_FS)
    den = wiener_den()
    return (W_NUM[0] + W_NUM[1] * e) / (den[0] + den[1] * e + den[2] * e * e)


def wiener_record(seed, x_rms):
    """White Gaussian u (u[0] = 0: at rest) scaled so that x has rms ``x_rms``; 40 dB noise."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(W_N)
    u[0] = 0.0
    x = lfilter(W_NUM, wiener_den(), u)
    s = x_rms / np.std(x)
    u, x = s * u, s * x
    return u, add_noise(x + A2 * x**2 + A3 * x**3, rng)


D = W_ZETA * W_FN  # half-power half-width [Hz]
F1 = np.array([20.0, W_FN - D, W_FN, W_FN + D, 80.0])
PAIRS_DIAG = np.array([F1, -F1])  # (f, -f)
PAIRS_OFF = np.array([[W_FN - D, W_FN + D], [W_FN, 20.0], [W_FN + D, -W_FN + 2 * D], [80.0, -30.0], [W_FN, W_FN]]).T
# sums 141, 141, 72.1, -11.5, -53.6 Hz: at least 4 half-widths from +-fn (the ridge)
TRIPLES = np.array(
    [
        [W_FN, W_FN, W_FN],
        [W_FN - D, W_FN, W_FN + D],
        [W_FN, W_FN + D, -W_FN / 2],
        [20.0, W_FN, -W_FN - 26.0 - 6 * D],
        [W_FN, -W_FN, -W_FN - 4 * D],
    ]
).T


def kernel_errors(model):
    """Largest relative errors of H1, H2 at (f, -f), H2 off the diagonal, H3 against the exact kernels."""
    return (
        rel_err(model.H1(F1), G(F1)),
        rel_err(model.H2(*PAIRS_DIAG), A2 * G(PAIRS_DIAG[0]) * G(PAIRS_DIAG[1])),
        rel_err(model.H2(*PAIRS_OFF), A2 * G(PAIRS_OFF[0]) * G(PAIRS_OFF[1])),
        rel_err(model.H3(*TRIPLES), A3 * G(TRIPLES[0]) * G(TRIPLES[1]) * G(TRIPLES[2])),
    )


@pytest.fixture(scope="module")
def wiener():
    # rms of y2 = a2 sqrt(3) x_rms^2 and y3 = a3 sqrt(15) x_rms^3 against y1 = x_rms:
    u_low, y_low = wiener_record(2302, x_rms=0.1)  # low level: y2 7.8 %, y3 0.66 % of y1
    u, y = wiener_record(2301, x_rms=1.0)  # y2 78 %, y3 66 % of y1
    basis = KautzBasis.from_data(u_low, y_low, W_FS, n_functions=(2, 2, 2))
    return dict(u_low=u_low, y_low=y_low, u=u, y=y, basis=basis, model=fit_volterra(u, y, basis))


def test_h0_is_an_unpenalised_constant_regressor(wiener):
    """fit_volterra with h0 against numpy's least squares with a column of ones
    (measured: coefficients, h0 and standard errors agree to 3e-14; tolerances
    are round-off with a wide margin); the ridge does not shrink h0; the
    projector gives the same answer; fit_h0=False is the problem without it."""
    u, basis = wiener["u"][:4000], wiener["basis"]
    rng = np.random.default_rng(23)
    Gm = basis.regressors(u)
    y = Gm @ rng.standard_normal(basis.n_params) + 0.7 + 0.2 * rng.standard_normal(u.size)
    X = np.column_stack([Gm, np.ones(u.size)])
    ref, rss = np.linalg.lstsq(X, y, rcond=None)[:2]
    model = fit_volterra(u, y, basis)
    assert np.allclose(model.coefficients, ref[:-1], rtol=1e-9, atol=1e-12)
    assert model.h0 == pytest.approx(ref[-1], rel=1e-9)
    sigma2 = rss[0] / (u.size - X.shape[1])
    cov = np.linalg.inv(X.T @ X) * sigma2
    assert model.info.h0_stderr == pytest.approx(math.sqrt(cov[-1, -1]), rel=1e-6)
    assert np.allclose(model.info.stderr, np.sqrt(np.diag(cov))[:-1], rtol=1e-6)
    # ridge on the column-normalised kernel coefficients only (h0 free)
    colnorm = np.linalg.norm(Gm, axis=0)
    lam = 0.1
    aug = np.vstack([X, np.column_stack([np.sqrt(lam) * np.diag(colnorm), np.zeros(basis.n_params)])])
    ref_r = np.linalg.lstsq(aug, np.concatenate([y, np.zeros(basis.n_params)]), rcond=None)[0]
    ridged = fit_volterra(u, y, basis, ridge=lam)
    assert np.allclose(ridged.coefficients, ref_r[:-1], rtol=1e-8, atol=1e-12)
    assert ridged.h0 == pytest.approx(ref_r[-1], rel=1e-9)
    # the projector solves the same problem
    proj = VolterraProjector(u, basis, ridge=lam)
    assert proj.h0(y) == pytest.approx(ridged.h0, rel=1e-9)
    comps = proj.components(y, include_h0=True)
    fitted = ridged.components(u, include_h0=True)
    assert sorted(comps) == [0, 1, 2, 3] and len(fitted) == 4
    for n in (0, 1, 2, 3):
        assert np.allclose(comps[n], fitted[n], rtol=1e-9, atol=1e-12 * np.abs(y).max())
    assert sorted(proj.components(y)) == [1, 2, 3]  # default: no key 0
    assert np.allclose(ridged.predict(u), sum(fitted))
    assert proj.model(y).h0 == pytest.approx(ridged.h0, rel=1e-9)
    assert "h0 = " in model.summary() and "||y0||/||y||" in model.summary()
    # without h0: the plain least-squares problem
    plain = fit_volterra(u, y, basis, fit_h0=False)
    assert plain.h0 == 0.0 and np.isnan(plain.info.h0_stderr)
    assert np.allclose(plain.coefficients, np.linalg.lstsq(Gm, y, rcond=None)[0], rtol=1e-8, atol=1e-12)


def test_wiener_pole_from_low_level_record(wiener):
    """from_data with its defaults on a low-level record whose output has a mean
    (a2 E[x^2]).  Measured: frequency 1e-6 relative (3e-5 zeta fn), damping
    0.057 %; tolerances 0.05 zeta fn and 1 % (J1 = 2 needs ~0.1 zeta fn)."""
    p = wiener["basis"].pole(1)
    assert abs(p.freq_hz - W_FN) < 0.05 * D
    assert p.damping_ratio == pytest.approx(W_ZETA, rel=0.01)


def test_wiener_kernels_with_the_estimated_pole(wiener):
    """Measured with the from_data pole: H1 0.050 %, H2(f, -f) 0.13 %, H2 off the
    diagonal 0.11 %, H3 off the ridge 0.11 % (targets 3 / 5 / 5 / 10 %).  h0 stays
    ~0: the mean a2 E[x^2] = 0.45 of the output belongs to y2 (measured h0 -4.6e-5)."""
    e1, e2d, e2o, e3 = kernel_errors(wiener["model"])
    print(
        f"Wiener: H1 {100 * e1:.3f} %, H2(f,-f) {100 * e2d:.3f} %, H2 off {100 * e2o:.3f} %, "
        f"H3 {100 * e3:.3f} %, h0 {wiener['model'].h0:.2e}"
    )
    assert e1 < 0.03 and e2d < 0.05 and e2o < 0.05 and e3 < 0.10
    assert abs(wiener["model"].h0) < 0.01 * A2  # a2 E[x^2] = a2 at x_rms = 1


def test_output_offset_changes_only_h0(wiener):
    """A sensor offset of 10 % of the output's rms lies in the span of the constant
    regressor and is removed before pole estimation: pole and kernel coefficients
    are the same to round-off (measured 1e-14 / 2e-16) and h0 moves by the offset."""
    u, y, basis = wiener["u"], wiener["y"], wiener["basis"]
    c = 0.1 * np.std(y)
    pole = KautzBasis.from_data(wiener["u_low"], wiener["y_low"] + c, W_FS).pole(1)
    assert pole.freq_hz == pytest.approx(basis.pole(1).freq_hz, rel=1e-9)
    assert pole.damping_ratio == pytest.approx(basis.pole(1).damping_ratio, rel=1e-9)
    shifted = fit_volterra(u, y + c, basis)
    ref = wiener["model"]
    assert np.abs(shifted.coefficients - ref.coefficients).max() < 1e-9 * np.abs(ref.coefficients).max()
    assert shifted.h0 - ref.h0 == pytest.approx(c, rel=1e-9)


def test_input_offset_larger_than_the_input_rms(wiener):
    """An input sensor offset of 1.5 x the input's rms.  The pole (means removed)
    is the same to round-off (measured: identical).  With input_offset="mean"
    the kernels are those of the clean record within 1 %: measured H1 0.32 %,
    H2 0.40 %, H3 3e-5, which is the clean record's own sample mean
    (-0.0074 rms) removed with the offset: x shifts by d = -G(0) mean(u) and
    the kernels by 2 a2 d (H1) and 3 a3 d / a2 (H2), predicted 0.320 % and
    0.402 %.  Without it the kernels are those of the shifted operating point:
    measured H1 38 %, H2 81 % off."""
    u, y, basis = wiener["u"], wiener["y"], wiener["basis"]
    c = 1.5 * np.std(u)
    pole = KautzBasis.from_data(wiener["u_low"] + c, wiener["y_low"], W_FS).pole(1)
    assert pole.freq_hz == pytest.approx(basis.pole(1).freq_hz, rel=1e-9)
    assert pole.damping_ratio == pytest.approx(basis.pole(1).damping_ratio, rel=1e-9)
    model = fit_volterra(u + c, y, basis, input_offset="mean")
    assert model.input_offset == pytest.approx(c + u.mean(), rel=1e-12)
    clean = wiener["model"]
    d1 = rel_err(model.H1(F1), clean.H1(F1))
    d2 = rel_err(model.H2(*PAIRS_OFF), clean.H2(*PAIRS_OFF))
    d3 = rel_err(model.H3(*TRIPLES), clean.H3(*TRIPLES))
    print(f"input offset: kernels off the clean fit by H1 {100 * d1:.3f} %, H2 {100 * d2:.3f} %, H3 {d3:.1e}")
    assert d1 < 0.01 and d2 < 0.01 and d3 < 0.01
    d = -np.real(G(0.0)) * u.mean()
    assert d1 == pytest.approx(2 * A2 * d + 3 * A3 * d * d, abs=5e-4)
    assert d2 == pytest.approx(3 * A3 * d / A2, abs=5e-4)
    e1, e2d, e2o, e3 = kernel_errors(model)
    assert e1 < 0.03 and e2d < 0.05 and e2o < 0.05 and e3 < 0.10
    e1_plain, _, e2o_plain, _ = kernel_errors(fit_volterra(u + c, y, basis))
    assert e1_plain > 0.1 and e2o_plain > 0.1


# ------------------------------------------------------------ Duffing on a band-limited chirp
DU_FS, DU_M, DU_FN, DU_ZETA = 1187.5, 0.037, 41.5, 0.018


def band_chirp(amp):
    """Linear chirp 20 -> 60 Hz in 3 s, then 2 s of free decay (starts at rest)."""
    t = np.arange(int(5.0 * DU_FS)) / DU_FS
    u = amp * np.sin(2 * np.pi * (20.0 * t + 40.0 * t**2 / (2 * 3.0)))
    u[t >= 3.0] = 0.0
    return u


def test_duffing_chirp_pole_over_20_noise_seeds():
    """from_data defaults, y3/y1 = 5 %, 40 dB.  Measured over the 20 seeds:
    frequency +0.119 ... +0.120 % (the best linear pole of a stiffening record),
    damping -0.13 ... -0.02 %; targets 1 % and 10 % every time."""
    u = band_chirp(1.0)
    r = Oscillator(fn=DU_FN, zeta=DU_ZETA, m=DU_M, k3=1.0).simulate(u, DU_FS)
    k3 = 0.05 / (np.linalg.norm(r["x3"]) / np.linalg.norm(r["x1"]))
    x = Oscillator(fn=DU_FN, zeta=DU_ZETA, m=DU_M, k3=k3).simulate(u, DU_FS)["x"]
    ef, ez = [], []
    for seed in range(20):
        y = add_noise(x, np.random.default_rng(4100 + seed))
        p = KautzBasis.from_data(u, y, DU_FS).pole(1)
        ef.append(p.freq_hz / DU_FN - 1)
        ez.append(p.damping_ratio / DU_ZETA - 1)
    ef, ez = np.array(ef), np.array(ez)
    print(
        f"Duffing chirp: frequency {100 * ef.min():+.3f} ... {100 * ef.max():+.3f} %, "
        f"damping {100 * ez.min():+.2f} ... {100 * ez.max():+.2f} %"
    )
    assert np.all(np.abs(ef) < 0.01) and np.all(np.abs(ez) < 0.10)


# ------------------------------------------------------------ band-limited Gaussian noise
BN_FS, BN_FN, BN_ZETA = 610.0, 73.5, 0.027


@pytest.mark.parametrize("band", [(40.0, 130.0), (2.0, 290.0)])
def test_band_limited_noise_pole_over_20_seeds(band):
    """A resonant system (displacement output) driven by Gaussian noise filtered to
    ``band``; (2, 290) Hz is nearly white up to 0.48 fs, so the excited band
    restricts nothing and the coherence does.  Measured over the 20 seeds:
    frequency -0.037 ... -0.032 % / -0.055 ... -0.049 %, damping -0.11 ... +0.07 %
    / -0.18 ... +0.16 %; targets 1 % and 10 % every time."""
    osc = Oscillator(fn=BN_FN, zeta=BN_ZETA, m=0.01)
    sos = butter(4, band, "bandpass", fs=BN_FS, output="sos")
    ef, ez = [], []
    for seed in range(20):
        rng = np.random.default_rng(7300 + seed)
        u = sosfilt(sos, rng.standard_normal(8192))
        u[0] = 0.0
        u /= np.std(u)
        y = add_noise(osc.simulate(u, BN_FS)["x"], rng)
        p = KautzBasis.from_data(u, y, BN_FS).pole(1)
        ef.append(p.freq_hz / BN_FN - 1)
        ez.append(p.damping_ratio / BN_ZETA - 1)
    ef, ez = np.array(ef), np.array(ez)
    print(
        f"noise {band} Hz: frequency {100 * ef.min():+.3f} ... {100 * ef.max():+.3f} %, "
        f"damping {100 * ez.min():+.2f} ... {100 * ez.max():+.2f} %"
    )
    assert np.all(np.abs(ef) < 0.01) and np.all(np.abs(ez) < 0.10)


def test_excited_band_ignores_an_input_offset():
    """The chirp's sweep band (measured (19.80, 64.82) Hz: Welch's Hann segments alone read
    (21.61, 64.82), tapering the sweep's first 0.3 s, which the whole record's periodogram
    restores, its running mean over Welch's main lobe spreading the abrupt start 0.2 Hz below
    20 Hz (the running median read 20.20); the abrupt stop spreads above 60 Hz) is exactly the
    same with an offset of twice the rms; white noise excites everything above the two lowest
    lines."""
    u = band_chirp(1.0)
    lo, hi = excited_band(u, DU_FS)
    print(f"excited band of the chirp: ({lo:.2f}, {hi:.2f}) Hz")
    assert 19.5 < lo < 23.0 and 60.0 < hi < 66.0
    assert excited_band(u + 2 * np.std(u), DU_FS) == (lo, hi)
    noise = np.random.default_rng(4).standard_normal(8192)
    lo_n, hi_n = excited_band(noise, W_FS)
    assert lo_n < 1.0 and hi_n == W_FS / 2


# ------------------------------------------------------------ errors, never a bad pole
def test_pure_noise_output_raises(wiener):
    y = np.random.default_rng(5).standard_normal(W_N)
    with pytest.raises(PoleEstimationError, match="noise"):
        KautzBasis.from_data(wiener["u_low"], y, W_FS)


def test_a_slow_drift_does_not_move_the_pole(wiener):
    """An output dominated by a slow drift (a random walk of 10 x the response's
    rms).  The previous estimator's Welch H1 peak moved to 0.35 Hz and it raised;
    the local polynomial method takes the drift in its transient term, and
    from_data finds the pole (measured 46.9993 Hz, zeta 0.03518; the targets of
    the clean record's test, 0.05 zeta fn, and 10 %).  refine_pole (the one-pole
    tool, a time-domain fit) refined from the true pole still leaves 99 % of the
    record unexplained and says to check for a drift."""
    rw = np.cumsum(np.random.default_rng(5).standard_normal(W_N))
    y = wiener["y_low"] + 10 * np.std(wiener["y_low"]) * rw / np.std(rw)
    p = KautzBasis.from_data(wiener["u_low"], y, W_FS).pole(1)
    assert abs(p.freq_hz - W_FN) < 0.05 * D and p.damping_ratio == pytest.approx(W_ZETA, rel=0.1)
    with pytest.raises(PoleEstimationError, match="unexplained.*drift"):
        refine_pole(wiener["u_low"], y, KautzPole.from_modal(W_FN, W_ZETA, W_FS))


def test_refine_pole_stays_in_its_neighbourhood(wiener):
    u, y = wiener["u_low"], wiener["y_low"]
    start = KautzPole.from_modal(W_FN, W_ZETA, W_FS)
    (f_lo, f_hi), (z_lo, z_hi) = refine_bounds(start)
    s = max(4 * W_ZETA, 0.05)
    assert (f_lo, f_hi) == pytest.approx((W_FN / (1 + s), W_FN * (1 + s)))
    assert (z_lo, z_hi) == pytest.approx((W_ZETA / 10, W_ZETA * 10))
    with pytest.raises(PoleEstimationError, match="DC"):
        refine_pole(u, y, KautzPole.from_modal(0.1, 0.5, W_FS))
    with pytest.raises(PoleEstimationError, match="Nyquist"):
        refine_pole(u, y, KautzPole.from_modal(0.47 * W_FS, 0.02, W_FS))
    with pytest.raises(PoleEstimationError, match="frequency ran to the lower edge"):
        refine_pole(u, y, KautzPole.from_modal(1.3 * W_FN, W_ZETA, W_FS))
    with pytest.raises(PoleEstimationError, match="damping ratio ran to the upper edge"):
        refine_pole(u, y, KautzPole.from_modal(W_FN, W_ZETA / 30, W_FS))


def test_record_that_a_linear_fit_cannot_explain_raises():
    """0 dB output noise on the band-limited noise record: refined from the true
    pole, the linear fit leaves 71 % of ||y|| unexplained (measured), more than
    the default 50 %, and refine_pole raises.  from_data raised too before (its
    Welch H1 peak was a noise line at 163 Hz); it now reads the mode through the
    noise, its peak clear of it on the local polynomial method's FRF (measured
    73.41 Hz, zeta 0.0282: within the 1 % and 10 % of the noise records above)."""
    osc = Oscillator(fn=BN_FN, zeta=BN_ZETA, m=0.01)
    rng = np.random.default_rng(7399)
    u = sosfilt(butter(4, (40.0, 130.0), "bandpass", fs=BN_FS, output="sos"), rng.standard_normal(8192))
    u[0] = 0.0
    y = add_noise(osc.simulate(u, BN_FS)["x"], rng, snr_db=0.0)
    with pytest.raises(PoleEstimationError, match="unexplained"):
        refine_pole(u, y, KautzPole.from_modal(BN_FN, BN_ZETA, BN_FS))
    p = KautzBasis.from_data(u, y, BN_FS).pole(1)
    assert abs(p.freq_hz / BN_FN - 1) < 0.01 and abs(p.damping_ratio / BN_ZETA - 1) < 0.10
