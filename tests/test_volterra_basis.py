"""Kautz poles, functions and basis: orthonormality (test 1), agreement with an
independent implementation of the formulas, and bad-input errors (test 8, poles/J)."""

import math
import pathlib
import sys

import numpy as np
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).parent))
from test_volterra_reference import kautz_ref_freq, kautz_ref_impulse, kautz_ref_pole  # noqa: E402

from volterra import (  # noqa: E402  # noqa: E402
    KautzBasis,
    KautzPole,
    kautz_filter,
    kautz_frequency_response,
    kautz_impulse_responses,
    pole_from_modal,
)

FS = 1024.0
POLES = [(30.0, 0.01), (30.0, 0.05), (30.0, 0.2), (100.0, 0.01), (100.0, 0.05), (5.0, 0.05), (5.0, 0.01), (300.0, 0.02)]


# ------------------------------------------------------------ test 1
@pytest.mark.parametrize("fn,zeta", POLES)
def test_gram_matrix_is_identity(fn, zeta):
    pole = KautzPole.from_modal(fn, zeta, FS)
    horizon = max(16384, 2 * pole.settling_samples(1e-14))
    psi = kautz_impulse_responses(pole, 8, horizon)
    for J in (2, 4, 6, 8):
        gram = psi[:, :J].T @ psi[:, :J]
        assert np.abs(gram - np.eye(J)).max() < 1e-10, (fn, zeta, J, horizon)


def test_short_horizon_is_not_orthonormal():
    # the notes: over 4096 samples at 30 Hz, zeta 0.01 the J = 8 Gram matrix is off by ~4e-2
    psi = kautz_impulse_responses(KautzPole.from_modal(30.0, 0.01, FS), 8, 4096)
    assert np.abs(psi.T @ psi - np.eye(8)).max() > 1e-2


# ------------------------------------------- against the independent formulas
@pytest.mark.parametrize("fn,zeta", [(30.0, 0.01), (100.0, 0.05), (5.0, 0.05)])
def test_impulse_responses_match_inverse_fft_of_closed_form(fn, zeta):
    pole = KautzPole.from_modal(fn, zeta, FS)
    ours = kautz_impulse_responses(pole, 8, 6000)
    ref = kautz_ref_impulse(fn, zeta, FS, 8, 6000)
    assert np.abs(ours - ref).max() < 1e-12


@pytest.mark.parametrize("fn,zeta", [(30.0, 0.01), (100.0, 0.05)])
def test_frequency_response_matches_closed_form_and_dtft(fn, zeta):
    pole = KautzPole.from_modal(fn, zeta, FS)
    f = np.linspace(-FS / 2, FS / 2, 41)
    ours = kautz_frequency_response(pole, 6, f)
    assert np.abs(ours - kautz_ref_freq(f, fn, zeta, FS, 6)).max() < 1e-11
    # DTFT of our own (recursively filtered) impulse responses
    n = 2 * pole.settling_samples(1e-16)
    psi = kautz_impulse_responses(pole, 6, n)
    E = np.exp(-2j * np.pi * np.outer(f, np.arange(n)) / FS)
    assert np.abs(E @ psi - ours).max() < 1e-9
    # Psi(-f) = conj Psi(f)
    assert np.allclose(kautz_frequency_response(pole, 6, -f), ours.conj(), atol=1e-14)


def test_pole_parameters():
    fn, zeta = 37.0, 0.01
    pole = pole_from_modal(fn, zeta, FS)
    Z = kautz_ref_pole(fn, zeta, FS)
    assert abs(pole.z - Z) < 1e-15
    assert pole.freq_hz == pytest.approx(fn, rel=1e-12)
    assert pole.damping_ratio == pytest.approx(zeta, rel=1e-10)
    b, c = pole.b, pole.c
    assert abs(b) < 1 and -1 < c < 0
    roots = np.roots([1.0, b * (c - 1.0), -c])
    assert np.allclose(sorted(roots, key=np.imag), [Z.conjugate(), Z], atol=1e-14)
    z = np.exp(2j * np.pi * np.linspace(0, FS / 2, 50) / FS)
    A = (-c * z**2 + b * (c - 1) * z + 1) / (z**2 + b * (c - 1) * z - c)
    assert np.abs(np.abs(A) - 1).max() < 1e-13
    # alternative constructors and conjugate normalisation
    assert KautzPole.from_z(Z.conjugate(), FS).z == pole.z
    assert abs(KautzPole.from_s(pole.s, FS).z - pole.z) < 1e-15
    assert pole.s.real == pytest.approx(-zeta * 2 * math.pi * fn, rel=1e-10)


def test_filter_equals_direct_convolution():
    rng = np.random.default_rng(11)
    u = rng.standard_normal((3, 2048))  # three records filtered at once
    pole = KautzPole.from_modal(30.0, 0.02, FS)
    out = kautz_filter(u, pole, 6)
    assert out.shape == (3, 2048, 6)
    psi = kautz_ref_impulse(30.0, 0.02, FS, 6, 2048)
    for r in range(3):
        for i in range(6):
            ref = np.convolve(u[r], psi[:, i])[:2048]
            assert np.abs(out[r, :, i] - ref).max() < 1e-11 * np.abs(ref).max()


