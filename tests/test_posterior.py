"""The likelihood, the prior box and the posterior pipeline (bayes_update.likelihood,
bayes_update.posterior)."""
import json
import math

import numpy as np
import pytest
from scipy import stats

import fe
from bayes_update.likelihood import (Likelihood, ParameterSpace, StageScale, noise_scale_from_replicates,
                                     white_noise_sd)
from bayes_update.posterior import PosteriorSettings, run_emcee, sample
from bayes_update.virtual_rig import load_default_dataset

TRUTH = {"eta": 3.0, "c": 15.0, "F": 77.0, "k_s": 180.0}


@pytest.fixture(scope="module")
def data():
    return load_default_dataset()


# ----------------------------------------------------------------- prior box
def test_prior_density_integrates_to_the_public_box_area(data):
    """The internal (P_eff, k_s) density (K_b + k_s) / K_b on the image of the
    (F, k_s) box has the box's area: the Jacobian is right."""
    space = ParameterSpace(data.rig)
    box = space.box()
    P = np.linspace(box[2, 0], box[2, 1], 801)
    K = np.linspace(box[3, 0], box[3, 1], 801)
    PP, KK = np.meshgrid(P, K, indexing="ij")
    X = np.column_stack([np.full(PP.size, 3.0), np.full(PP.size, 15.0), PP.ravel(), KK.ravel()])
    dens = np.exp(space.log_prior(X)).reshape(PP.shape)
    area = np.trapezoid(np.trapezoid(dens, K, axis=1), P)
    assert area == pytest.approx((95 - 60) * 600, rel=5e-3)


def test_prior_draws_are_uniform_in_F_and_round_trip(data):
    space = ParameterSpace(data.rig)
    X = space.sample_prior(20000, seed=1)
    F = space.F_of(X)
    assert stats.kstest((F - 60) / 35, "uniform").pvalue > 1e-3
    assert np.all(np.isfinite(space.log_prior(X)))
    p = fe.Parameters(eta=3e6, c=15e3, F=77.0, k_s=180e3)
    q = space.to_parameters(space.to_internal(p))
    assert (q.eta, q.c, q.k_s) == pytest.approx((p.eta, p.c, p.k_s)) and q.F == pytest.approx(77.0)


def test_bad_prior_and_parameters_outside_it_are_named(data):
    with pytest.raises(ValueError, match="prior range of c"):
        ParameterSpace(data.rig, c=(10.0, 5.0))
    space = ParameterSpace(data.rig)
    with pytest.raises(ValueError, match="k_s = 700"):
        space.check(fe.Parameters(eta=3e6, c=15e3, F=77.0, k_s=700e3))


# ---------------------------------------------------------------- likelihood
def test_z_transform_round_trip_and_likelihood_agree():
    sc = {st: StageScale(st, noise_mean_square=4e-6, noise_dof=2.0, model_error=3e-3, n_regressors=2,
                         n_replicates=8) for st in ("linear", "nonlinear")}
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
    the floor read above the excited band must find it."""
    for t in data.tests:
        if t.signal != "chirp":
            continue
        band = (200.0, 450.0)
        for x in (t.force, t.velocity):
            # the recorded RMS includes the noise: 1 % of the clean RMS is 0.99995 % of it
            assert white_noise_sd(x, data.sampling_rate_hz, band) == pytest.approx(0.01 * np.std(x), rel=0.1)


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
    replicates, emcee.  Over 100 truths drawn from the prior the 90 % central
    intervals must cover 80-98 % and the ranks must be uniform."""
    rng = np.random.default_rng(2017)
    sigma, n_truths, n_rank = 0.05, 100, 99
    covered = np.zeros(2)
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
        lo, hi = np.percentile(draws, [5, 95], axis=0)
        covered += (truth >= lo) & (truth <= hi)
        thin = draws[rng.choice(len(draws), n_rank, replace=False)]
        ranks[k] = np.sum(thin < truth, axis=0)
    coverage = covered / n_truths
    assert np.all((coverage >= 0.80) & (coverage <= 0.98)), coverage
    for j in range(2):
        counts = np.histogram(ranks[:, j], bins=10, range=(0, n_rank + 1))[0]
        assert stats.chisquare(counts).pvalue > 1e-3, counts


def test_emcee_is_reproducible_with_a_seed():
    def log_prob(X):
        return -0.5 * np.sum(X ** 2, axis=1)

    x0 = np.random.default_rng(0).standard_normal((8, 2))
    a = run_emcee(log_prob, x0, 8, 50, seed=5, vectorize=True, progress=False).get_chain()
    b = run_emcee(log_prob, x0, 8, 50, seed=5, vectorize=True, progress=False).get_chain()
    c = run_emcee(log_prob, x0, 8, 50, seed=6, vectorize=True, progress=False).get_chain()
    assert np.array_equal(a, b) and not np.array_equal(a, c)


# ------------------------------------------------------------- the pipeline
@pytest.fixture(scope="module")
def rom_posterior(data):
    """Surrogate posterior on the ROM with reduced settings, from a given start
    (the deterministic start is tested in test_calibrate)."""
    start = fe.Parameters(eta=3.05e6, c=12e3, F=77.5, k_s=200e3)
    settings = PosteriorSettings.quick(n_linear=24, n_global=0, n_predictive=8)
    return sample(data, fe.ModalROM(data.rig), settings, workers=2, start=start, progress=False,
                  log=lambda *a: None)


