"""The generalized orthonormal basis (several modes, feed-through) and the
estimation of several modes from data.

Systems and constants of this module only (no other test uses them):

* a resonant filter sampled behind a zero-order hold: G(s) = w^2 / (s^2 + 2
  zeta w s + w^2), fn = 63.7 Hz, zeta = 0.027, fs = 517 Hz, discretised by
  scipy.signal.cont2discrete (numerator in z^-1, z^-2, no feed-through);
* a Wiener system on it, y = x + a2 x^2 + a3 x^3 (a2 = 0.37, a3 = 0.12);
* two independent resonators seen by two sensors (41.3 Hz / 0.031 and
  127.9 Hz / 0.022, fs = 517 Hz), driven by one white-noise input;
* a three-mass chain (tests/chain_reference.py: 1.3, 0.9, 0.7 kg; 9.1, 12,
  14 kN/m; Rayleigh damping 1.7 M + 1.5e-4 K; cubic spring 5e5 N/m^3 on mass
  1, 0.51 % of the response), periodic multisine 6-39 Hz (4 s period, seeded
  phases), accelerations of the three masses sampled at fs = 97.5 Hz = 2.5 x
  the top of the band, 40 dB noise and offsets on force and accelerations.

Every expected value comes from scipy or closed forms, never from the package.
"""

import pathlib
import sys

import numpy as np
import pytest
from scipy.signal import cont2discrete, lfilter
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from chain_reference import Chain, multisine, simulate  # noqa: E402
from test_volterra_reference import kautz_ref_impulse  # noqa: E402

from volterra import (  # noqa: E402
    KautzBasis,
    KautzPole,
    PoleEstimationError,
    RealPole,
    VolterraProjector,
    estimate_modes,
    fit_volterra,
    gobf_filter_rows,
    gobf_frequency_response,
    periodic_h1,
)

Z_FS, Z_FN, Z_ZETA = 517.0, 63.7, 0.027
A2, A3 = 0.37, 0.12


@pytest.fixture(scope="module", autouse=True)
def one_blas_thread():
    # small least-squares problems: BLAS threads only contend on a shared machine
    with threadpool_limits(1):
        yield


def zoh_resonator(fn, zeta, fs):
    """(num, den) in powers of z^-1 of w^2 / (s^2 + 2 zeta w s + w^2) behind a ZOH."""
    w = 2 * np.pi * fn
    num, den, _ = cont2discrete(([w * w], [1.0, 2 * zeta * w, w * w]), 1.0 / fs, method="zoh")
    return np.ravel(num), np.ravel(den)


def dtft(num, den, f, fs):
    e = np.exp(-2j * np.pi * np.asarray(f, float) / fs)
    return np.polyval(num[::-1], e) / np.polyval(den[::-1], e)


def true_pole(den, fs):
    """The discrete pole of a second-order denominator, from numpy's roots."""
    return KautzPole.from_z(np.roots(den)[0], fs)


def add_noise(x, rng, snr_db=40.0):
    return x + np.std(x, axis=0) * 10 ** (-snr_db / 20) * rng.standard_normal(x.shape)


# ------------------------------------------------------------ orthonormality
def _mixed_modes(fs):
    return [
        KautzPole.from_modal(11.9, 0.043, fs),
        KautzPole.from_modal(87.0, 0.012, fs),
        RealPole(0.83, fs),
        KautzPole.from_modal(203.0, 0.07, fs),
    ]


@pytest.mark.parametrize("feedthrough", [True, False])
def test_gram_matrix_is_identity_in_time_and_frequency(feedthrough):
    """Three pairs and a real pole, the sequence repeated twice (J = 4 per mode):
    impulse responses by recursive filtering over 2^15 samples, and (Parseval)
    the closed-form frequency responses on 2^15 lines."""
    fs = Z_FS
    basis = KautzBasis.from_modes(_mixed_modes(fs), (4,), feedthrough=feedthrough)
    assert basis.dim(1) == 2 * (3 * 2 + 1) + feedthrough
    n = 1 << 15
    psi = basis.impulse_responses(1, n)
    assert np.abs(psi.T @ psi - np.eye(basis.dim(1))).max() < 1e-10
    f = np.arange(n) * fs / n
    P = basis.frequency_response(1, f)
    gram = (P.conj().T @ P).real / n
    assert np.abs(gram - np.eye(basis.dim(1))).max() < 1e-10
    # the two code paths agree: DTFT of the filtered impulse responses
    assert np.abs(np.fft.fft(psi, axis=0) - P).max() < 1e-9


