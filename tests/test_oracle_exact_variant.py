"""Issue 11: the ``exact_dH_dtheta`` ablation variant integrates the fitted GP's EXACT posterior mean."""

from __future__ import annotations

import numpy as np

from crgpr.commands.oracle_ablation import exact_subset_mean
from crgpr.gp import fit_gp


def _dense_mean(gp, idx, Xs):
    """R&W eq. 2.41 with a constant basis, written out densely on the subset rows ``idx``."""
    ell = np.ravel(gp.lengthscales)
    U = (gp.X[idx] - gp.x_mean) / gp.x_scale / ell
    Us = (Xs - gp.x_mean) / gp.x_scale / ell
    v = (np.ravel(gp.Y[idx]) - gp.y_mean[0]) / gp.y_scale[0]
    sq = lambda A, B: ((A[:, None, :] - B[None, :, :]) ** 2).sum(-1)  # noqa: E731
    K = gp.sigma_f**2 * np.exp(-0.5 * sq(U, U)) + gp.sigma_n**2 * np.eye(len(idx))
    Ks = gp.sigma_f**2 * np.exp(-0.5 * sq(Us, U))
    h = np.ones((len(idx), 1))
    Ki_v, Ki_h = np.linalg.solve(K, v), np.linalg.solve(K, h)
    beta = np.linalg.solve(h.T @ Ki_h, h.T @ Ki_v)
    mean = beta[0] + Ks @ (Ki_v - Ki_h @ beta)
    return gp.y_mean[0] + gp.y_scale[0] * mean


def test_exact_variant_component_equals_dense_posterior_mean_on_subset(tmp_path):
    rng = np.random.default_rng(11)
    n, d = 500, 6  # dH/dtheta's six paper features, smoke size
    X = rng.normal(size=(n, d)) * np.array([1.5, 1.5, 1.5, 100.0, 0.5, 0.8])
    y = np.sin(X[:, 0]) - 0.01 * X[:, 3] + 0.05 * rng.standard_normal(n)
    gp = fit_gp(X, y, kernel="se", basis="constant", ard=True, n_restarts=0, seed=2,
                fixed={"sigma_f": 1.1, "lengthscales": np.array([0.8, 2.0, 3.0, 1.0, 4.0, 5.0]),
                       "sigma_n": 0.2})
    gp.save(tmp_path / "dH_dtheta")
    ev, idx = exact_subset_mean(tmp_path / "dH_dtheta", 120, seed=7, tol=1e-14)
    assert idx.size == 120 and np.unique(idx).size == 120 and np.all(np.diff(idx) > 0)
    Xs = rng.normal(size=(200, d)) * np.array([1.5, 1.5, 1.5, 100.0, 0.5, 0.8])
    dense = _dense_mean(gp, idx, Xs)
    assert np.max(np.abs(ev(Xs) - dense)) <= 1e-9 * np.max(np.abs(dense))
    # conditioning on the subset, not on all n points: the full-data mean differs
    assert np.max(np.abs(gp.predict(Xs) - dense)) > 1e-3 * np.max(np.abs(dense))
    # seeded: same seed, same subset; a subset larger than n is all n points
    _, idx2 = exact_subset_mean(tmp_path / "dH_dtheta", 120, seed=7, tol=1e-14)
    assert np.array_equal(idx, idx2)
    _, idx_all = exact_subset_mean(tmp_path / "dH_dtheta", 10 * n, seed=7, tol=1e-14)
    assert np.array_equal(idx_all, np.arange(n))
