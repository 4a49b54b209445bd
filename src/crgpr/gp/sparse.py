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


def pivoted_cholesky(K: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Greedy pivoted Cholesky K ~ L L^T (Harbrecht et al. 2012): pivots P, in order, while the
    largest residual diagonal exceeds tol max(diag K); L (M, r), L[P] lower triangular."""
    M = K.shape[0]
    d = np.diag(K).astype(float).copy()
    top = float(d.max()) if M else 0.0
    L = np.zeros((M, M))
    piv: list[int] = []
    for k in range(M):
        i = int(np.argmax(d))
        if not d[i] > tol * top:
            break
        piv.append(i)
        col = (K[:, i] - L[:, :k] @ L[i, :k]) / np.sqrt(d[i])
        L[:, k] = col
        d -= col * col
        d[piv] = 0.0
    return np.array(piv, dtype=int), L[:, :len(piv)]


def nystrom_reduce(Z: np.ndarray, A: np.ndarray, kernel: str, ell: np.ndarray, tol: float
                   ) -> tuple[np.ndarray, np.ndarray]:
    """A kernel expansion k(u, Z) A (Z (M, d) standardised, A (M, ...)) on the pivoted-Cholesky
    subset Z_P of Z whose residual diagonal is below tol x k(0): A' = K_PP^-1 K_PZ A (Nystrom),
    i.e. k(u, Z) -> k(u, Z_P) K_PP^-1 K_PZ, exact at u in Z up to the dropped residual. For a
    smooth kernel K_ZZ has a small numerical rank and the expansion shrinks from M to r terms;
    callers measure the change. Returns (P, A'): the pivots (indices into Z) and coefficients."""
    K = kernel_matrix(kernel, Z, Z, 1.0, np.asarray(ell, dtype=float))
    piv, L = pivoted_cholesky(K, tol)
    A2 = np.asarray(A, dtype=float).reshape(Z.shape[0], -1)
    red = sla.solve_triangular(L[piv].T, L.T @ A2, lower=False, check_finite=False)
    return piv, red.reshape((len(piv), *np.shape(A)[1:]))
