"""RFF / pathwise posterior samples of SE and ARD-SE GPs with explicit bases (crgpr.gp.sampling).

Small synthetic problems: exact formulas (R&W eq. 2.42) are the reference.
"""

from __future__ import annotations

import numpy as np
import pytest

from crgpr.gp import GP, fit_gp
from crgpr.gp.sampling import (
    CompressedSamples,
    compress,
    compression_error,
    draw_rff,
    exact_posterior,
    inducing_indices,
    pathwise_covariance,
    pathwise_samples,
    posterior_from_gp,
    reduce_update_rank,
    sparse_posterior,
    weight_space_samples,
)
from crgpr.gp.sparse import pivoted_cholesky
from crgpr.io import load_npz, write_npz


def _problem(basis: str, ard: bool, seed: int = 0, n: int = 120):
    rng = np.random.default_rng(seed)
    X = rng.uniform(-2.0, 2.0, (n, 2)) * [1.0, 3.0] + [0.5, 1.0]
    y = 4.0 * np.sin(1.5 * X[:, 0]) + 0.3 * X[:, 1] ** 2 + 0.1 * rng.standard_normal(n)
    mu, sd = X.mean(0), X.std(0)
    ell = [0.6, 0.9] if ard else [0.7, 0.7]
    spec = GP.from_standardised((X - mu) / sd, (y - y.mean()) / y.std(), 1.1, ell, 0.05, basis, mu, sd,
                  float(y.mean()), float(y.std()))
    # test inputs: inside the data, at its edge and outside it (prior reversion)
    xt = np.vstack([X[:3] + 0.05, rng.uniform(-3.0, 3.0, (9, 2)) * [1.0, 3.0] + [0.5, 1.0]])
    return spec, xt


@pytest.mark.parametrize(("basis", "ard"), [("none", False), ("constant", True),
                                             ("pure_quadratic", True)])
def test_sample_moments_match_exact_posterior(basis: str, ard: bool) -> None:
    """Many pathwise samples: mean, variance and covariance of f equal the exact GP posterior
    (incl. the basis-coefficient posterior) within Monte Carlo error. Each sample has its own
    RFF draw, so this holds even for few features (D = 64): no RFF bias in the ensemble."""
    spec, xt = _problem(basis, ard)
    post = exact_posterior(spec)
    mean, var = post.mean_var(xt)
    C = post.cov(xt)
    S = 4000
    smp = pathwise_samples(post, S, 64, np.random.default_rng(1))
    f = smp(xt)
    sd = np.sqrt(var)
    # mean: MC standard error sd / sqrt(S); 5 standard errors over 12 points
    assert np.all(np.abs(f.mean(0) - mean) < 5.0 * sd / np.sqrt(S))
    # variance: MC relative standard error sqrt(2 / S) = 2.2 % (Gaussian); 5 of them
    rel = f.var(0, ddof=1) / var - 1.0
    assert np.all(np.abs(rel) < 5.0 * np.sqrt(2.0 / S)), rel
    # joint samples: the full covariance, not just the diagonal
    Cs = np.cov(f.T)
    assert np.abs(Cs - C).max() < 6.0 * np.sqrt(2.0 / S) * var.max()


def test_basis_posterior_is_part_of_the_sample() -> None:
    """Far from the data the basis uncertainty dominates: dropping it underestimates the
    variance, keeping it reproduces R&W 2.42."""
    spec, _ = _problem("pure_quadratic", True)
    post = exact_posterior(spec)
    x_far = np.array([[6.0, 12.0], [-5.0, -10.0]])
    _, var = post.mean_var(x_far)
    C = pathwise_covariance(post, draw_rff(spec, 20000, np.random.default_rng(3)), x_far)
    np.testing.assert_allclose(np.diag(C), var, rtol=0.05)
    post.beta_cov[:] = 0.0
    C0 = pathwise_covariance(post, draw_rff(spec, 20000, np.random.default_rng(3)), x_far)
    assert np.all(np.diag(C0) < 0.5 * var)


def test_covariance_converges_with_number_of_features() -> None:
    """D -> large: the closed-form covariance of the pathwise sampler tends to the exact one
    (error ~ D^-1/2), averaged over feature draws."""
    spec, xt = _problem("constant", True)
    post = exact_posterior(spec)
    C = post.cov(xt)
    rng = np.random.default_rng(5)
    errs = []
    for D in (16, 256, 4096):
        e = [np.abs(pathwise_covariance(post, draw_rff(spec, D, rng), xt) - C).max() for _ in range(4)]
        errs.append(np.mean(e))
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 0.25 * errs[0]
    assert errs[2] < 0.05 * np.diag(C).max()


