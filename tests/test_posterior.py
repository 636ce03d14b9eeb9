"""The likelihood, the prior box and the posterior pipeline (bayes_update.core.likelihood,
bayes_update.core.posterior)."""

import json
import math

import numpy as np
import pytest
from scipy import stats

import fe
import volterra
from bayes_update.core.likelihood import Likelihood, StageScale, noise_scale_from_replicates
from bayes_update.core.parameters import ParameterSet
from bayes_update.core.posterior import PosteriorSettings, sample
from bayes_update.core.posterior.mcmc import run_emcee
from bayes_update.models.beam.model import Beam, beam_model
from bayes_update.models.beam.virtual_rig import load_default_dataset

TRUTH = {"eta": 3.0, "c": 15.0, "F": 77.0, "k_s": 180.0}


@pytest.fixture(scope="module")
def data():
    return load_default_dataset()


def beam_space(model: Beam) -> ParameterSet:
    """The beam's prior in its internal coordinates (eta, c, P_eff, k_s)."""
    return ParameterSet(model.parameters, model)


# ----------------------------------------------------------------- prior box
def test_prior_density_integrates_to_the_public_box_area(data):
    """The internal (P_eff, k_s) density (K_b + k_s) / K_b on the image of the
    (F, k_s) box has the box's area: the Jacobian is right."""
    space = beam_space(beam_model(data, "rom"))
    box = space.box()
    P = np.linspace(box[2, 0], box[2, 1], 801)
    K = np.linspace(box[3, 0], box[3, 1], 801)
    PP, KK = np.meshgrid(P, K, indexing="ij")
    X = np.column_stack([np.full(PP.size, 3.0), np.full(PP.size, 15.0), PP.ravel(), KK.ravel()])
    dens = np.exp(space.log_prior(X)).reshape(PP.shape)
    area = np.trapezoid(np.trapezoid(dens, K, axis=1), P)
    assert area == pytest.approx((95 - 60) * 600, rel=5e-3)


def test_prior_draws_are_uniform_in_F_and_round_trip(data):
    space = beam_space(beam_model(data, "rom"))
    X = space.sample_prior(20000, seed=1)
    F = space.report(X)["F"]
    assert stats.kstest((F - 60) / 35, "uniform").pvalue > 1e-3
    assert np.all(np.isfinite(space.log_prior(X)))
    p = {"eta": 3.0, "c": 15.0, "F": 77.0, "k_s": 180.0}
    q = space.to_parameters(space.to_internal(p))
    assert (q["eta"], q["c"], q["k_s"]) == pytest.approx((3.0, 15.0, 180.0)) and q["F"] == pytest.approx(77.0)


def test_bad_prior_and_parameters_outside_it_are_named(data):
    with pytest.raises(ValueError, match="prior range of c"):
        beam_model(data, "rom", prior={"c": (10.0, 5.0)})
    space = beam_space(beam_model(data, "rom"))
    with pytest.raises(ValueError, match="k_s = 700"):
        space.check({"eta": 3.0, "c": 15.0, "F": 77.0, "k_s": 700.0})


# ---------------------------------------------------------------- likelihood
def test_z_transform_round_trip_and_likelihood_agree():
    sc = {
        st: StageScale(st, noise_mean_square=4e-6, noise_dof=2.0, model_error=3e-3, n_regressors=2, n_replicates=8)
        for st in ("linear", "nonlinear")
    }
    lik = Likelihood(sc)
    e = np.array([0.0, 1e-3, 0.01, 0.3])
    assert np.allclose(lik.from_z("linear", lik.to_z("linear", e)), e, rtol=1e-9, atol=1e-15)
    for a, b in [(1e-3, 2e-2), (0.05, 0.0)]:
        z = {"linear": lik.to_z("linear", a), "nonlinear": lik.to_z("nonlinear", b)}
        assert Likelihood.log_likelihood_from_z(z) == pytest.approx(lik.log_likelihood({"e_lin": a, "e_nlin": b}))
    assert lik.log_likelihood({"e_lin": np.nan, "e_nlin": 0.0}) == -np.inf
    assert sc["linear"].sd == pytest.approx(math.hypot(math.sqrt(2e-6), 3e-3))