def test_one_mode_special_case_is_todays_kautz_basis():
    """feedthrough=False: exactly today's functions (the independent closed-form
    reference of test_volterra_reference.py); feedthrough=True: the input itself,
    then the same functions delayed by one sample."""
    fn, zeta, J, n = 44.4, 0.018, 6, 3000
    ref = kautz_ref_impulse(fn, zeta, Z_FS, J, n)
    old = KautzBasis.from_modal(fn, zeta, Z_FS, (J,), feedthrough=False).impulse_responses(1, n)
    assert np.abs(old - ref).max() < 1e-12
    new = KautzBasis.from_modal(fn, zeta, Z_FS, (J,)).impulse_responses(1, n)
    assert new.shape == (n, J + 1)
    assert new[0, 0] == 1.0 and not new[1:, 0].any() and not new[0, 1:].any()
    assert np.abs(new[1:, 1:] - ref[:-1]).max() < 1e-12


def test_feedthrough_per_order():
    """The feed-through on order 1 only: orders 2-3 keep today's functions."""
    pole = KautzPole.from_modal(44.4, 0.018, Z_FS)
    basis = KautzBasis(pole, (2, 2, 6), feedthrough=(1,))
    assert basis.feedthrough == (1,) and basis.has_feedthrough(1) and not basis.has_feedthrough(3)
    assert (basis.dim(1), basis.dim(2), basis.dim(3)) == (3, 2, 6)
    assert basis.n_params == 3 + 3 + 56
    assert basis.subset((2, 3)).feedthrough is False and basis.subset((1,)).feedthrough is True
    u = np.random.default_rng(77).standard_normal(700)
    rows = basis.filter(u)
    old = KautzBasis(pole, (2, 2, 6), feedthrough=False).filter(u)
    assert np.array_equal(rows[3], old[3]) and np.array_equal(rows[1][:, 0], u)
    assert basis != KautzBasis(pole, (2, 2, 6)) and "feed-through (1,)" in basis.describe()


# ------------------------------------------------------------ exact representation
def test_zoh_resonator_is_exact_with_the_feedthrough_only():
    """The issue's case: (b1 z^-1 + b2 z^-2) / D is outside today's span for every
    J1 (H1 off by percents), and inside the feed-through basis with 3 functions."""
    num, den = zoh_resonator(Z_FN, Z_ZETA, Z_FS)
    assert abs(num[0]) < 1e-12 * np.abs(num).max()  # strictly proper
    rng = np.random.default_rng(3141)
    u = rng.standard_normal(6000)
    y = lfilter(num, den, u)
    pole = true_pole(den, Z_FS)
    f = np.linspace(1.0, 0.45 * Z_FS, 200)
    G = dtft(num, den, f, Z_FS)
    exact = fit_volterra(u, y, KautzBasis(pole, (2,)))
    err = np.max(np.abs(exact.H1(f) / G - 1))
    print(f"ZOH resonator, feed-through, J1 = 2: H1 max relative error {err:.2e}")
    assert err < 1e-8
    assert exact.basis.n_params == 3
    for J1 in (2, 4, 6):
        old = fit_volterra(u, y, KautzBasis(pole, (J1,), feedthrough=False))
        e_old = np.max(np.abs(old.H1(f) / G - 1))
        print(
            f"  without the feed-through, J1 = {J1}: H1 off by {100 * e_old:.2f} %, residual "
            f"{100 * old.info.relative_residual:.2f} %"
        )
        assert e_old > 1e-3