def test_weight_space_sampler_starves_variance() -> None:
    """The paper's weight-space sampler underestimates the variance away from the data
    (variance starvation, Wilson et al. 2020): the documented reason for choosing pathwise
    conditioning, which gets it right with the same number of features."""
    spec, _ = _problem("none", False, n=200)
    post = exact_posterior(spec)
    x_far = np.array([[3.5, 1.0], [0.5, 9.0], [-2.5, -6.0]])
    _, var = post.mean_var(x_far)
    rff, beta, w = weight_space_samples(spec, 2000, 40, np.random.default_rng(2))
    assert beta.shape == (2000, 0)
    f_ws = spec.to_output(w @ rff(spec.standardise(x_far)).T)
    assert np.all(f_ws.var(0) < 0.3 * var)
    f_pw = pathwise_samples(post, 2000, 40, np.random.default_rng(2))(x_far)
    assert np.all(f_pw.var(0) > 0.5 * var)


def test_compression_converges_and_roundtrips(tmp_path) -> None:
    """The inducing-point compression of the update term: error falls with M and is tiny
    when Z spans K_XX; the compressed samples survive an npz round trip."""
    spec, xt = _problem("pure_quadratic", True)
    post = exact_posterior(spec)
    smp = pathwise_samples(post, 5, 300, np.random.default_rng(4))
    errs = []
    for M in (10, 40, 120):
        comp = compress(smp, inducing_indices(spec, M, 0))
        errs.append(compression_error(smp, comp, xt)["max_rel_sd"])
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-2
    write_npz(tmp_path / "c.npz", **comp.to_arrays())
    back = CompressedSamples.from_arrays(load_npz(tmp_path / "c.npz"))
    x3 = np.broadcast_to(xt, (5, *xt.shape))
    np.testing.assert_allclose(back(x3), comp(x3), rtol=1e-12, atol=1e-12)


def test_from_fitted_gp_matches_gp_predictions() -> None:
    """posterior_from_gp reuses crgpr.gp._gpr's factors: same mean and variance as GP.predict, and
    samples centre on it."""
    rng = np.random.default_rng(0)
    X = rng.uniform(-1.0, 1.0, (80, 3))
    y = 50.0 + 20.0 * X[:, 0] * X[:, 1] + np.cos(3.0 * X[:, 2]) + 0.01 * rng.standard_normal(80)
    gp = fit_gp(X, y, kernel="ard_se", basis="constant", n_restarts=1, seed=0)
    post = posterior_from_gp(gp, "toy")
    xt = rng.uniform(-1.2, 1.2, (6, 3))
    m, v = post.mean_var(xt)
    mg, vg = gp.predict(xt, return_var=True)
    np.testing.assert_allclose(m, mg, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(v, vg, rtol=1e-6, atol=1e-12)
    f = pathwise_samples(post, 2000, 2000, np.random.default_rng(1))(xt)
    assert np.all(np.abs(f.mean(0) - m) < 5.0 * np.sqrt(v) / np.sqrt(2000) + 1e-9)
    with pytest.raises(ValueError, match="SE"):
        from crgpr.gp import fit_gp as fg

        posterior_from_gp(fg(X, y, kernel="matern52", n_restarts=0), "m52")


@pytest.mark.parametrize("basis", ["none", "pure_quadratic"])
def test_sparse_pathwise_samples(basis: str) -> None:
    """DTC posterior on inducing inputs: equals the exact posterior when Z = X, converges as M
    grows, and its compressed joint samples have the DTC mean and variance (Monte Carlo)."""
    spec, xt = _problem(basis, True)
    post = exact_posterior(spec)
    mean, var = post.mean_var(xt)
    m_all, v_all = sparse_posterior(spec, spec.Xs).mean_var(xt)
    np.testing.assert_allclose(m_all, mean, atol=1e-4 * np.sqrt(var).max())
    np.testing.assert_allclose(v_all, var, rtol=1e-4)
    errs = []
    for M in (10, 30, 60):
        sp = sparse_posterior(spec, spec.Xs[inducing_indices(spec, M, 0)])
        m_s, v_s = sp.mean_var(xt)
        errs.append(np.abs(m_s - mean).max() / np.sqrt(var).max())
    assert errs[0] > errs[1] > errs[2]
    S = 3000
    comp = sp.sample(S, 100, np.random.default_rng(0))
    f = comp(np.broadcast_to(xt, (S, *xt.shape)))
    assert np.all(np.abs(f.mean(0) - m_s) < 5.0 * np.sqrt(v_s / S))
    assert np.all(np.abs(f.var(0, ddof=1) / v_s - 1.0) < 5.0 * np.sqrt(2.0 / S))


def test_compiled_cosine_and_sample_evaluation() -> None:
    """The polynomial cosine of the compiled RFF sums agrees with libm; compressed samples
    agree with a direct numpy evaluation of their formula."""
    from crgpr.gp.sampling import _rff_sum, se_kernel

    rng = np.random.default_rng(0)
    xs = rng.uniform(-3.0, 3.0, (2, 7, 3))
    omega = rng.standard_normal((2, 50, 3)) * 4.0
    phase = rng.uniform(0.0, 2 * np.pi, (2, 50))
    w = rng.standard_normal((2, 50))
    out = np.empty((2, 7))
    _rff_sum(xs, omega, phase, w, 0.3, out)
    ref = 0.3 * np.einsum("sj,smj->sm", w, np.cos(np.einsum("smd,sjd->smj", xs, omega) + phase[:, None]))
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-10)
    spec, xt = _problem("pure_quadratic", True)
    comp = sparse_posterior(spec, spec.Xs[:30]).sample(2, 50, rng)
    x3 = np.broadcast_to(xt, (2, *xt.shape))
    u = spec.standardise(xt)
    direct = np.stack([
        comp.beta[s] @ spec.basis_fn(u).T
        + np.sqrt(2.0 * comp.sigma_f**2 / 50) * np.cos(u @ comp.omega[s].T + comp.phase[s]) @ comp.w[s]
        + se_kernel(u, comp.Z, comp.sigma_f, comp.lengthscales) @ comp.a[s] for s in range(2)])
    np.testing.assert_allclose(comp(x3), spec.to_output(direct), rtol=1e-10, atol=1e-10 * spec.out_scale)