def test_noise_dof_from_replicates_recovers_chi_square():
    rng = np.random.default_rng(3)
    for nu in (2, 8):
        e2 = 1e-6 * rng.chisquare(nu, size=4000)
        mean, est = noise_scale_from_replicates(e2, max_dof=59)
        assert est == pytest.approx(nu, rel=0.1)
        assert mean / est == pytest.approx(1e-6, rel=0.1)
    with pytest.raises(ValueError):
        noise_scale_from_replicates([1.0, 2.0], 5)


def test_noise_floor_matches_the_rig_snr(data):
    """The virtual rig adds white noise at 40 dB SNR (1 % of each channel's RMS):
    the noise estimator the likelihood uses (bayes_update.data.noise) must find
    it on every test and channel, from whichever source the test offers."""
    from bayes_update.data.noise import dataset_noise

    noise = dataset_noise(data)
    for t in data.tests:
        for name, x in (("force", t.force), ("velocity", t.velocity)):
            # the recorded RMS includes the noise: 1 % of the clean RMS is 0.99995 % of it
            assert noise[t.name][name].sd == pytest.approx(0.01 * np.std(x), rel=0.1), (t.name, name)


# ------------------------------------------- simulation-based calibration (toy)
def _toy_coefficients(theta):
    A = np.array([[1.0, 0.3], [0.2, 1.0], [0.5, -0.4]])
    theta = np.atleast_2d(theta)
    extra = 0.1 * np.column_stack([np.sin(3 * theta[:, 0]), np.cos(2 * theta[:, 1]), theta[:, 0] * theta[:, 1]])
    return theta @ A.T + extra + 1.0


def test_simulation_based_calibration_on_a_surrogate_level_simulator():
    """SBC (Talts et al. 2018) of the likelihood as the pipeline builds it:
    a metric e = ||c_ref - c(theta)|| / ||c_ref|| of a 3-coefficient model,
    white noise on the reference, the scale s and nu estimated from 32 noise
    replicates, emcee.  Over 100 truths drawn from the prior the ranks must
    be uniform and the 50 % and 90 % central intervals cover their share.

    This checks the sampler on a likelihood of known form (model error 0, no
    curvature adjustment); the scales the pipeline measures are calibrated
    by the ROM SBC below.  Bands, binomial: the two parameters' indicators
    are independent, so 200 trials per level.  Right sds: 0.50 / 0.90, sd
    0.035 / 0.021; sds x 0.8: 0.41 / 0.81; x 1.25: 0.60 / 0.96.  With 50 % in
    [0.43, 0.60] and 90 % in [0.855, 0.945] a right posterior passes with
    probability 0.95, one with sds x 0.8 with 0.02, x 1.25 with 0.09 (exact
    binomial, the two levels taken as independent; measured here: 0.55 and
    0.905).  The previous band (90 % in 80-98 % per parameter, 100 trials)
    passed sds from 0.8x to 1.4x."""
    rng = np.random.default_rng(2017)
    sigma, n_truths, n_rank = 0.05, 100, 99
    covered, covered50 = np.zeros(2), np.zeros(2)
    ranks = np.zeros((n_truths, 2), int)
    for k in range(n_truths):
        truth = rng.random(2)
        c_ref = _toy_coefficients(truth)[0] + sigma * rng.standard_normal(3)
        norm = np.linalg.norm(c_ref)
        e2 = [(np.linalg.norm(sigma * rng.standard_normal(3)) / norm) ** 2 for _ in range(32)]
        mean, nu = noise_scale_from_replicates(e2, max_dof=3)
        lik = Likelihood({"linear": StageScale("linear", mean, nu, 0.0, 3, 32)})

        def log_prob(X):
            inside = np.all((X >= 0) & (X <= 1), axis=1)
            e = np.linalg.norm(c_ref - _toy_coefficients(X), axis=1) / norm
            return np.where(inside, -0.5 * (e / lik.scales["linear"].sd) ** 2, -np.inf)

        smp = run_emcee(log_prob, rng.random((16, 2)), 16, 700, seed=k, vectorize=True, progress=False)
        draws = smp.get_chain(discard=200, flat=True)
        lo, q25, q75, hi = np.percentile(draws, [5, 25, 75, 95], axis=0)
        covered += (truth >= lo) & (truth <= hi)
        covered50 += (truth >= q25) & (truth <= q75)
        thin = draws[rng.choice(len(draws), n_rank, replace=False)]
        ranks[k] = np.sum(thin < truth, axis=0)
    cover90, cover50 = covered.sum() / (2 * n_truths), covered50.sum() / (2 * n_truths)
    assert 0.855 <= cover90 <= 0.945, covered / n_truths
    assert 0.43 <= cover50 <= 0.60, covered50 / n_truths
    for j in range(2):
        counts = np.histogram(ranks[:, j], bins=10, range=(0, n_rank + 1))[0]
        assert stats.chisquare(counts).pvalue > 1e-3, counts


