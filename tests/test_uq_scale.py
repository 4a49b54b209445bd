"""The sampled posterior's scale from held-out time blocks (``uq.posterior_scale``,
crgpr.gp.sampling.heldout_block_scale / scaled_spec): scaling sigma_f and sigma_n together keeps
the posterior mean and multiplies the posterior covariance by c^2; blocked cross-validation gives
c ~ 1 for data the GP's own model generated and c >> 1 when the targets carry a smooth error
correlated along the trajectory (the prefilter's bias), which an iid noise term averages away."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from crgpr.gp import GP
from crgpr.gp.sampling import (
    exact_posterior,
    heldout_block_scale,
    scaled_spec,
    se_kernel,
    sparse_posterior,
    split_noise_scale,
)
from crgpr.uq.samples import draw_model_samples
from crgpr.uq.settings import UQSettings

SETTINGS = UQSettings(methods=("m",), sampler="sparse_pathwise", n_samples=6, paper_n_samples=4,
                      n_features=64, inducing=40, levels=(50.0, 95.0), angles_deg=(125,),
                      figure_angle_deg=125, figure_level=95.0, figure_time_fractions=(1.0,),
                      exact_check_max_n=300, check_points=50, posterior_scale="heldout_rms",
                      heldout_blocks=8, kernel_tol=0.0, update_rank_tol=0.0, update_rank_max_error=1.0e-4,
                      tabulated_exact_max_n=4000)


def _trajectory_gp(n: int, seed: int, bias: float, basis: str = "linear") -> GP:
    """A GP on inputs along a periodic 2D 'trajectory' x(t) (rows in time order, as the gradient
    GPs' training rows), targets = a draw of that GP's own prior (sigma_f = 1, ell = 0.7,
    sigma_n = 0.05) plus ``bias`` x a smooth function of time (a correlated target error)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    U = np.stack([np.cos(20 * t), np.sin(13 * t)], 1) * 2.0  # a Lissajous orbit: states revisited
    K = se_kernel(U, U, 1.0, np.array([0.7, 0.7])) + 1e-8 * np.eye(n)
    f = np.linalg.cholesky(K) @ rng.standard_normal(n)
    y = f + 0.05 * rng.standard_normal(n) + bias * np.sin(40 * t + 1.0)
    return GP.from_standardised(U, y, 1.0, np.array([0.7, 0.7]), 0.05, basis, np.zeros(2), np.ones(2),
                                0.3, 2.0, "synthetic")


def test_scaled_spec_keeps_the_mean_and_scales_the_covariance() -> None:
    """Exact posterior (basis part included): mean unchanged to round-off, variance x c^2. Sparse
    sampler with the same random stream: every sample's deviation from the mean x c exactly."""
    spec, c = _trajectory_gp(300, 0, 0.0), 3.7
    x = np.random.default_rng(1).uniform(-3, 3, (40, 2))
    m1, v1 = exact_posterior(spec).mean_var(x)
    mc, vc = exact_posterior(scaled_spec(spec, c)).mean_var(x)
    np.testing.assert_allclose(mc, m1, rtol=1e-9, atol=1e-9 * np.abs(m1).max())
    np.testing.assert_allclose(vc, c**2 * v1, rtol=1e-6)
    Z = spec.Xs[::10]
    f = {}
    for k, s in (("1", spec), ("c", scaled_spec(spec, c))):
        sp = sparse_posterior(s, Z)
        f[k] = sp.sample(5, 32, np.random.default_rng(7))(np.broadcast_to(x, (5, *x.shape)))
        f[k + "mean"] = sp.mean_var(x)[0]
    np.testing.assert_allclose(f["cmean"], f["1mean"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(f["c"] - f["cmean"], c * (f["1"] - f["1mean"]), rtol=0, atol=1e-7)
    with pytest.raises(ValueError, match="posterior scale"):
        scaled_spec(spec, 0.0)


def test_heldout_blocks_calibrate_a_correct_model_and_widen_a_correlated_error() -> None:
    """Data from the GP's own model: c within [0.8, 1.5] for both statistics, rms and the robust
    median |z| / 0.6745 (deterministic seeds; ~600 held-out
    z, correlated within a block; c >= ~1 by construction, since noisy targets are compared with
    the latent predictive, which is conservative by sqrt(1 + sigma_n^2 / v)). The same data
    plus a smooth error of 0.8 (16 sigma_n) along time that is no function of the state (the
    orbit revisits its states): c > 1.8, the unscaled held-out 95 % coverage below 0.7, the
    scaled one above 0.9."""
    for seed in (0, 1, 2):
        for stat in ("rms", "median"):
            c, info = heldout_block_scale(_trajectory_gp(600, seed, 0.0), 8, statistic=stat)
            assert 0.8 < c < 1.5, (seed, stat, c)
            assert len(info["heldout_block_rms_z"]) == 8
    spec = _trajectory_gp(600, 0, 0.8)
    c, info = heldout_block_scale(spec, 8, statistic="rms")
    assert c > 1.8 and info["heldout_scale_median"] > 1.5
    assert info["heldout_coverage95_unscaled"] < 0.7 and info["heldout_coverage95_scaled"] > 0.9
    c_sparse, _ = heldout_block_scale(spec, 8, spec.Xs[::5], "rms")  # DTC posterior, 120 inducing inputs
    assert c_sparse == pytest.approx(c, rel=0.25)
    with pytest.raises(ValueError, match="held-out blocks"):
        heldout_block_scale(spec, 1)
    with pytest.raises(ValueError, match="statistic"):
        heldout_block_scale(spec, 8, statistic="mean")


def test_sampled_deviations_carry_the_heldout_scale() -> None:
    """draw_model_samples with uq.posterior_scale = heldout_rms: the samples' deviations from
    the posterior mean are exactly c times those of posterior_scale = none (same seed), c is
    recorded in the diagnostics; the mean the samples scatter around is unchanged."""
    spec = _trajectory_gp(400, 3, 0.8)
    x = np.random.default_rng(2).uniform(-2, 2, (30, 2))
    xb = np.broadcast_to(x, (SETTINGS.n_samples, *x.shape))
    comp_c, info = draw_model_samples(spec, SETTINGS, 5)
    comp_1, info1 = draw_model_samples(spec, dataclasses.replace(SETTINGS, posterior_scale="none"), 5)
    c = info["posterior_scale"]
    assert c > 1.5 and info1["posterior_scale"] == 1.0
    m = sparse_posterior(spec, comp_1.Z).mean_var(x)[0]
    np.testing.assert_allclose(comp_c(xb) - m, c * (comp_1(xb) - m), rtol=0, atol=1e-7 * c)


def test_truncated_sample_kernel_sums_agree_within_their_bound() -> None:
    """uq.kernel_tol: the sampled functions with kernel sums truncated below 1e-16 sigma_f^2 (cell
    grid) equal the dense sums within the recorded bound plus round-off, where most centre-input
    pairs are actually skipped (short lengthscale); ``select_samples`` keeps the truncation."""
    from crgpr.uq.samples import select_samples

    base = _trajectory_gp(500, 4, 0.0)
    spec = GP.from_standardised(base.Xs, base.y, 1.0, np.array([0.12, 0.2]), 0.05, "linear", np.zeros(2),
                                np.ones(2), 0.3, 2.0, "short")
    Z = spec.Xs[::4]
    comp = sparse_posterior(spec, Z).sample(5, 64, np.random.default_rng(3))
    tr = comp.truncate(1e-16)
    x = np.random.default_rng(4).uniform(-2.2, 2.2, (5, 200, 2))
    r2 = (((x[:, :, None, :] - Z[None, None]) / spec.ell) ** 2).sum(-1)
    assert np.mean(r2 > 2 * np.log(1e16)) > 0.5  # most terms are below the tolerance
    dense, fast = comp(x), tr(x)
    assert 0 < tr.truncation_bound < 1e-9 * np.abs(dense).max()
    np.testing.assert_allclose(fast, dense, rtol=0, atol=tr.truncation_bound + 1e-12 * np.abs(dense).max())
    sel = select_samples(tr, np.array([0, 3]))
    assert sel.kernel_tol == 1e-16
    np.testing.assert_allclose(sel(x[[0, 3]]), fast[[0, 3]], rtol=0, atol=1e-13 * np.abs(dense).max())


def test_split_noise_scale_recovers_the_function_and_the_target_error() -> None:
    """r_i ~ N(0, c^2 v_i + s^2) with v_i spread over six decades (as the held-out latent
    variances between interpolated and extrapolated blocks): the maximum-likelihood (c, s) of
    ``split_noise_scale`` within 10 % of the truth for 4000 residuals (the MLE's relative sd is
    ~2-3 % here: a >3 sd margin, fixed seeds); a target error that dominates the residual (s^2 =
    25 c^2 v at the median v) is not taken for function error, and s = 0 is found as ~0."""
    for seed, (c, s) in enumerate([(1.0, 0.5), (0.2, 1.0), (3.0, 0.3), (1.0, 0.0)]):
        rng = np.random.default_rng(seed)
        v = np.exp(rng.uniform(-7.0, 7.0, 4000))
        r = rng.standard_normal(v.size) * np.sqrt(c**2 * v + s**2)
        c_hat, s_hat = split_noise_scale(r, v)
        assert c_hat == pytest.approx(c, rel=0.1), (seed, c_hat)
        if s > 0:
            assert s_hat == pytest.approx(s, rel=0.1), (seed, s_hat)
        else:
            assert s_hat < 0.05 * c * np.sqrt(np.median(v)), (seed, s_hat)
    with pytest.raises(ValueError, match="residuals"):
        split_noise_scale(np.ones(5), np.ones(4))


def test_heldout_split_separates_the_target_noise_from_the_function_error() -> None:
    """uq.posterior_scale = heldout_split on data from the GP's own model (iid target noise
    sigma_n = 0.05 std = 0.1 in output units): the latent scale c within [0.8, 1.35] and the
    target error s within [0.07, 0.13] for three seeds; the latent predictive alone (rms z) reads
    the target noise as function error (c_rms > c_split). With the smooth time-correlated target
    error of the test above, part of it is assigned to s: c_split < c_rms (measured 1.4-1.9 vs
    2.1-2.4)."""
    for seed in (0, 1, 2):
        c, info = heldout_block_scale(_trajectory_gp(600, seed, 0.0), 8, statistic="split")
        assert 0.8 < c < 1.35, (seed, c)
        assert 0.07 < info["heldout_target_error_split"] < 0.13, (seed, info)
        assert info["heldout_scale_rms"] > c
        c_b, info_b = heldout_block_scale(_trajectory_gp(600, seed, 0.8), 8, statistic="split")
        assert c_b < info_b["heldout_scale_rms"] and info_b["heldout_target_error_split"] > 0.15


def test_scaled_sparse_posterior_equals_the_scaled_gp_refactorised() -> None:
    """SparsePosterior.scaled(c) (no new factorisation) is the DTC posterior of scaled_spec(spec, c):
    mean and variance at new inputs to round-off, and the same samples from the same stream."""
    spec, c = _trajectory_gp(300, 5, 0.0), 0.173
    Z = spec.Xs[::6]
    x = np.random.default_rng(8).uniform(-3, 3, (25, 2))
    a, b = sparse_posterior(spec, Z).scaled(c), sparse_posterior(scaled_spec(spec, c), Z)
    (ma, va), (mb, vb) = a.mean_var(x), b.mean_var(x)
    np.testing.assert_allclose(ma, mb, rtol=0, atol=1e-9 * np.abs(mb).max())
    np.testing.assert_allclose(va, vb, rtol=1e-7)
    xb = np.broadcast_to(x, (4, *x.shape))
    fa, fb = a.sample(4, 32, np.random.default_rng(2))(xb), b.sample(4, 32, np.random.default_rng(2))(xb)
    np.testing.assert_allclose(fa, fb, rtol=0, atol=1e-7 * np.abs(fb).max())
    with pytest.raises(ValueError, match="posterior scale"):
        sparse_posterior(spec, Z).scaled(-1.0)


def _linear_law_with_block_error(n: int, seed: int, amp: float = 1.0, ell_t: float = 0.02,
                                 sigma_n: float = 30.0, L: np.ndarray | None = None) -> tuple[GP, np.ndarray]:
    """The obj_m situation in miniature: a linear law y = [1, u]^T beta along a damped 3D orbit
    u(t) (rows in time order), targets with a smooth error of size ``amp`` and correlation time
    ``ell_t`` (the prefilter's smoothing error: no function of the state), fitted by a GP with a
    linear basis, the kernel nearly off (sigma_f 0.01) and a noise level ``sigma_n`` far above the
    error (a floor; ``L``: the Cholesky factor of its time kernel, if already computed). Returns the
    GP and the true beta."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, n)
    env = np.exp(-2.0 * t)
    U = np.stack([env * np.cos(25 * t), 0.7 * env * np.sin(17 * t), 0.5 * env * np.cos(9 * t + 0.3)], 1)
    beta = np.array([0.2, 3.0, -1.0, 0.5])
    if L is None:
        L = np.linalg.cholesky(np.exp(-0.5 * ((t[:, None] - t[None]) / ell_t) ** 2) + 1e-8 * np.eye(n))
    y = np.hstack([np.ones((n, 1)), U]) @ beta + amp * (L @ rng.standard_normal(n))
    return (GP.from_standardised(U, y, 0.01, np.full(3, 50.0), sigma_n, "linear", np.zeros(3), np.ones(3),
                                 0.0, 1.0, "linear_law"), beta)


def test_jackknife_scale_calibrates_a_linear_law_whose_targets_carry_a_correlated_error() -> None:
    """uq.posterior_scale = heldout_jackknife. 150 replications of ``_linear_law_with_block_error``:
    the law's error at three new states (one beyond the orbit) over the posterior sd scaled by c.
    The held-out residual scales (median, rms) measure the targets' error, not the law's, and give
    bands several times too wide (95 % coverage of the true law > 0.99, median |z| < 0.35 against a
    calibrated 0.674); the jackknife measures the spread of the law itself: 95 % coverage within
    [0.85, 0.99] and median |z| within [0.5, 0.9] (expected for a scale estimated from 8 blocks:
    ~0.93, between the normal's 0.95 and the t distribution with 7 dof's 0.91; measured 95 % / 50 %
    coverage 0.918 / 0.504 and median |z| 0.667 in this deterministic setup, against 1.000 / 0.884
    / 0.273 with the held-out median scale; the binomial sd of the coverage over 450 correlated z
    is < 0.02, so the bounds are > 3 sd away). Unscaled, the noise floor makes the band far too
    wide (median |z| 0.09)."""
    xt = np.array([[1.2, 0.5, -0.4], [-0.8, -0.6, 0.5], [0.3, 0.2, 0.1]])
    z: dict[str, list[np.ndarray]] = {"none": [], "median": [], "rms": [], "jackknife": []}
    for r in range(150):
        spec, beta = _linear_law_with_block_error(400, r)
        full = exact_posterior(spec)
        c, info = heldout_block_scale(spec, 8, None, "jackknife", 400, full)
        assert c == info["heldout_scale_jackknife"] == info["posterior_scale"]
        m, v = full.mean_var(xt)
        zr = (np.hstack([np.ones((3, 1)), xt]) @ beta - m) / np.sqrt(v)
        for k, cc in (("none", 1.0), ("median", info["heldout_scale_median"]),
                      ("rms", info["heldout_scale_rms"]), ("jackknife", c)):
            z[k].append(zr / cc)
    cov = {k: float(np.mean(np.abs(np.concatenate(v)) < 1.959964)) for k, v in z.items()}
    med = {k: float(np.median(np.abs(np.concatenate(v)))) for k, v in z.items()}
    assert 0.85 <= cov["jackknife"] <= 0.99 and 0.5 <= med["jackknife"] <= 0.9, (cov, med)
    for k in ("none", "median", "rms"):
        assert cov[k] > 0.99 and med[k] < 0.35, (k, cov, med)


def _sparse_linear_law(seed: int, L: np.ndarray) -> tuple[GP, np.ndarray]:
    """``_linear_law_with_block_error`` (400 rows, error correlation time 0.02 against blocks of
    0.125; ``L`` the Cholesky factor of the error's time kernel, shared by the replications) with
    every 20th input as the inducing set of the sparse (DTC) posterior."""
    spec, beta = _linear_law_with_block_error(400, seed, L=L)
    return spec, spec.Xs[::20]


R_JK = 100


def test_jackknife_covariance_recovers_the_law_coefficient_covariance_under_block_errors() -> None:
    """uq.posterior_scale = jackknife_covariance (``SparsePosterior.sample(jackknife=...)``).

    Truth: the posterior mean is linear in the targets, theta_hat = W y, so under the targets'
    error covariance Sigma (amp^2 x the SE time kernel of ``_linear_law_with_block_error``) its
    exact covariance is W Sigma W^T. (1) Over 100 replications the sampler's covariance of the
    basis coefficients (C_jk + P^-1 Lambda P^-1, 8 time blocks) averages to the truth: every
    diagonal ratio within [0.8, 1.5]. The delete-a-block jackknife is conservative (Efron & Stein
    1981: its expectation is >= the variance), here by the blocks' unequal leverage (the orbit's
    amplitude decays 7x over the run): measured 1.08-1.30 (1.04-1.32 with 200 replications); a
    7-dof estimate has relative sd sqrt(2 / 7) = 0.53, the mean of 100 ~0.05, so the bounds are
    >= 3.5 sd from the measured means (false-alarm rate < 1e-3). The fitted posterior P^-1 (noise
    floor 30x above the error) is > 5x too large in every coefficient: the check can fail.
    (2) The drawn samples have that covariance: 4000 samples' basis coefficients and their values
    at three states match it within 5 sd of a variance estimate, 5 sqrt(2 / 4000) = 11 %
    (false-alarm rate < 1e-5 for the 7 checks together)."""
    B, p, n = 8, 4, 400
    t = np.linspace(0.0, 1.0, n)
    Sigma = np.exp(-0.5 * ((t[:, None] - t[None]) / 0.02) ** 2) + 1e-8 * np.eye(n)
    L = np.linalg.cholesky(Sigma)
    spec0, Z = _sparse_linear_law(0, L)
    post0 = sparse_posterior(spec0, Z)
    # W: the posterior mean as a linear map of the targets (the same inputs in every replication)
    F = post0.features(spec0.Xs) / spec0.sigma_n**2
    W = np.linalg.solve(post0.RP.T @ post0.RP, F.T)[:p]  # (p, n)
    true = W @ Sigma @ W.T
    ratios, post_ratio = [], None
    for r in range(R_JK):
        spec, Z = _sparse_linear_law(r, L)
        post = sparse_posterior(spec, Z)
        coeffs: list[np.ndarray] = []
        heldout_block_scale(spec, B, Z, "jackknife", 50, post, coeffs)
        C = post.jackknife_covariance(np.asarray(coeffs))[:p, :p]
        ratios.append(np.diag(C) / np.diag(true))
        if r == 0:
            Pi = np.linalg.inv(post.RP.T @ post.RP)[:p, :p]
            post_ratio = np.diag(Pi) / np.diag(true)
            J0, C0, full0 = np.asarray(coeffs), post.jackknife_covariance(np.asarray(coeffs)), post
    mean_ratio = np.mean(ratios, axis=0)
    assert np.all((mean_ratio > 0.8) & (mean_ratio < 1.5)), mean_ratio
    assert np.all(post_ratio > 5.0), post_ratio
    S = 4000
    comp = full0.sample(S, 16, np.random.default_rng(1), J0)
    tol = 5.0 * np.sqrt(2.0 / S)
    np.testing.assert_allclose(np.var(comp.beta, axis=0) / np.diag(C0)[:p], 1.0, atol=tol)
    xt = np.array([[0.4, 0.2, -0.1], [-0.3, 0.3, 0.2], [0.8, -0.5, 0.4]])  # the last beyond the orbit
    f = comp(np.broadcast_to(xt, (S, *xt.shape)))
    m, v = full0.mean_var(xt, J0)
    np.testing.assert_allclose(np.var(f, axis=0) / v, 1.0, atol=tol)
    assert np.all(np.abs(f.mean(0) - m) < 5.0 * np.sqrt(v / S))
