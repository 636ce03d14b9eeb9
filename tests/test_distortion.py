"""volterra.distortion: a periodic record's odd and even distortion against closed forms,
an independent ODE solver and the noise's own statistics.

* a sine through a static polynomial ``u + a u^2 + b u^3``: the even line 2 k0
  holds ``a A^2 / 2`` and the odd line 3 k0 ``b A^3 / 4`` against ``A + 3 b A^3 / 4``
  on the excited line (trigonometric identities): the levels to 1e-6 dB;
* an oscillator solved by scipy's DOP853 under an odd random-phase multisine
  (a third of the odd lines left out as detection lines): a cubic spring
  shows on the odd lines alone, a quadratic one on the even lines first,
  a linear one on neither;
* a linear structure whose force carries even lines (a shaker's own
  distortion): the force's even lines detected, the output's not (the linear
  response to the force's content is taken out);
* noise alone: the ratio's sd over 200 records within 15 % of the stated one,
  at most 1 % of records detected.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.signal import butter, lfilter

from volterra.distortion import distortion, line_classes
from volterra.periods import PeriodLayout

FS, N, P = 256.0, 1024, 7
LAYOUT = PeriodLayout(N, 0, P, True, 0.0)


def _multisine(rng, top_line=120, odd_random=True):
    """One period of a random-phase multisine on the odd lines 3 .. top_line (one in three
    left out at random when ``odd_random``), unit rms; and its excited lines."""
    lines = np.arange(3, top_line, 2)
    if odd_random:
        lines = np.array([k for k in lines if rng.integers(3) != 0])
    X = np.zeros(N // 2 + 1, complex)
    X[lines] = np.exp(1j * rng.uniform(0, 2 * np.pi, lines.size))
    x = np.fft.irfft(X, N)
    return x / x.std(), lines


def test_a_sine_through_a_polynomial_has_the_closed_form_levels():
    k0, A, a, b = 5, 2.0, 0.03, 0.01
    t = np.arange(N * P)
    u = A * np.cos(2 * np.pi * k0 * t / N + 0.4)
    y = u + a * u**2 + b * u**3
    rng = np.random.default_rng(7)
    d = distortion(u + 1e-9 * rng.standard_normal(u.size), y + 1e-9 * rng.standard_normal(u.size), FS, LAYOUT)
    assert d.classes == {"odd": 1, "even": 1, "noise": 12}  # lines 1..15: 15; 10; the rest but 5 (excited)
    first = (A + 3 * b * A**3 / 4) ** 2
    assert d.sensors["y0"]["even"]["level_db"] == pytest.approx(10 * np.log10((a * A**2 / 2) ** 2 / first), abs=1e-6)
    assert d.sensors["y0"]["odd"]["level_db"] == pytest.approx(10 * np.log10((b * A**3 / 4) ** 2 / first), abs=1e-6)
    assert d.sensors["y0"]["odd"]["detected"] and d.sensors["y0"]["even"]["detected"]
    assert not d.sensors["y0"]["noise"]["detected"]


def test_classes_by_parity_of_the_excited_lines():
    excited = np.zeros(40, bool)
    excited[[3, 9, 15]] = True  # odd multiples of 3
    c = line_classes(excited, 40)
    assert list(c["odd"]) == [21, 27, 33, 39] and list(c["even"]) == [6, 12, 18, 24, 30, 36]
    assert 1 in c["noise"] and 3 not in c["noise"]
    excited[[3, 4]] = True  # both parities: the classes merge
    assert set(line_classes(excited, 40)) == {"any"}


def _oscillator(u_period, k2, k3, fn=12.0, zeta=0.02):
    """Displacement [m] of a unit mass (fn [Hz], zeta) with springs k2 q^2 + k3 q^3 [N/m^2, N/m^3]
    under P periods of the force, by scipy's DOP853 (the force interpolated by its Fourier series)."""
    wn = 2 * np.pi * fn
    C = np.fft.rfft(u_period) / N
    k = np.arange(C.size)

    def force(t):
        return float(np.real(C[0]) + 2 * np.real(np.sum(C[1:] * np.exp(2j * np.pi * k[1:] * t * FS / N))))

    def rhs(t, x):
        q, v = x
        return [v, force(t) - 2 * zeta * wn * v - wn**2 * q - k2 * q**2 - k3 * q**3]

    t = np.arange(N * P) / FS
    sol = solve_ivp(rhs, (0, t[-1]), [0.0, 0.0], t_eval=t, method="DOP853", rtol=1e-9, atol=1e-12)
    assert sol.success and sol.y.shape[1] == t.size
    return sol.y[0]