# ------------------------- simulation-based calibration of the likelihood on the ROM
SBC_CHIRPS = {"chirp_low": (0.02, "linear"), "chirp_high": (0.2, "nonlinear")}


class _RomPoint:
    """Picklable x (internal coordinates) -> (model, parameters)."""

    def __init__(self, space, model):
        self.space, self.model = space, model

    def __call__(self, x):
        return self.model, self.space.to_parameters(x)


def _sbc_truth(args):
    """z = (mode - truth) / posterior sd of (eta, c, P_eff, k_s, F) at one truth.

    Data: the two updating chirps (0.02 N and 0.2 N, 4 s at 1024 Hz) made by
    ``generator`` ("rom": the modal ROM itself; "refined": the model
    ``estimate_likelihood`` measures the ROM's error against) at the truth,
    noise at ``snr_db`` on force and velocity.  Then what ``sample`` does
    before the sampler: the likelihood scales by ``estimate_likelihood`` at
    the truth (96 replicates, the default; model error on unless the data come
    from the ROM itself), the mode by least squares from the truth, and the
    curvature adjustment at the mode.  The posterior's covariance is the
    adjusted Laplace one, A^-1 (J^T J)^-1 A^-T (F by the delta method): the
    linearised form of benchmarks/sbc.py, without GP and MCMC (the toy SBC
    above and the surrogate-against-direct test cover those).  None when the
    data's Kautz pole cannot be identified (the data set is unusable, not the
    likelihood wrong)."""
    from bayes_update.core.adjustment import curvature_adjustment
    from bayes_update.core.likelihood import estimate_likelihood
    from bayes_update.core.mode import ResidualFunction, find_mode
    from bayes_update.core.problem import Problem
    from bayes_update.data import signals
    from bayes_update.data.dataset import Dataset, Record
    from bayes_update.models.beam.virtual_rig import PAPER_EQUIVALENT_RIG

    k, x, seed, generator, snr_db = args
    rig = PAPER_EQUIVALENT_RIG
    rom = Beam(fe.ModalROM(rig))
    space = beam_space(rom)
    box = space.box()
    widths = box[:, 1] - box[:, 0]
    params = space.to_parameters(x)
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(k,)))
    gen = rom if generator == "rom" else rom.refined()
    tests = []
    for name, (amp, role) in SBC_CHIRPS.items():
        f = signals.chirp(amp)
        v = gen.simulate(params, f, 1024.0)
        tests.append(
            Record(
                f"{name}.csv",
                "chirp",
                name.split("_")[1],
                role,
                np.arange(f.size) / 1024.0,
                signals.add_noise(f, snr_db, rng),
                signals.add_noise(v, snr_db, rng),
            )
        )
    try:
        problem = Problem(Dataset("sbc", 1024.0, rig, tests), rom)
    except ValueError as exc:  # volterra.PoleEstimationError is one
        if isinstance(exc, volterra.PoleEstimationError) or "Kautz pole" in str(exc):
            return None
        raise
    lik = estimate_likelihood(problem, params, model_error=generator != "rom", n_replicates=96, seed=k, space=space)
    stages = lik.stages
    fun = ResidualFunction(problem, stages, tuple(lik.scales[st].sd for st in stages), _RomPoint(space, rom))
    mode = find_mode(fun, [x], box[:, 0], box[:, 1], 1e-4 * widths, None, max_iterations=40)
    adj = curvature_adjustment(lik, mode.jacobian, mode.x, widths, stages)
    a_inv = np.linalg.inv(adj.A)
    cov = a_inv @ mode.covariance(scale=widths) @ a_inv.T
    z = (mode.x - x) / np.sqrt(np.diag(cov))
    kb = rom.kb
    grad_F = np.array([0.0, 0.0, (kb + mode.x[3]) / kb, mode.x[2] / kb])
    z_F = (space.report(mode.x)["F"][0] - space.report(x)["F"][0]) / math.sqrt(grad_F @ cov @ grad_F)
    return np.append(z, z_F)


