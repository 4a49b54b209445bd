"""The kernel matrix of the compiled fill (marginal likelihood, exact posterior weights): entries
below KERNEL_FLOOR noise2 / n are stored as 0, and nothing computed from the matrix moves
beyond round-off."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import given, settings
from hypothesis import strategies as st

from crgpr.gp import exact_weights, fit_gp
from crgpr.gp._gpr import KERNEL_FLOOR, KERNEL_ID, _fill_kernel, _neg_lml, kernel_matrix


def _spread_inputs(n: int, d: int, seed: int) -> np.ndarray:
    """Inputs far apart on the lengthscale: most kernel entries underflow below the floor."""
    return np.random.default_rng(seed).uniform(-15.0, 15.0, (n, d))


@pytest.mark.parametrize("kernel", ["se", "matern52"])
def test_entries_below_the_floor_are_zero_the_rest_exact(kernel):
    n, sf2, noise2 = 300, 1.7, 0.2
    Ul = _spread_inputs(n, 3, 1)
    K = np.full((n, n), np.nan)
    _fill_kernel(Ul, KERNEL_ID[kernel], sf2, noise2, K)
    ref = kernel_matrix(kernel, Ul, Ul, np.sqrt(sf2), np.ones(3))
    low = np.tril_indices(n, -1)
    floor = KERNEL_FLOOR * noise2 / n
    small = ref[low] < floor
    assert 0.2 < small.mean() < 1.0  # the case the floor is for
    assert np.all(K[low][small] == 0.0)
    np.testing.assert_allclose(K[low][~small], ref[low][~small], rtol=1e-12)  # numba vs numpy distances
    np.testing.assert_allclose(np.diag(K), sf2 + noise2, rtol=1e-15)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**16), log_noise=st.floats(-3.0, 0.0), spread=st.floats(1.0, 12.0))
def test_the_marginal_likelihood_is_the_unfloored_one_to_round_off(seed, log_noise, spread):
    """R&W eq. (2.30) from the same Cholesky factorisation of the unfloored kernel matrix."""
    rng = np.random.default_rng(seed)
    n, d = 120, 2
    U = rng.uniform(-spread, spread, (n, d))
    V = np.sin(U).sum(1, keepdims=True) + 0.1 * rng.standard_normal((n, 1))
    sn = 10.0**log_noise
    theta = np.array([0.0, 0.0, 0.0, np.log(sn)])
    got, _ = _neg_lml(theta, "se", True, U, V, np.zeros((n, 0)))
    K = kernel_matrix("se", U, U, 1.0, np.ones(d)) + sn**2 * np.eye(n)
    L = sla.cholesky(K, lower=True)
    a = sla.cho_solve((L, True), V[:, 0])
    want = 0.5 * float(V[:, 0] @ a) + np.log(np.diag(L)).sum() + 0.5 * n * np.log(2 * np.pi)
    assert got == pytest.approx(want, rel=1e-10)


def test_exact_weights_of_far_apart_inputs_are_the_dense_solve():
    rng = np.random.default_rng(4)
    n, d = 600, 3
    X = _spread_inputs(n, d, 2)
    y = np.cos(X).sum(1) + 0.05 * rng.standard_normal(n)
    gp = fit_gp(X, y, kernel="se", basis="constant", ard=True, n_restarts=0, seed=1, factorise=False,
                fixed={"sigma_f": 1.0, "lengthscales": np.full(d, 0.15), "sigma_n": 0.05})
    alpha, beta = exact_weights(gp)
    K = kernel_matrix("se", gp.Xs, gp.Xs, gp.sigma_f, gp.ell) + gp.sigma_n**2 * np.eye(n)
    H = np.ones((n, 1))
    Kiv, KiH = np.linalg.solve(K, gp.y), np.linalg.solve(K, H)
    b = np.linalg.solve(H.T @ KiH, H.T @ Kiv)
    np.testing.assert_allclose(beta, b, rtol=1e-10)
    np.testing.assert_allclose(alpha, Kiv - KiH @ b, rtol=0, atol=1e-10 * np.abs(alpha).max())
