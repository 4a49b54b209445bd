"""gp.KernelMean.exact: a fitted GP's exact posterior mean over all n points, with the kernel
sums truncated below tol sigma_f^2 on a cell grid."""

from __future__ import annotations

import numpy as np
import pytest

from crgpr.gp import KernelMean, cutoff_radius, exact_weights, fit_gp, load_evaluator


def _dense_mean(gp, Xs):
    """R&W eq. (2.41) written out with dense matrices (numpy solve, no Cholesky reuse)."""
    from crgpr.gp import basis_matrix_std, kernel_matrix

    U, Us = gp.Xs, gp.standardise_x(Xs)
    K = kernel_matrix(gp.kernel, U, U, gp.sigma_f, gp.ell) + gp.sigma_n**2 * np.eye(gp.n)
    H, Hs = basis_matrix_std(gp.basis, U), basis_matrix_std(gp.basis, Us)
    v = gp.y
    Kiv = np.linalg.solve(K, v)
    if H.shape[1]:
        KiH = np.linalg.solve(K, H)
        beta = np.linalg.solve(H.T @ KiH, H.T @ Kiv)
        alpha = Kiv - KiH @ beta
        g = kernel_matrix(gp.kernel, Us, U, gp.sigma_f, gp.ell) @ alpha + Hs @ beta
    else:
        g = kernel_matrix(gp.kernel, Us, U, gp.sigma_f, gp.ell) @ Kiv
    return gp.out_mean + gp.out_scale * g


@pytest.mark.parametrize(("kernel", "basis", "d", "ell"),
                         [("se", "pure_quadratic", 3, 0.4), ("se", "constant", 6, 0.3),
                          ("matern52", "none", 2, 0.4), ("se", "none", 1, 0.2), ("se", "constant", 6, 0.05)])
def test_exact_mean_equals_dense_posterior_mean(kernel, basis, d, ell, tmp_path):
    rng = np.random.default_rng(3)
    n = 400
    X = rng.uniform(-2, 2, (n, d)) * (1 + np.arange(d))
    y = np.sin(X).sum(1) + 0.3 * X[:, 0] ** 2 + 0.01 * rng.standard_normal(n)
    gp = fit_gp(X, y, kernel=kernel, basis=basis, ard=d > 1, n_restarts=0, seed=1, factorise=False,
                fixed={"sigma_f": 1.3, "lengthscales": np.full(d if d > 1 else 1, ell), "sigma_n": 0.05})
    ev = KernelMean.exact(gp, tol=1e-12)
    Xs = rng.uniform(-2.5, 2.5, (300, d)) * (1 + np.arange(d))
    Xs[:50] = X[:50] + 1e-3  # near the data, where the sums are largest
    dense = _dense_mean(gp, Xs)
    got = ev(Xs)
    assert np.max(np.abs(got - dense)) <= 1e-10 * np.max(np.abs(dense))
    assert np.max(np.abs(got - ev.dense()(Xs))) <= ev.truncation_bound
    # the saved weights load as the same evaluator
    alpha, beta = exact_weights(gp)
    gp.save(tmp_path / "m", extra={"name": "m", "exact_tol": 1e-12},
            extra_arrays={"mean_alpha": alpha, "mean_beta": beta})
    loaded = load_evaluator(tmp_path / "m")
    assert loaded.kind == "exact" and np.array_equal(loaded(Xs), got)
    if d == 1:
        _, d1, _ = gp.predict_derivatives(Xs[:, 0])
        np.testing.assert_allclose(ev.slope(Xs[:, 0]), d1, rtol=1e-8, atol=1e-10 * np.abs(d1).max())
        assert ev(Xs[:, 0]).shape == (300,)
    else:
        assert ev(Xs.reshape(3, 100, d)).shape == (3, 100)


def test_truncation_skips_far_centres_only():
    """With a short lengthscale most centres are beyond the cutoff, the result is unchanged."""
    rng = np.random.default_rng(0)
    X = rng.uniform(0, 10, (2000, 2))
    gp = fit_gp(X, np.sin(X[:, 0]) * np.cos(X[:, 1]), kernel="se", basis="constant", ard=True,
                factorise=False, fixed={"sigma_f": 1.0, "lengthscales": [0.02, 0.02], "sigma_n": 0.1})
    ev = KernelMean.exact(gp, tol=1e-12)
    Xs = rng.uniform(0, 10, (200, 2))
    np.testing.assert_allclose(ev(Xs), ev.dense()(Xs), rtol=0, atol=max(ev.truncation_bound, 1e-14))


