"""Sparse GP means: inducing-input selection and the DTC / subset-of-regressors fit.

Used by the gradient models (Sec. III-B step 3) for the mean the rollouts integrate and by the
posterior samplers (``crgpr.gp.sampling``) for their inducing set. The DTC mean with a
jointly estimated basis (flat prior on beta, Quinonero-Candela & Rasmussen 2005):

    min_{beta, w} |v - H beta - K_XZ w|^2 + sigma_n^2 w^T K_ZZ w,

whose solution is the posterior mean h(u)^T beta + k(u, Z) w of the DTC model, evaluated by
``crgpr.gp.evaluators.KernelMean.dtc``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from crgpr.gp._gpr import GP, basis_matrix_std, kernel_matrix


def select_inducing(Ul: np.ndarray, M: int, seed: int) -> np.ndarray:
    """Indices of M rows of ``Ul`` (standardised inputs divided by the lengthscales) by greedy
    farthest-point sampling from a seeded random start; all rows when M >= n."""
    n = Ul.shape[0]
    if M >= n:
        return np.arange(n)
    rng = np.random.default_rng(seed)
    idx = np.empty(M, dtype=int)
    idx[0] = rng.integers(n)
    d2 = ((Ul - Ul[idx[0]]) ** 2).sum(1)
    for k in range(1, M):
        idx[k] = int(np.argmax(d2))
        d2 = np.minimum(d2, ((Ul - Ul[idx[k]]) ** 2).sum(1))
    return idx


def dtc_fit(gp: GP, X: np.ndarray, V: np.ndarray, M: int, seed: int) -> dict[str, np.ndarray]:
    """DTC mean of ``gp``'s kernel on inputs X (original units), standardised targets V (n, 1):
    M inducing inputs by ``select_inducing``; returns ``dtc_Z`` (standardised), ``dtc_beta``,
    ``dtc_w`` (the arrays saved with a gradient model)."""
    U = gp.standardise_x(X)
    ell = np.broadcast_to(gp.lengthscales, (gp.dim,)).astype(float)
    zi = select_inducing(U / ell, M, seed)
    Z = U[zi]
    Kxz = kernel_matrix(gp.kernel, U, Z, gp.sigma_f, ell)
    Kzz = kernel_matrix(gp.kernel, Z, Z, gp.sigma_f, ell)
    H = basis_matrix_std(gp.basis, U)
    m = H.shape[1]
    Phi = np.hstack([H, Kxz])
    A = Phi.T @ Phi
    A[m:, m:] += gp.sigma_n**2 * (Kzz + 1e-8 * gp.sigma_f**2 * np.eye(len(zi)))
    A[np.diag_indices_from(A)] += 1e-10 * np.trace(A) / A.shape[0]
    sol = sla.solve(A, Phi.T @ V, assume_a="pos")
    return {"dtc_Z": Z, "dtc_beta": sol[:m], "dtc_w": sol[m:]}