def _sbc_z(n_truths, seed, generator, snr_db):
    from bayes_update.models.beam.virtual_rig import PAPER_EQUIVALENT_RIG
    from surrogates.evaluation import default_executor, evaluate_many

    truths = beam_space(Beam(fe.ModalROM(PAPER_EQUIVALENT_RIG))).sample_prior(n_truths, seed=seed)
    pool = default_executor(2)
    try:
        out = evaluate_many(
            _sbc_truth,
            [(k, x, seed, generator, snr_db) for k, x in enumerate(truths)],
            pool,
            batch_size=1,
            progress=False,
        )
    finally:
        pool.shutdown()
    return out


# The acceptance bands, from binomial statistics and the measured spread.  For
# each truth and each of eta, c, P_eff, k_s: is the truth inside the central
# 50 % and 90 % intervals (|z| < 0.674, |z| < 1.645)?  Pooled over truths and
# parameters these are coverage fractions.  Posterior sds off by a factor f
# move them to P(|Z| < 0.674 f), P(|Z| < 1.645 f): 0.41 / 0.81 at f = 0.8,
# 0.60 / 0.96 at f = 1.25 (0.50 / 0.90 right).  The four indicators of a truth
# are not independent (z of c and k_s correlate -0.90), and the pipeline's own
# coverage is not exactly nominal: measured at 200 truths (seeds 0 and 1 of
# this test's generator; 197 with an identifiable pole) 0.54 and 0.91 pooled,
# and the pooled coverage's sd over N truths is 1.3x (50 %) and 1.5x (90 %)
# the binomial sqrt(p (1 - p) / 4N), i.e. 2.4-3 effective trials per truth
# (at N = 96: sd 0.030 and 0.018).  Bootstrap of those 197 truths (6000
# resamples, z scaled by 1/f for sds off by f), probability that the test
# passes:
#                                                  as measured  sds x 0.8  sds x 1.25
#   N = 96,  50 % in [0.45, 0.60], 90 % in [0.865, 0.95]:   0.96      0.015      0.08
#   N = 200, 50 % in [0.47, 0.58], 90 % in [0.88, 0.94]:    0.96      0.000      0.002
# (N = 48 could not do it: the best bands passing 0.97 of right posteriors
# passed 0.29 / 0.35 of the wrong ones.)  The default check (96 truths, 80 s
# on 2 quiet cores: 0.83 s per truth) fails a 0.8x posterior with probability
# 0.985 and a 1.25x one with 0.92; the full one (200 truths) with > 0.99 and
# runs with -m slow.  Seed 3: not one of the truths the bands came from.
SBC_DEFAULT = dict(n_truths=96, band_50=(0.45, 0.60), band_90=(0.865, 0.95))
SBC_FULL = dict(n_truths=200, band_50=(0.47, 0.58), band_90=(0.88, 0.94))
SBC_SEED = 3


def _check_sbc(n_truths, band_50, band_90):
    z = _sbc_z(n_truths, SBC_SEED, "rom", 40.0)
    # at a lightly damped truth (zeta1 0.5-0.7 %) the H1 pole estimate of a
    # noisy low-level chirp can fail: 2 of 200 data sets at seeds 0-1
    failed = sum(r is None for r in z)
    assert failed <= 0.05 * n_truths, f"{failed} of {n_truths} data sets without an identifiable Kautz pole"
    Z = np.array([r for r in z if r is not None])[:, :4]
    cover50, cover90 = np.mean(np.abs(Z) < 0.6745), np.mean(np.abs(Z) < 1.6449)
    per_parameter = {
        "50": np.mean(np.abs(Z) < 0.6745, axis=0).round(3),
        "90": np.mean(np.abs(Z) < 1.6449, axis=0).round(3),
    }
    assert band_50[0] <= cover50 <= band_50[1], (cover50, per_parameter)
    assert band_90[0] <= cover90 <= band_90[1], (cover90, per_parameter)


