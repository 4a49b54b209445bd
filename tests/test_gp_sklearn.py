"""The GP core (crgpr.gp._gpr) against scikit-learn's GaussianProcessRegressor, an independent
implementation: posterior mean, latent variance and log marginal likelihood (with its gradient)
of the ARD squared-exponential kernel plus white noise at fixed hyperparameters
(``optimizer=None``), on random data, to 1e-8 relative.

Kernel correspondence (scikit-learn works in the original input units, crgpr in standardised
ones): sigma_f^2 SE(ell) + sigma_n^2 delta  <->  ConstantKernel(sigma_f^2) * RBF(ell * x_scale)
+ WhiteKernel(sigma_n^2); scikit-learn's predictive variance includes the white noise, crgpr's
is the latent one, so they differ by sigma_n^2 (times y_scale^2).

The constant basis (crgpr's vague-prior mean, R&W Sec. 2.7) has no scikit-learn counterpart:
``normalize_y`` subtracts the sample mean, not the generalised-least-squares beta_hat, so it is
not exact. Exact instead: with a = K^-1 y and b = K^-1 1 from scikit-learn fits to y and to a
vector of ones, beta_hat = sum(a) / sum(b) (A = sum(b) = 1^T K^-1 1); scikit-learn fitted to
y - beta_hat then gives mean = beta_hat + its mean, variance = its latent variance
+ (1 - k*^T K^-1 1)^2 / A, and the restricted LML (R&W eq. 2.45, m = 1) = its LML
- log(A) / 2 + log(2 pi) / 2 (because y^T P y = (y - beta_hat)^T K^-1 (y - beta_hat)).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel

from crgpr.gp._gpr import _neg_lml, basis_matrix_std, fit_gp

RTOL = 1e-8


def _data(seed: int, n: int, d: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict]:
    """Random inputs (scaled differently per dimension), a smooth noisy target, test inputs and
    hyperparameters (standardised units) drawn from a seeded generator."""
    rng = np.random.default_rng(seed)
    scale = rng.uniform(0.1, 10.0, d)
    X = rng.uniform(-1.0, 1.0, (n, d)) * scale + rng.normal(0.0, 3.0, d)
    y = 5.0 + 2.0 * np.sin((X / scale) @ rng.normal(size=d) * 2.0) + 0.1 * rng.standard_normal(n)
    Xs = rng.uniform(-1.2, 1.2, (17, d)) * scale + X.mean(0)
    hyp = {"sigma_f": float(rng.uniform(0.5, 2.0)), "lengthscales": rng.uniform(0.3, 2.0, d),
           "sigma_n": float(rng.uniform(0.05, 0.5))}
    return X, y, Xs, hyp


def _sklearn(gp, hyp: dict, normalize_y: bool) -> GaussianProcessRegressor:
    """The scikit-learn regressor with the same kernel as ``gp`` at fixed hyperparameters."""
    box = (1e-8, 1e8)  # bounds only (no optimiser runs): they keep theta free for the gradient
    kernel = (ConstantKernel(hyp["sigma_f"] ** 2, constant_value_bounds=box)
              * RBF(hyp["lengthscales"] * gp.x_scale, length_scale_bounds=box)
              + WhiteKernel(hyp["sigma_n"] ** 2, noise_level_bounds=box))
    return GaussianProcessRegressor(kernel=kernel, alpha=0.0, optimizer=None, normalize_y=normalize_y)


def _lml(gp, hyp: dict) -> tuple[float, np.ndarray]:
    """crgpr's (restricted) LML and its gradient w.r.t. [log sigma_f, log ell, log sigma_n]."""
    theta = np.log(np.r_[hyp["sigma_f"], hyp["lengthscales"], hyp["sigma_n"]])
    U = gp.standardise_x(gp.X)
    V = gp._V()
    f, g = _neg_lml(theta, "se", True, U, V, basis_matrix_std(gp.basis, U))
    return -f, -g


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(5, 40), d=st.integers(1, 4),
       standardise_y=st.booleans())