def test_every_proper_system_with_the_modes_poles_is_in_the_span():
    """A random proper numerator of full degree over three pairs and a real pole
    (lfilter of the product of their denominators): exact with 1 + 2 x 3 + 1
    functions (J1 = 2 per mode), the minimal size."""
    fs = Z_FS
    modes = _mixed_modes(fs)[:3] + [KautzPole.from_modal(150.0, 0.05, fs)]
    modes[2] = RealPole(0.91, fs)
    den = np.array([1.0])
    for p in modes:
        den = np.convolve(den, [1.0, -p.a] if isinstance(p, RealPole) else p.denominator())
    rng = np.random.default_rng(2718)
    num = rng.standard_normal(den.size)  # degree 7 = 2 x 3 + 1
    u = rng.standard_normal(5000)
    y = lfilter(num, den, u)
    basis = KautzBasis.from_modes(modes, (2,))
    assert basis.n_params == den.size
    model = fit_volterra(u, y, basis)
    f = np.linspace(0.5, 0.49 * fs, 300)
    err = np.max(np.abs(model.H1(f) / dtft(num, den, f, fs) - 1))
    print(f"proper 7th-order system: H1 max relative error {err:.2e}")
    assert err < 1e-8 and model.info.relative_residual < 1e-10


def test_wiener_system_kernels_with_the_feedthrough():
    """y = x + a2 x^2 + a3 x^3, x = ZOH resonator output, 40 dB output noise, J = (2, 2, 2)
    with the true pole: H1 = G, H2 = a2 G(f1) G(f2) in closed form."""
    num, den = zoh_resonator(Z_FN, Z_ZETA, Z_FS)
    rng = np.random.default_rng(1618)
    u = rng.standard_normal(1 << 14)
    x = lfilter(num, den, u)
    s = 0.8 / np.std(x)
    u, x = s * u, s * x
    y = add_noise(x + A2 * x**2 + A3 * x**3, rng)
    model = fit_volterra(u, y, KautzBasis(true_pole(den, Z_FS), (2, 2, 2)))
    G = lambda f: dtft(num, den, f, Z_FS)  # noqa: E731
    d = Z_ZETA * Z_FN
    f1 = np.array([15.0, Z_FN - d, Z_FN, Z_FN + d, 140.0])
    pairs = np.array([[Z_FN, -Z_FN], [Z_FN - d, Z_FN + d], [Z_FN, 20.0], [140.0, -35.0], [Z_FN, Z_FN]]).T
    e1 = np.max(np.abs(model.H1(f1) / G(f1) - 1))
    e2 = np.max(np.abs(model.H2(*pairs) / (A2 * G(pairs[0]) * G(pairs[1])) - 1))
    print(f"Wiener on the ZOH resonator: H1 {100 * e1:.3f} %, H2 {100 * e2:.3f} %")
    assert e1 < 0.01 and e2 < 0.03


# ------------------------------------------------------------ several modes from data
CH_FS, CH_PERIOD = 97.5, 390  # 2.5 x 39 Hz; 4 s period
CH_GEOMETRY = dict(m=[1.3, 0.9, 0.7], k=[9.1e3, 1.2e4, 1.4e4], a_damp=1.7, b_damp=1.5e-4)
CH_K3 = 5e5


@pytest.fixture(scope="module")
def chain():
    df = CH_FS / CH_PERIOD
    lines = np.arange(round(6.0 / df), round(39.0 / df) + 1) * df
    phases, _ = multisine(lines, 1.0, 611)
    linear = Chain(**CH_GEOMETRY)
    u, acc = simulate(Chain(**CH_GEOMETRY, k3=CH_K3), lines, 1.0, phases, CH_FS, 6 * CH_PERIOD)
    _, acc_lin = simulate(linear, lines, 1.0, phases, CH_FS, 6 * CH_PERIOD)
    fn, zeta = linear.modes()
    return dict(
        u=u,
        acc=acc,
        lines=lines,
        fn=fn,
        zeta=zeta,
        H=linear.frf_acc(lines),
        share=np.linalg.norm(acc - acc_lin) / np.linalg.norm(acc_lin),
    )


def noisy_chain(chain, seed):
    """40 dB on force and accelerations, offsets on both channels."""
    rng = np.random.default_rng(5150 + seed)
    return add_noise(chain["u"], rng) + 0.4, add_noise(chain["acc"], rng) - np.array([0.3, 0.1, 0.2])


def by_frequency(poles):
    poles = sorted(poles, key=lambda p: p.freq_hz)
    return np.array([p.freq_hz for p in poles]), np.array([p.damping_ratio for p in poles])