@pytest.mark.slow  # 120-160 s: the 15-minute budget; benchmarks/sbc.py (200 truths) is the measurement
@pytest.mark.headline
def test_simulation_based_calibration_of_the_likelihood_on_the_rom():
    """SBC of the likelihood the pipeline builds (estimate_likelihood's noise
    scales from 96 replicates and the curvature adjustment), linearised at
    the mode: truths from the prior, data from the ROM plus 40 dB noise on
    both channels, the ROM updating them.  The model error is off here as in
    benchmarks/sbc.py, because the data come from the updating model itself
    (with it on, the ROM's 0.7-3.2 % error against the refined FE in e_nlin
    would widen c and k_s several-fold and no coverage could tell 1.25x from
    right); its budget is checked by the test after the next.  F's z is
    k_s's (correlation 1.00 measured), so it is left out of the pooling.
    Bands and power: the comment above SBC_DEFAULT."""
    _check_sbc(**SBC_DEFAULT)


@pytest.mark.slow  # 170 s on 2 quiet cores: the test above with 200 truths
def test_simulation_based_calibration_of_the_likelihood_on_the_rom_full():
    _check_sbc(**SBC_FULL)


def test_the_model_error_budget_moves_no_parameter_by_more_than_one_sd():
    """docs/likelihood.md: the model error "is budgeted as one standard
    deviation in any direction ... a bias of that size then moves any
    parameter by at most one posterior sd".  Data from the refined model
    (the full FE at 3x the elements and 4x the substeps, what
    estimate_likelihood measures the ROM's error against) without noise
    (120 dB), the ROM updating them with the model error on: the mode's
    offset from the truth is that bias.  In linear theory |z| <=
    e_model / s <= 1 for every parameter (Cauchy-Schwarz); and since the
    error is "mostly in one direction (a frequency error moves P_eff)", the
    budget is nearly used up along P_eff: |z_P_eff| near 1, not 0.1
    (an e_model measured 2x too large would halve it)."""
    z = _sbc_z(8, 2, "refined", 120.0)
    assert all(r is not None for r in z)
    Z = np.abs(np.array(z))
    # measured at 16 truths of this seed: max |z| 1.02 (P_eff; 0.47, 0.88, 0.78
    # for eta, c, k_s), 0.96 over these 8; 1.2 leaves 18 % for the
    # linearisation, and an e_model measured 0.8x too small would push 3 of
    # the 16 beyond it
    assert Z.max() <= 1.2, Z.max(axis=0)
    # |z_P_eff| measured 0.67-1.02, median 0.87 (0.84 over these 8): the
    # budget is nearly used up where the bias is; 0.5 fails an e_model
    # measured 1.7x too large
    assert np.median(Z[:, 2]) >= 0.5, Z[:, 2]


def test_emcee_is_reproducible_with_a_seed():
    def log_prob(X):
        return -0.5 * np.sum(X**2, axis=1)

    x0 = np.random.default_rng(0).standard_normal((8, 2))
    a = run_emcee(log_prob, x0, 8, 50, seed=5, vectorize=True, progress=False).get_chain()
    b = run_emcee(log_prob, x0, 8, 50, seed=5, vectorize=True, progress=False).get_chain()
    c = run_emcee(log_prob, x0, 8, 50, seed=6, vectorize=True, progress=False).get_chain()
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_the_vectorised_stretch_move_is_emcees():
    """stretch_sample against emcee's EnsembleSampler (default StretchMove) from the
    same RandomState: the same chain and log probabilities to the last bit, on a
    correlated, bounded target (walkers that propose outside are rejected), with
    an odd number of walkers; the same acceptance fractions and autocorrelation times."""
    import emcee

    from bayes_update.core.posterior.stretch import stretch_sample

    cov = np.array([[1.0, 0.9, 0.1], [0.9, 1.0, 0.0], [0.1, 0.0, 2.0]])
    P = np.linalg.inv(cov)

    def log_prob(X):
        X = np.atleast_2d(X)
        lp = -0.5 * np.einsum("ij,jk,ik->i", X, P, X)
        return np.where(X[:, 2] < 1.5, lp, -np.inf)

    x0 = 0.3 * np.random.default_rng(2).standard_normal((11, 3))
    ref = emcee.EnsembleSampler(11, 3, log_prob, vectorize=True)
    ref.random_state = np.random.RandomState(77).get_state()
    ref.run_mcmc(x0, 400, progress=False)
    ours = stretch_sample(log_prob, x0, 400, np.random.RandomState(77))
    assert np.array_equal(ours.get_chain(), ref.get_chain())
    assert np.array_equal(
        ours.get_log_prob(discard=50, thin=7, flat=True), ref.get_log_prob(discard=50, thin=7, flat=True)
    )
    assert np.array_equal(ours.get_chain(discard=13, thin=3, flat=True), ref.get_chain(discard=13, thin=3, flat=True))
    np.testing.assert_array_equal(ours.acceptance_fraction, ref.acceptance_fraction)
    np.testing.assert_array_equal(ours.get_autocorr_time(discard=100, tol=0), ref.get_autocorr_time(discard=100, tol=0))
    assert np.array_equal(ours.get_last_sample().coords, ref.get_last_sample().coords)
    assert 0.1 < ours.acceptance_fraction.mean() < 0.9  # it moved, and not every time