def test_pivoted_cholesky_reproduces_the_matrix_to_its_tolerance() -> None:
    """K ~ L L^T with the residual diagonal below tol max(diag K); L[P] lower triangular."""
    rng = np.random.default_rng(3)
    X = rng.uniform(-1.0, 1.0, (200, 2))
    K = np.exp(-0.5 * ((X[:, None] - X[None]) ** 2).sum(-1) / 0.8**2)
    for tol in (1e-4, 1e-10):
        piv, L = pivoted_cholesky(K, tol)
        assert len(set(piv)) == len(piv) < 200
        assert np.allclose(np.triu(L[piv], 1), 0.0)
        assert np.max(np.diag(K - L @ L.T)) <= tol * (1 + 1e-6)
        np.testing.assert_allclose(L @ L[piv].T, K[:, piv], atol=1e-12)


@pytest.mark.parametrize(("ell", "reduced"), [(8.0, True), (0.05, False)])
def test_update_rank_reduction_keeps_the_samples(ell: float, reduced: bool) -> None:
    """A smooth kernel's update term k(u, Z) a_s lives on a few pivots of Z: the reduced samples
    equal the full ones to a small fraction of the posterior sd; a rough kernel keeps ~all of Z."""
    rng = np.random.default_rng(4)
    X = rng.uniform(-2.0, 2.0, (300, 2))
    y = np.sin(X[:, 0]) + 0.2 * X[:, 1] + 0.01 * rng.standard_normal(300)
    spec = GP.from_standardised(X, y, 1.0, [ell, ell], 0.01, "constant", np.zeros(2), np.ones(2), 0.0, 1.0)
    sp = sparse_posterior(spec, X[inducing_indices(spec, 100, 0)])
    comp = sp.sample(8, 64, np.random.default_rng(1))
    red = reduce_update_rank(comp, 1e-14)
    assert (red.Z.shape[0] <= 40) == reduced
    xt = rng.uniform(-2.0, 2.0, (150, 2))
    _, var = sp.mean_var(xt)
    err = np.abs(red(np.broadcast_to(xt, (8, *xt.shape))) - comp(np.broadcast_to(xt, (8, *xt.shape))))
    assert np.max(err / np.sqrt(var)) < 1e-3