def test_zero_basis_matches_sklearn(seed, n, d, standardise_y):
    """No basis: mean, latent variance, LML and its gradient equal scikit-learn's (with
    ``normalize_y`` exactly when crgpr standardises the outputs: both use the mean and the
    ddof-0 standard deviation)."""
    X, y, Xs, hyp = _data(seed, n, d)
    gp = fit_gp(X, y, kernel="se", ard=True, basis="none", fixed=hyp, standardise_y=standardise_y)
    sk = _sklearn(gp, hyp, normalize_y=standardise_y).fit(X, y)
    mean, var = gp.predict(Xs, return_var=True)
    sk_mean, sk_std = sk.predict(Xs, return_std=True)
    np.testing.assert_allclose(mean, sk_mean, rtol=RTOL, atol=RTOL * np.abs(sk_mean).max())
    noise = hyp["sigma_n"] ** 2 * gp.out_scale**2
    np.testing.assert_allclose(var + noise, sk_std**2, rtol=RTOL)
    lml, grad = _lml(gp, hyp)
    sk_lml, sk_grad = sk.log_marginal_likelihood(sk.kernel_.theta, eval_gradient=True)
    assert lml == pytest.approx(sk_lml, rel=RTOL)
    # scikit-learn's theta is [log sigma_f^2, log ell', log sigma_n^2]: d/d log s = 2 d/d log s^2
    np.testing.assert_allclose(grad, np.r_[2.0 * sk_grad[0], sk_grad[1:-1], 2.0 * sk_grad[-1]],
                               rtol=RTOL, atol=RTOL * np.abs(sk_grad).max())


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
@pytest.mark.parametrize("standardise_y", [False, True])
def test_constant_basis_matches_sklearn_by_gls_centring(seed, standardise_y):
    """Constant basis (vague prior on the mean): crgpr equals scikit-learn fitted to the data
    centred by the GLS mean beta_hat, with the basis's variance and LML terms computed from
    scikit-learn fits alone (module docstring)."""
    X, y, Xs, hyp = _data(seed, 12 + 5 * seed, 1 + seed % 3)
    gp = fit_gp(X, y, kernel="se", ard=True, basis="constant", fixed=hyp, standardise_y=standardise_y)
    v = gp._V()[:, 0]  # the targets crgpr regresses (standardised when standardise_y)
    fit = lambda t: _sklearn(gp, hyp, normalize_y=False).fit(X, t)  # noqa: E731
    a, b = fit(v).alpha_.ravel(), fit(np.ones_like(v))
    A = b.alpha_.sum()
    beta = a.sum() / A
    sk = fit(v - beta)
    sk_mean, sk_std = sk.predict(Xs, return_std=True)
    r = 1.0 - b.predict(Xs)  # 1 - k*^T K^-1 1
    ref_mean = gp.out_mean + gp.out_scale * (beta + sk_mean)
    ref_var = gp.out_scale**2 * (sk_std**2 - hyp["sigma_n"] ** 2 + r * r / A)
    mean, var = gp.predict(Xs, return_var=True)
    np.testing.assert_allclose(mean, ref_mean, rtol=RTOL, atol=RTOL * np.abs(ref_mean).max())
    np.testing.assert_allclose(var, ref_var, rtol=RTOL, atol=RTOL * ref_var.max())
    assert gp.beta[0, 0] == pytest.approx(beta, rel=RTOL)
    lml, _ = _lml(gp, hyp)
    assert lml == pytest.approx(sk.log_marginal_likelihood_value_ - 0.5 * math.log(A)
                                + 0.5 * math.log(2.0 * math.pi), rel=RTOL)
    # the basis matters here: without it the mean differs (the comparison can fail)
    gp0 = fit_gp(X, y, kernel="se", ard=True, basis="none", fixed=hyp, standardise_y=standardise_y)
    assert not np.allclose(gp0.predict(Xs), mean, rtol=1e-4)