def frf_error(u, acc, basis, chain):
    """||H1 - H|| / ||H|| over the excited lines and the three sensors (flat
    multisine: the input-energy weighting is uniform)."""
    H1 = np.stack(
        [fit_volterra(u, acc[:, s], basis, input_offset="mean").H1(chain["lines"]) for s in range(acc.shape[1])], axis=1
    )
    return np.linalg.norm(H1 - chain["H"]) / np.linalg.norm(chain["H"])


def test_chain_modes_over_20_noise_seeds(chain):
    """Measured over the 20 seeds: frequencies within 0.032 %, damping ratios
    within 1.0 %, first-order FRF within 0.91 % (targets 0.5 %, 10 %, 2 %).
    The FRF error is that of the noise and of a rational discrete model of a
    continuous chain (0.65 % with k3 = 0), not of the poles."""
    assert chain["share"] == pytest.approx(0.0051, abs=5e-4)
    ef, ez, eh = [], [], []
    for seed in range(20):
        u, acc = noisy_chain(chain, seed)
        basis = KautzBasis.from_data(u, acc, CH_FS, n_functions=(2,), period_samples=CH_PERIOD)
        assert len(basis.poles[1]) == 3
        fr, ze = by_frequency(basis.poles[1])
        ef.append(np.abs(fr / chain["fn"] - 1).max())
        ez.append(np.abs(ze / chain["zeta"] - 1).max())
        eh.append(frf_error(u, acc, basis, chain))
    print(
        f"chain, 20 seeds: frequency {100 * max(ef):.3f} %, damping {100 * max(ez):.2f} %, "
        f"FRF {100 * max(eh):.2f} % (largest)"
    )
    assert max(ef) < 0.005 and max(ez) < 0.10 and max(eh) < 0.02


def test_chain_modes_sorted_by_energy_and_n_modes_override(chain):
    u, acc = noisy_chain(chain, 99)
    est = estimate_modes(u, acc, CH_FS, period_samples=CH_PERIOD)
    assert np.all(np.diff(est.energy_shares) <= 0) and est.energy_shares.sum() == pytest.approx(1.0)
    # the most energetic mode of the accelerations is the middle one (shares measured
    # 0.59 / 0.28 / 0.13 for 21.0 / 33.9 / 7.7 Hz)
    assert est.poles[0].freq_hz == pytest.approx(chain["fn"][1], rel=0.005)
    # n_modes: the most energetic ones; refined with fewer modes than the band holds, the
    # linear fit leaves too much unexplained (measured 63 % with one mode): an honest error
    one = estimate_modes(u, acc, CH_FS, period_samples=CH_PERIOD, n_modes=1, refine=False)
    assert len(one.poles) == 1 and one.poles[0].freq_hz == pytest.approx(chain["fn"][1], rel=0.005)
    with pytest.raises(PoleEstimationError, match="n_modes"):
        estimate_modes(u, acc, CH_FS, period_samples=CH_PERIOD, n_modes=1)
    two = estimate_modes(u, acc, CH_FS, period_samples=CH_PERIOD, n_modes=2)
    fr, ze = by_frequency(two.poles)
    assert np.all(np.abs(fr / chain["fn"][1:] - 1) < 0.005)
    assert np.all(np.abs(ze / chain["zeta"][1:] - 1) < 0.1)
    from matplotlib.figure import Figure

    from volterra import plot_stabilisation

    assert isinstance(plot_stabilisation(est), Figure)
    basis = KautzBasis.from_data(u, acc, CH_FS, period_samples=CH_PERIOD)
    # the same modes, polished in the basis's form (volterra.polish: within zeta0 or 0.5 % in frequency,
    # a factor 2 in damping, of the modal poles), the dominant first; orders 2-3: nonlinear_modes=1
    for mine, modal in zip(basis.poles[1], est.poles):
        assert mine.freq_hz == pytest.approx(modal.freq_hz, rel=max(modal.damping_ratio, 0.005))
        assert 0.5 < mine.damping_ratio / modal.damping_ratio < 2.0
    assert basis.poles[2] == basis.poles[3] == (basis.pole(1),)
    assert basis.dim(1) == 7 and basis.dim(2) == 3 and basis.dim(3) == 7