# ------------------------------------------------------------- the pipeline
@pytest.fixture(scope="module")
def rom_posterior(data):
    """Surrogate posterior on the ROM with reduced settings, from a given start
    (the deterministic start is tested in test_calibrate)."""
    from bayes_update.models.beam.ridge import add_linear_only

    start = {"eta": 3.05, "c": 12.0, "F": 77.5, "k_s": 200.0}
    settings = PosteriorSettings.quick(n_linear=24, n_global=0, n_predictive=8)
    post = sample(data, beam_model(data, "rom"), settings, workers=2, start=start, progress=False, log=lambda *a: None)
    add_linear_only(post, 2, None, progress=False, log=lambda *a: None)
    return post


def test_posterior_covers_the_truth_on_the_default_data(rom_posterior, data):
    s = rom_posterior.summary
    truth = dict(TRUTH)
    kb = beam_model(data, "rom").kb
    truth["P_eff"] = 77.0 * kb / (kb + 180.0)
    for name, value in truth.items():
        assert s[name]["hdi_3%"] <= value <= s[name]["hdi_97%"], (name, s[name])
        # in posterior sds (1 % of P_eff would be 200 of them): measured |mean - truth| / sd
        # 0.39 (eta), 0.86 (c, F, k_s), 0.90 (P_eff: 74.0596 +- 0.0038 N against 74.0630); 3 sd
        # leaves 3.3x that
        assert abs(s[name]["mean"] - value) <= 3.0 * s[name]["sd"], (name, s[name])
    # (No check of noise_dof here: nu = 2 mean^2 / var of the replicates' e^2 is
    # clipped by the code to [1, n_regressors], so that range cannot fail; it does
    # not enter the likelihood (the scale is the variance per direction of the
    # parameters' span); and with these 12 replicates its only independent
    # expectation, (tr S)^2 / tr S^2 of the replicates' covariance S, is itself
    # a factor 2-3 uncertain.  The estimator is checked on chi-square draws with
    # a known nu in test_noise_dof_from_replicates_recovers_chi_square.)
    # the linear-only posterior is the ridge: F and k_s move together
    assert rom_posterior.extras["linear_only"]["corr_F_k_s"] > 0.99
    assert rom_posterior.extras["linear_only"]["narrowing"]["c"] > 1.5


def test_posterior_result_is_written_as_arviz_and_json(rom_posterior, tmp_path):
    import arviz as az

    from bayes_update.reports.posterior import write_posterior

    write_posterior(rom_posterior, tmp_path, figures=False)
    idata = az.from_netcdf(str(tmp_path / "posterior.nc"))
    assert set(idata.posterior.data_vars) >= {"eta", "c", "F", "k_s", "P_eff"}
    # the groups ArviZ's checks need (az.plot_ppc: observed_data and posterior_predictive), one
    # variable per test, and every variable's unit
    assert {"posterior", "sample_stats", "observed_data", "posterior_predictive", "log_likelihood"} <= set(
        idata.groups()
    )
    # the pointwise log-likelihood of every observation (named by test), the records of every test
    names = [str(v) for v in idata.log_likelihood["observation"].values]
    assert {n.split("[")[0] for n in names} == {"chirp_low", "chirp_high"}
    assert set(idata.observed_data.data_vars) == {t.name for t in rom_posterior.problem.tests.values()} | set(
        rom_posterior.problem.validation
    )
    assert idata.posterior["k_s"].attrs["units"] == "N/mm" and idata.observed_data["chirp_low"].attrs["units"] == "m/s"
    assert idata.posterior_predictive["chirp_high"].shape[-1] == idata.observed_data["chirp_high"].shape[-1]
    # one value per direction of the compared output (y1: J1 = 2 functions; y2 + y3 of the paper's set)
    problem = rom_posterior.problem
    assert sum(n.startswith("chirp_low[") for n in names) == problem.n_regressors("linear")
    assert sum(n.startswith("chirp_high[") for n in names) == problem.n_regressors("nonlinear")
    loo = az.loo(idata)  # without an argument: every test's observations
    assert np.isfinite(loo.elpd_loo) and loo.n_data_points == problem.n_regressors("linear") + problem.n_regressors(
        "nonlinear"
    )
    az.plot_ppc(idata, data_pairs={"chirp_high": "chirp_high"}, num_pp_samples=4)
    summary = json.loads((tmp_path / "posterior_summary.json").read_text())
    for name in ("eta", "c", "F", "k_s", "P_eff"):
        assert set(summary["parameters"][name]) >= {"mean", "sd", "hdi_3%", "hdi_97%", "r_hat", "ess_bulk"}
    assert np.isclose(float(idata.posterior["P_eff"].mean()), summary["parameters"]["P_eff"]["mean"])