# ------------------------------------------------------------ basis
def test_basis_orders_terms_and_per_order_poles():
    """Today's Kautz functions (feedthrough=False); with the feed-through every
    order has one function more (the input itself)."""
    basis = KautzBasis.from_modal(freq_hz=37.0, damping_ratio=0.01, fs=FS, n_functions=(2, 2, 6), feedthrough=False)
    assert basis.orders == (1, 2, 3)
    assert basis.n_params == 2 + 2 * 3 // 2 + 6 * 7 * 8 // 6
    with_ft = KautzBasis.from_modal(freq_hz=37.0, damping_ratio=0.01, fs=FS, n_functions=(2, 2, 6))
    assert with_ft.feedthrough and with_ft.n_params == 3 + 3 * 4 // 2 + 7 * 8 * 9 // 6
    b13 = KautzBasis.from_modal(37.0, 0.01, FS, n_functions=(2, 0, 6), feedthrough=False)
    assert b13.orders == (1, 3) and b13.n_params == 2 + 56
    assert KautzBasis.from_modal(37.0, 0.01, FS, {1: 4, 3: 4}).orders == (1, 3)
    assert KautzBasis.from_modal(37.0, 0.01, FS, 8).orders == (1,)
    per = KautzBasis.from_modal(
        freq_hz=(30.0, 25.0, 35.0),
        damping_ratio={1: 0.01, 2: 0.05, 3: 0.03},
        fs=FS,
        n_functions=(4, 2, 4),
        feedthrough=False,
    )
    assert per.pole(2).freq_hz == pytest.approx(25.0)
    assert per.pole(3).damping_ratio == pytest.approx(0.03)
    rng = np.random.default_rng(2)
    u = rng.standard_normal(1000)
    filt = per.filter(u)
    for n, (fn, z) in {1: (30.0, 0.01), 2: (25.0, 0.05), 3: (35.0, 0.03)}.items():
        ref = kautz_filter(u, KautzPole.from_modal(fn, z, FS), per.n_functions[n])
        assert np.array_equal(filt[n], ref)
    # shared pole: orders 2 and 3 filtered once and sliced
    shared = KautzBasis.from_modal(30.0, 0.01, FS, (2, 2, 6), feedthrough=False).filter(u)
    assert np.allclose(shared[2], shared[3][:, :2])
    # regressor matrix: (N, P) and equal to the products of filtered inputs
    G = per.regressors(u)
    assert G.shape == (1000, per.n_params)
    l3 = filt[3]
    assert np.allclose(G[:, -1], l3[:, 3] ** 3)  # last tuple (3, 3, 3)
    assert np.allclose(G[:, 4 + 1], filt[2][:, 0] * filt[2][:, 1])  # B2[0, 1]


def test_basis_is_reusable_and_comparable():
    a = KautzBasis.from_modal(30.0, 0.01, FS, (2, 2, 6))
    b = KautzBasis.from_modal(30.0, 0.01, FS, (2, 2, 6))
    assert a == b and hash(a) == hash(b)
    assert a != KautzBasis.from_modal(30.0, 0.02, FS, (2, 2, 6))
    assert "order 3: J =  6" in a.describe()


# ------------------------------------------------------------ test 8 (poles, J)
@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(freq_hz=30.0, damping_ratio=-0.01), "unstable"),
        (dict(freq_hz=30.0, damping_ratio=0.0), "unstable"),
        (dict(freq_hz=30.0, damping_ratio=1.2), "real poles"),
        (dict(freq_hz=600.0, damping_ratio=0.01), "Nyquist"),
        (dict(freq_hz=-5.0, damping_ratio=0.01), "positive"),
        (dict(freq_hz=float("nan"), damping_ratio=0.01), "positive"),
    ],
)
def test_bad_modal_pole_raises(kwargs, match):
    with pytest.raises(ValueError, match=match):
        KautzPole.from_modal(fs=FS, **kwargs)
    with pytest.raises(ValueError, match=match):
        KautzBasis.from_modal(fs=FS, n_functions=(2, 2, 2), **kwargs)


def test_bad_discrete_pole_raises():
    with pytest.raises(ValueError, match="unstable.*inside the unit circle"):
        KautzPole.from_z(1.001 * np.exp(0.2j), FS)
    with pytest.raises(ValueError, match="unstable"):
        KautzPole.from_s(complex(0.5, 100.0), FS)
    with pytest.raises(ValueError, match="complex-conjugate pair"):
        KautzPole.from_z(0.9, FS)
    with pytest.raises(ValueError, match="sampling rate"):
        KautzPole.from_modal(30.0, 0.01, 0.0)


@pytest.mark.parametrize("n_functions", [(3, 2, 2), (2, 2, 5), (-2,), {1: 2.5}, (2, "a"), ()])
def test_bad_number_of_functions_raises(n_functions):
    with pytest.raises(ValueError, match="even|order|no kernel order"):
        KautzBasis.from_modal(30.0, 0.01, FS, n_functions)


def test_bad_basis_definitions_raise():
    p1, p2 = KautzPole.from_modal(30, 0.01, 1024.0), KautzPole.from_modal(30, 0.01, 2048.0)
    with pytest.raises(ValueError, match="sampling rate"):
        KautzBasis({1: p1, 3: p2}, {1: 2, 3: 2})
    with pytest.raises(ValueError, match="orders must be integers 1..3"):
        KautzBasis(p1, {4: 2})
    with pytest.raises(ValueError, match="no entry for order"):
        KautzBasis({1: p1}, (2, 2))
    with pytest.raises(ValueError, match="not in this basis"):
        KautzBasis(p1, (2,)).pole(3)
    with pytest.raises(ValueError, match="odd|even"):
        kautz_filter(np.zeros(10), p1, 3)