def test_cutoff_radius_is_the_tolerance():
    r = cutoff_radius("se", 1e-12)
    assert np.isclose(np.exp(-0.5 * r * r), 1e-12)
    r = cutoff_radius("matern52", 1e-12)
    v = (1 + np.sqrt(5) * r + 5 / 3 * r * r) * np.exp(-np.sqrt(5) * r)
    assert np.isclose(v, 1e-12, rtol=1e-6)
    assert cutoff_radius("se", 0.0) == np.inf


@pytest.mark.parametrize(("kernel", "basis", "ell"), [("se", "linear", 20.0), ("matern52", "constant", 200.0),
                                                      ("se", "pure_quadratic", 5.0)])
def test_low_rank_exact_weights_equal_the_dense_posterior_mean(kernel, basis, ell):
    """Long lengthscales (a kernel matrix of small numerical rank, as obj_m's): exact_weights
    takes the pivoted-Cholesky-preconditioned CG path and gives the same exact mean (1e-10)."""
    import crgpr.gp.evaluators as ev

    rng = np.random.default_rng(5)
    n, d = 600, 3
    X = rng.uniform(-1, 1, (n, d))
    y = 2.0 * X[:, 0] - X[:, 1] + 0.05 * np.sin(2 * X[:, 2]) + 0.01 * rng.standard_normal(n)
    gp = fit_gp(X, y, kernel=kernel, basis=basis, ard=True, n_restarts=0, seed=1, factorise=False,
                fixed={"sigma_f": 1.0, "lengthscales": np.full(d, ell), "sigma_n": 0.02})
    Ul = np.ascontiguousarray(gp.Xs / gp.ell)
    B = np.column_stack([gp.y, ev.basis_matrix_std(gp.basis, gp.Xs)])
    assert ev._lowrank_solve(Ul, ev.KERNEL_ID[kernel], gp.sigma_f**2, gp.sigma_n**2, B) is not None
    Xs = rng.uniform(-1.5, 1.5, (200, d))
    ref = _dense_mean(gp, Xs)
    got = KernelMean.exact(gp, tol=0.0, weights=exact_weights(gp))(Xs)
    assert np.max(np.abs(got - ref)) <= 1e-10 * np.max(np.abs(ref))


def test_full_rank_kernels_fall_back_to_the_dense_factorisation():
    """Short lengthscales: the low-rank path declines (None) and the dense Cholesky is used."""
    import crgpr.gp.evaluators as ev

    rng = np.random.default_rng(6)
    Ul = rng.uniform(-20, 20, (800, 3))
    assert ev._lowrank_solve(Ul, 0, 1.0, 1e-4, np.ones((800, 1))) is None


def test_noise_at_round_off_falls_back_to_the_dense_factorisation():
    """sigma_n^2 / sigma_f^2 at 1e-12 on a low-rank kernel (a momentum GP with a tiny noise
    floor): the factor's residual trace is below what double precision resolves and CG breaks
    down (before the guard: a ValueError on non-finite iterates); the low-rank path declines
    (None) and exact_weights gives the dense Cholesky mean."""
    import crgpr.gp.evaluators as ev

    rng = np.random.default_rng(7)
    n = 3000
    X = np.sort(rng.uniform(0.0, 1.0, n))[:, None]
    y = np.sin(3.0 * X[:, 0])
    gp = fit_gp(X, y, kernel="se", basis="constant", ard=True, n_restarts=0, seed=1, factorise=False,
                fixed={"sigma_f": 1.0, "lengthscales": np.full(1, 2.0), "sigma_n": 1e-6})
    Ul = np.ascontiguousarray(gp.Xs / gp.ell)
    B = np.column_stack([gp.y, ev.basis_matrix_std(gp.basis, gp.Xs)])
    assert ev._lowrank_solve(Ul, 0, gp.sigma_f**2, gp.sigma_n**2, B) is None
    Xs = rng.uniform(0.0, 1.0, (100, 1))
    ref = _dense_mean(gp, Xs)
    got = KernelMean.exact(gp, tol=0.0, weights=exact_weights(gp))(Xs)
    assert np.max(np.abs(got - ref)) <= 1e-8 * np.max(np.abs(ref))