def test_sample_refuses_a_start_outside_the_prior(data):
    with pytest.raises(ValueError, match="outside the prior"):
        sample(
            data,
            beam_model(data, "rom"),
            PosteriorSettings.quick(),
            workers=1,
            start={"eta": 9.0, "c": 15.0, "F": 77.0, "k_s": 180.0},
            progress=False,
        )


def test_settings_are_validated():
    with pytest.raises(ValueError, match="n_steps > burn"):
        PosteriorSettings(n_steps=100, burn=200)
    with pytest.raises(ValueError, match="n_initial"):
        PosteriorSettings(n_initial=-1)


@pytest.mark.slow  # 360-430 s (the direct chain): benchmarks/posterior_comparison.py is the measurement
@pytest.mark.headline
def test_surrogate_posterior_agrees_with_the_direct_one_on_the_rom(rom_posterior, data):
    """Reduced version of benchmarks/posterior_comparison.py at docs/posterior.md's
    thresholds, every parameter: the same start, likelihood (the surrogate
    run's, passed on) and prior, emcee on the ROM itself; posterior means
    within 0.3 direct sd, 94 % HDIs overlapping > 0.8, two-sample KS D < 0.1.

    The direct chain must be long enough to resolve the thresholds: at 16
    walkers x 700 steps (the previous setting; R-hat 1.17, bulk ESS 71) the
    KS distance of c, F and k_s was 0.107-0.111 from Monte Carlo noise alone.
    At 24 x 1500 (burn 500; R-hat 1.07, bulk ESS 265) measured: means within
    0.049-0.079 sd, overlap 0.941-0.979, KS 0.028-0.042, against Monte Carlo
    sds of about 0.07 (mean) and 0.03 (KS) at that ESS."""
    import arviz as az
    from scipy import stats

    start = rom_posterior.space.to_parameters(rom_posterior.map.x)
    settings = PosteriorSettings.quick(
        direct_walkers=24, direct_steps=1500, direct_burn=500, n_linear=0, n_global=0, n_predictive=0
    )
    direct = sample(
        data,
        beam_model(data, "rom"),
        settings,
        workers=2,
        start=start,
        direct=True,
        likelihood=rom_posterior.likelihood,
        progress=False,
        log=lambda *a: None,
    )
    a = rom_posterior.space.report(rom_posterior.draws)
    b = direct.space.report(direct.draws)
    for name in ("eta", "c", "F", "k_s", "P_eff"):
        x, y = a[name], b[name]
        (la, ha), (lb, hb) = az.hdi(x, hdi_prob=0.94), az.hdi(y, hdi_prob=0.94)
        overlap = max(0.0, min(ha, hb) - max(la, lb)) / (max(ha, hb) - min(la, lb))
        assert overlap > 0.8, (name, (la, ha), (lb, hb))
        assert abs(np.mean(x) - np.mean(y)) < 0.3 * np.std(y), (name, np.mean(x), np.mean(y), np.std(y))
        assert stats.ks_2samp(x, y).statistic < 0.1, name


@pytest.fixture(scope="module")
def cli_sample(tmp_path_factory):
    from bayes_update.cli import main

    out = tmp_path_factory.mktemp("cli_sample") / "post"
    # the predictive runs are opt-in (--quick changes sizes, not steps): asked for, for predictive.png
    config = out.parent / "sample.toml"
    config.write_text("[sample]\nn_predictive = 8\n")
    assert (
        main(
            [
                "sample",
                "--model",
                "rom",
                "--quick",
                "--config",
                str(config),
                "--out",
                str(out),
                "--workers",
                "2",
                "--no-cache",
            ]
        )
        == 0
    )
    return out