def test_periodic_h1_is_leakage_free():
    """A periodic random input (period 512 samples, 6 periods) through a damped
    ZOH resonator: after the first period H1 equals the filter's DTFT on every
    line (the transient is below 1e-20 after one period)."""
    num, den = zoh_resonator(38.1, 0.21, Z_FS)
    rng = np.random.default_rng(512)
    u = np.tile(rng.standard_normal(512), 6)
    y = lfilter(num, den, u)
    f, H, coh, upow = periodic_h1(u, np.column_stack([y, 2 * y]), Z_FS, 512)
    G = dtft(num, den, f[1:], Z_FS)
    assert np.max(np.abs(H[1:, 0] / G - 1)) < 1e-10 and np.allclose(H[:, 1], 2 * H[:, 0])
    assert np.all(coh[1:] > 1 - 1e-12) and f[1] == pytest.approx(Z_FS / 512)


def test_two_sensors_share_the_poles():
    """Sensor 1 sees only resonator A, sensor 2 only resonator B: each alone gives
    its own mode, the joint estimate both (white noise input, Welch H1, 40 dB)."""
    rng = np.random.default_rng(4242)
    u = rng.standard_normal(1 << 14)
    modes = [(41.3, 0.031), (127.9, 0.022)]
    ys = np.stack([lfilter(*zoh_resonator(fn, z, Z_FS), u) for fn, z in modes], axis=1)
    ys = add_noise(ys, rng)
    u = add_noise(u, rng)
    both = estimate_modes(u, ys, Z_FS)
    fr, ze = by_frequency(both.poles)
    truth = np.array(modes)
    print("two sensors:", np.round(fr, 3), np.round(ze, 4))
    assert np.all(np.abs(fr / truth[:, 0] - 1) < 0.005) and np.all(np.abs(ze / truth[:, 1] - 1) < 0.1)
    assert both.H.shape[1] == 2
    for s in range(2):
        alone = estimate_modes(u, ys[:, s], Z_FS)
        assert len(alone.poles) == 1 and abs(alone.poles[0].freq_hz / modes[s][0] - 1) < 0.005


@pytest.mark.parametrize("periodic", [False, True])
def test_no_mode_in_white_noise_raises(periodic):
    """Output noise independent of the input ("white noise through nothing")."""
    rng = np.random.default_rng(8088)
    u = rng.standard_normal(8 * 512)
    y = rng.standard_normal(u.size)
    kw = dict(period_samples=512) if periodic else {}
    with pytest.raises(PoleEstimationError):
        KautzBasis.from_data(u, y, Z_FS, **kw)


def test_projector_on_a_several_mode_basis(chain):
    """The projector gives the fit's components on a three-mode basis (orders 2-3
    from the dominant mode)."""
    u, acc = noisy_chain(chain, 7)
    basis = KautzBasis.from_data(u, acc, CH_FS, period_samples=CH_PERIOD)
    proj = VolterraProjector(u, basis)
    fit = dict(zip((1, 2, 3), fit_volterra(u, acc[:, 1], basis).components(u)))
    mine = proj.components(acc[:, 1])
    for n in (1, 2, 3):
        assert np.linalg.norm(mine[n] - fit[n]) <= 1e-8 * np.linalg.norm(fit[1])


def test_real_pole_first_order_system_is_exact():
    """b z^-1 / (1 - a z^-1) (a first-order system behind a ZOH) with its real pole."""
    a = float(np.exp(-2 * np.pi * 9.7 / Z_FS))
    rng = np.random.default_rng(1234)
    u = rng.standard_normal(3000)
    y = lfilter([0.0, 1.0 - a], [1.0, -a], u)
    model = fit_volterra(u, y, KautzBasis(RealPole(a, Z_FS), (2,)))
    f = np.linspace(0.0, 0.45 * Z_FS, 50)
    e = np.exp(-2j * np.pi * f / Z_FS)
    assert np.max(np.abs(model.H1(f) / ((1 - a) * e / (1 - a * e)) - 1)) < 1e-9
    # the filter and the closed form agree for a sequence starting with a real pole
    seq = (RealPole(a, Z_FS), KautzPole.from_modal(30.0, 0.05, Z_FS))
    rows = gobf_filter_rows(np.eye(1, 4096)[0], seq)
    assert (
        np.abs(np.fft.rfft(rows, axis=1).T - gobf_frequency_response(seq, np.fft.rfftfreq(4096, 1 / Z_FS), Z_FS)).max()
        < 1e-9
    )
