"""GP regression (crgpr.gp._gpr) against closed forms (R&W Sec. 2.7) and finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import approx_fprime

from crgpr.gp._gpr import GP, _neg_lml, basis_matrix_std, fit_gp, kernel_matrix, smooth_series


def _hand_gp(U, v, Us, kernel, sf, ell, sn, Hfun):
    """R&W eqs. (2.41), (2.42) written out with dense inverses (tiny problems only)."""
    K = kernel_matrix(kernel, U, U, sf, ell) + sn**2 * np.eye(len(U))
    Ki = np.linalg.inv(K)
    H = Hfun(U).T  # (m, n) as in R&W
    Hs = Hfun(Us).T
    Ks = kernel_matrix(kernel, U, Us, sf, ell)  # (n, n*)
    beta = np.linalg.solve(H @ Ki @ H.T, H @ Ki @ v)
    mean = Ks.T @ Ki @ v + (Hs - H @ Ki @ Ks).T @ beta
    R = Hs - H @ Ki @ Ks
    cov = kernel_matrix(kernel, Us, Us, sf, ell) - Ks.T @ Ki @ Ks + R.T @ np.linalg.solve(H @ Ki @ H.T, R)
    return mean, np.diag(cov)


@pytest.mark.parametrize("basis", ["constant", "quadratic", "pure_quadratic", "linear"])
@pytest.mark.parametrize("kernel", ["se", "matern52"])
def test_basis_gp_matches_closed_form(basis, kernel):
    rng = np.random.default_rng(0)
    X = rng.uniform(-2, 3, size=(9, 2)) if basis != "quadratic" else rng.uniform(-2, 3, size=(9, 1))
    y = 3.0 + X[:, 0] ** 2 - 0.5 * X.sum(1) + 0.1 * rng.standard_normal(len(X))
    fixed = {"sigma_f": 0.7, "lengthscales": 0.9, "sigma_n": 0.2}
    gp = fit_gp(X, y, kernel=kernel, basis=basis, fixed=fixed)
    Xs = rng.uniform(-3, 4, size=(7, X.shape[1]))
    mean, var = gp.predict(Xs, return_var=True)
    U = gp.standardise_x(X)
    Us = gp.standardise_x(Xs)
    v = (y - gp.y_mean[0]) / gp.y_scale[0]
    m_ref, var_ref = _hand_gp(U, v, Us, kernel, 0.7, np.full(X.shape[1], 0.9), 0.2,
                              lambda A: basis_matrix_std(basis, A))
    np.testing.assert_allclose(mean, m_ref * gp.y_scale[0] + gp.y_mean[0], rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(var, var_ref * gp.y_scale[0] ** 2, rtol=1e-8, atol=1e-10)


def test_constant_basis_beta_is_gls_mean():
    """With a constant basis, beta_hat is the GLS mean 1^T K^-1 y / 1^T K^-1 1 (R&W 2.42)."""
    rng = np.random.default_rng(1)
    X = np.sort(rng.uniform(0, 1, 6))
    y = rng.standard_normal(6) + 5.0
    gp = fit_gp(X, y, kernel="se", basis="constant", standardise_y=False,
                fixed={"sigma_f": 1.3, "lengthscales": 0.5, "sigma_n": 0.3})
    U = gp.standardise_x(X)
    K = kernel_matrix("se", U, U, 1.3, np.array([0.5])) + 0.09 * np.eye(6)
    Ki = np.linalg.inv(K)
    one = np.ones(6)
    assert gp.beta[0, 0] == pytest.approx(one @ Ki @ y / (one @ Ki @ one), rel=1e-10)
    # far from the data the mean reverts to beta_hat
    assert gp.predict(np.array([[50.0]]))[0] == pytest.approx(gp.beta[0, 0], rel=1e-9)


def test_quadratic_data_reproduced_exactly_by_basis():
    """A quadratic function is in the span of the basis: the mean is exact everywhere."""
    t = np.linspace(0, 2, 40)
    y = 1.0 - 2.0 * t + 0.7 * t**2
    gp = fit_gp(t, y, kernel="matern52", basis="quadratic", standardise_y=True,
                fixed={"sigma_f": 1.0, "lengthscales": 0.3, "sigma_n": 1e-3})
    ts = np.array([-1.0, 0.33, 5.0])
    m, d1, d2 = gp.predict_derivatives(ts)
    np.testing.assert_allclose(m, 1.0 - 2.0 * ts + 0.7 * ts**2, atol=1e-6)
    np.testing.assert_allclose(d1, -2.0 + 1.4 * ts, atol=1e-5)
    np.testing.assert_allclose(d2, 1.4, atol=1e-4)


@pytest.mark.parametrize("kernel", ["se", "matern52"])
def test_mean_derivatives_match_finite_differences(kernel):
    t = np.linspace(0, 1, 60)
    y = np.sin(6 * t) + 0.3 * t**2
    gp = fit_gp(t, y, kernel=kernel, basis="quadratic", noise_var_min_std=1e-9, seed=3)
    ts = np.linspace(0.05, 0.95, 13)
    m, d1, d2 = gp.predict_derivatives(ts)
    h = 1e-4
    mp, mm = gp.predict(ts + h), gp.predict(ts - h)
    np.testing.assert_allclose(d1, (mp - mm) / (2 * h), rtol=1e-5, atol=2e-5)
    h = 1e-3  # larger step for the second difference (round-off ~ eps / h^2)
    mp, mm = gp.predict(ts + h), gp.predict(ts - h)
    np.testing.assert_allclose(d2, (mp - 2 * m + mm) / h**2, rtol=1e-3, atol=5e-3)
    # and the fitted GP recovers the true derivative of the smooth function
    np.testing.assert_allclose(d1, 6 * np.cos(6 * ts) + 0.6 * ts, atol=1e-2)


@pytest.mark.parametrize("kernel,ard,basis", [("se", True, "pure_quadratic"),
                                              ("matern52", False, "quadratic"),
                                              ("se", False, "none")])
def test_lml_gradient_matches_finite_differences(kernel, ard, basis):
    rng = np.random.default_rng(2)
    d = 2 if basis != "quadratic" else 1
    U = rng.standard_normal((25, d))
    V = (np.sin(U.sum(1)) + 0.1 * rng.standard_normal(25))[:, None]
    Hs = basis_matrix_std(basis, U)
    th = np.array([0.2] + ([0.1, -0.3] if ard else [0.05]) + [math.log(0.2)])
    f, g = _neg_lml(th, kernel, ard, U, V, Hs)
    g_fd = approx_fprime(th, lambda x: _neg_lml(x, kernel, ard, U, V, Hs)[0], 1e-6)
    np.testing.assert_allclose(g, g_fd, rtol=1e-4, atol=1e-5)


def test_noise_lower_bound_respected_and_roundtrip(tmp_path):
    rng = np.random.default_rng(4)
    X = rng.uniform(-1, 1, size=(60, 3))
    y = X[:, 0] ** 2 + np.sin(2 * X[:, 1]) + 0.001 * rng.standard_normal(60)
    gp = fit_gp(X, y, kernel="ard_se", basis="pure_quadratic", sigma_n_min=0.05, seed=0)
    assert gp.sigma_n * gp.y_scale[0] >= 0.05 * (1 - 1e-9)
    assert gp.ard and len(gp.lengthscales) == 3
    gp.save(tmp_path / "m")
    gp2 = GP.load(tmp_path / "m")
    Xs = rng.uniform(-1, 1, size=(5, 3))
    np.testing.assert_allclose(gp2.predict(Xs), gp.predict(Xs), rtol=1e-12)
    with np.load(tmp_path / "m.npz", allow_pickle=False) as a:
        assert "X" in a.files


def test_smooth_series_noisy_nonuniform():
    rng = np.random.default_rng(5)
    t = np.sort(rng.uniform(0, 2, 300))
    y = 0.1 * np.sin(3 * t) + 0.002 * rng.standard_normal(t.size)  # 2 mm noise
    to = np.linspace(0.2, 1.8, 50)
    m, d1, _, gp = smooth_series(t, y, to, noise_std_min=1e-3)
    assert np.sqrt(np.mean((m - 0.1 * np.sin(3 * to)) ** 2)) < 1e-3
    assert np.sqrt(np.mean((d1 - 0.3 * np.cos(3 * to)) ** 2)) < 0.02
    assert gp.sigma_n * gp.y_scale[0] == pytest.approx(0.002, rel=0.4)