def test_cli_sample_writes_posterior_files(cli_sample, tmp_path):
    """posterior_summary.json: parameters -> name -> mean, sd, hdi_3%, hdi_97%,
    r_hat, ess_bulk, each the statistic of the draws in posterior.nc
    (recomputed here: numpy for the mean and sd, arviz for HDI, R-hat and
    ESS; the JSON round trip is exact to 1e-12); the truth within 3 sd; the
    figures are PNG images."""
    import arviz as az

    from bayes_update.cli import main

    out = cli_sample
    summary = json.loads((out / "posterior_summary.json").read_text())
    idata = az.from_netcdf(str(out / "posterior.nc"))
    kb = beam_model(load_default_dataset(), "rom").kb
    truth = {"eta": 3.0, "c": 15.0, "F": 77.0, "k_s": 180.0, "P_eff": 77.0 * kb / (kb + 180.0)}
    for name in ("eta", "c", "F", "k_s", "P_eff"):
        got = summary["parameters"][name]
        assert {"mean", "sd", "hdi_3%", "hdi_97%", "r_hat", "ess_bulk"} <= set(got), (name, got)
        draws = idata.posterior[name].values  # (walker, draw), the parameter's unit
        lo, hi = az.hdi(draws.ravel(), hdi_prob=0.94)
        for key, ref in (
            ("mean", draws.mean()),
            ("sd", draws.std(ddof=1)),
            ("hdi_3%", lo),
            ("hdi_97%", hi),
            ("r_hat", float(az.rhat(idata, var_names=[name])[name])),
            ("ess_bulk", float(az.ess(idata, var_names=[name], method="bulk")[name])),
        ):
            assert got[key] == pytest.approx(float(ref), rel=1e-9, abs=1e-12 * abs(got["mean"])), (name, key)
        assert got["hdi_3%"] < got["mean"] < got["hdi_97%"]
        # |mean - truth| / sd measured 0.43 (eta), 0.86-0.87 (c, F, k_s), 0.90 (P_eff); 3 sd
        assert abs(got["mean"] - truth[name]) <= 3.0 * got["sd"], (name, got)
    assert summary["parameters"]["P_eff"]["units"] == "N"
    for name in ("corner.png", "traces.png", "predictive.png", "gp_diagnostics.png"):
        head = (out / name).read_bytes()[:8]
        assert head == b"\x89PNG\r\n\x1a\n" and (out / name).stat().st_size > 10_000, name
    assert main(["sample", "--modes", "4", "--quick", "--out", str(tmp_path)]) == 2  # --modes needs --model rom
    assert main(["sample", "--prior", "G=1:2", "--quick", "--out", str(tmp_path)]) == 2
    assert main(["sample", "--prior", "F=95:20", "--quick", "--out", str(tmp_path)]) == 2


def test_whitening_round_trip_and_box_cut_fraction(data):
    from bayes_update.core.posterior.mcmc import fraction_outside_box
    from bayes_update.core.posterior.target import Whitening

    space = beam_space(beam_model(data, "rom"))
    cov = np.diag([0.03, 2.0, 0.03, 150.0]) ** 2
    cov[1, 3] = cov[3, 1] = -0.9 * 2.0 * 150.0
    w = Whitening.from_covariance(np.array([3.0, 15.0, 74.0, 200.0]), cov)
    X = np.array([[3.1, 14.0, 74.02, 250.0], [2.9, 16.0, 73.99, 150.0]])
    assert np.allclose(w.to_x(w.to_u(X)), X)
    emp = np.cov(w.to_x(np.random.default_rng(0).standard_normal((200000, 4))).T)
    scale = np.sqrt(np.outer(np.diag(cov), np.diag(cov)))
    assert np.all(np.abs(emp - cov) < 0.02 * scale)
    # draws at the u box's edge count as cut only where the prior goes on beyond it
    U = np.zeros((4, 4))
    U[0, 0] = 3.9  # eta direction, inside the prior beyond: cut
    assert fraction_outside_box(U, 4.0, w, space) == pytest.approx(0.25)
    assert fraction_outside_box(np.zeros((4, 4)), 4.0, w, space) == 0.0