@pytest.mark.parametrize(
    "k2, k3, odd, even",
    [(0.0, 0.0, False, False), (0.0, 1.4e5, True, False), (6e3, 0.0, True, True)],
    ids=["linear", "cubic", "quadratic"],
)
def test_an_oscillator_shows_its_nonlinearity_on_the_right_lines(k2, k3, odd, even):
    rng = np.random.default_rng(11)
    u1, _ = _multisine(rng)
    u1 *= 100.0  # rms displacement about 0.045 m: k3 q^2 / wn^2 about 0.05, k2 q / wn^2 about 0.05
    u = np.tile(u1, P)
    y = _oscillator(u1, k2, k3)
    un = u + 0.01 * u.std() * rng.standard_normal(u.size)
    yn = y + 0.01 * y.std() * rng.standard_normal(y.size)
    d = distortion(un, yn, FS)
    r = d.sensors["y0"]
    assert d.parity and (r["odd"]["detected"], r["even"]["detected"]) == (odd, even), d.verdict("y0")
    if k2:  # the quadratic's own lines lead: degree 2 at first order, degree 3 at second
        assert r["even"]["level_db"] > r["odd"]["level_db"] + 5
    assert not any(f["detected"] for f in d.force.values())


def test_distortion_of_the_force_is_not_read_as_the_structures():
    rng = np.random.default_rng(3)
    u1, lines = _multisine(rng)
    # the shaker's own distortion: 2 % of the force on the even lines (-34 dB: below the excited
    # lines' threshold of -30 dB), the structure linear
    X = np.fft.rfft(u1)
    X[lines + 1] += 0.02 * np.abs(X[lines]) * np.exp(1j * rng.uniform(0, 2 * np.pi, lines.size))
    u1 = np.fft.irfft(X, N)
    b, a = butter(2, [10 / 128, 14 / 128], "band")
    y = lfilter(b, a, np.tile(u1, P + 3))[3 * N :]
    u = np.tile(u1, P)
    d = distortion(u + 0.01 * rng.standard_normal(u.size), y + 0.01 * y.std() * rng.standard_normal(y.size), FS)
    assert d.force["even"]["detected"] and not d.force["odd"]["detected"]
    assert not d.sensors["y0"]["even"]["detected"], d.verdict("y0")


def test_noise_alone_reads_as_noise_with_the_stated_spread():
    rng = np.random.default_rng(1)
    u1, _ = _multisine(rng)
    b, a = butter(2, [10 / 128, 14 / 128], "band")
    y = lfilter(b, a, np.tile(u1, P + 3))[3 * N :]
    u = np.tile(u1, P)
    ratios, sds, hits = {"odd": [], "even": []}, {}, 0
    for _ in range(200):
        # a force sensor's noise passes through the resonance into the lines' noise: unequal lines
        d = distortion(u + 0.02 * rng.standard_normal(u.size), y + 0.01 * y.std() * rng.standard_normal(y.size), FS)
        for c in ratios:
            ratios[c].append(d.sensors["y0"][c]["noise_ratio"])
            sds[c] = d.sensors["y0"][c]["sd"]
            hits += d.sensors["y0"][c]["detected"]
    for c, r in ratios.items():
        assert np.mean(r) == pytest.approx(1.0, abs=3 * sds[c] / np.sqrt(len(r)))
        assert np.std(r) == pytest.approx(sds[c], rel=0.15)
    assert hits <= 4  # of 400 class readings


def test_a_record_that_does_not_repeat_is_refused():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="not periodic"):
        distortion(rng.standard_normal(4096), rng.standard_normal(4096), FS)