def test_posterior_covers_the_truth_on_the_default_data(rom_posterior, data):
    s = rom_posterior.summary
    truth = dict(TRUTH)
    kb = data.rig.axial_stiffness / 1e3
    truth["P_eff"] = 77.0 * kb / (kb + 180.0)
    si = {"eta": 1e6, "c": 1e3, "F": 1.0, "k_s": 1e3, "P_eff": 1.0}
    for name, value in truth.items():
        assert s[name]["hdi_3%"] <= value * si[name] <= s[name]["hdi_97%"], (name, s[name])
    assert s["P_eff"]["mean"] == pytest.approx(truth["P_eff"], rel=0.01)
    # the likelihood scales: nu <= the regressors behind each metric
    for sc in rom_posterior.likelihood.scales.values():
        assert 1.0 <= sc.noise_dof <= sc.n_regressors
    # the linear-only posterior is the ridge: F and k_s move together
    assert rom_posterior.linear_only["corr_F_k_s"] > 0.99
    assert rom_posterior.linear_only["narrowing"]["c"] > 1.5


def test_posterior_result_is_written_as_arviz_and_json(rom_posterior, tmp_path):
    import arviz as az

    from bayes_update.posterior import write_posterior

    write_posterior(rom_posterior, tmp_path, figures=False)
    idata = az.from_netcdf(str(tmp_path / "posterior.nc"))
    assert set(idata.posterior.data_vars) >= {"eta", "c", "F", "k_s", "P_eff"}
    summary = json.loads((tmp_path / "posterior_summary.json").read_text())
    for name in ("eta", "c", "F", "k_s", "P_eff"):
        assert set(summary["parameters"][name]) >= {"mean", "sd", "hdi_3%", "hdi_97%", "r_hat", "ess_bulk"}
    assert np.isclose(float(idata.posterior["P_eff"].mean()), summary["parameters"]["P_eff"]["mean"])


def test_sample_refuses_a_start_outside_the_prior(data):
    with pytest.raises(ValueError, match="outside the prior box"):
        sample(data, fe.ModalROM(data.rig), PosteriorSettings.quick(), workers=1,
               start=fe.Parameters(eta=9e6, c=15e3, F=77.0, k_s=180e3), progress=False)


def test_settings_are_validated():
    with pytest.raises(ValueError, match="n_steps > burn"):
        PosteriorSettings(n_steps=100, burn=200)
    with pytest.raises(ValueError, match="n_initial"):
        PosteriorSettings(n_initial=-1)


def test_surrogate_posterior_agrees_with_the_direct_one_on_the_rom(rom_posterior, data):
    """Reduced version of benchmarks/posterior_comparison.py: the same start,
    likelihood and prior, emcee on the ROM itself.  With short direct chains
    the thresholds are looser than the benchmark's (0.3 sd, overlap 0.8)."""
    import arviz as az

    from bayes_update.posterior_plots import paper_draws

    start = rom_posterior.space.to_parameters(rom_posterior.map.x)
    settings = PosteriorSettings.quick(n_walkers=16, direct_steps=700, direct_burn=250, n_linear=0,
                                       n_global=0, n_predictive=0)
    direct = sample(data, fe.ModalROM(data.rig), settings, workers=2, start=start, direct=True,
                    progress=False, log=lambda *a: None)
    a = paper_draws(rom_posterior.space, rom_posterior.draws)
    b = paper_draws(direct.space, direct.draws)
    for name in ("eta", "c", "F", "k_s", "P_eff"):
        (la, ha), (lb, hb) = az.hdi(a[name], hdi_prob=0.94), az.hdi(b[name], hdi_prob=0.94)
        overlap = max(0.0, min(ha, hb) - max(la, lb)) / (max(ha, hb) - min(la, lb))
        assert overlap > 0.5, (name, (la, ha), (lb, hb))
        if name in ("eta", "P_eff"):
            assert abs(np.mean(a[name]) - np.mean(b[name])) < 0.5 * np.std(b[name]), name


def test_cli_sample_writes_posterior_files(tmp_path):
    from bayes_update.cli import main

    out = tmp_path / "post"
    assert main(["sample", "--model", "rom", "--quick", "--out", str(out), "--workers", "2", "--no-cache"]) == 0
    for name in ("posterior.nc", "posterior_summary.json", "corner.png", "traces.png", "predictive.png",
                 "ridge.png", "gp_diagnostics.png"):
        assert (out / name).exists(), name
    summary = json.loads((out / "posterior_summary.json").read_text())
    assert summary["parameters"]["P_eff"]["units"] == "N"
    assert main(["sample", "--modes", "4", "--quick", "--out", str(out)]) == 2   # --modes needs --model rom
    assert main(["sample", "--prior", "G=1:2", "--quick", "--out", str(out)]) == 2
    assert main(["sample", "--prior", "F=95:20", "--quick", "--out", str(out)]) == 2


def test_whitening_round_trip_and_box_cut_fraction(data):
    from bayes_update.posterior import Whitening, _box_cut_fraction

    space = ParameterSpace(data.rig)
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
    U[0, 0] = 3.9                                  # eta direction, inside the prior beyond: cut
    assert _box_cut_fraction(U, 4.0, w, space) == pytest.approx(0.25)
    assert _box_cut_fraction(np.zeros((4, 4)), 4.0, w, space) == 0.0
