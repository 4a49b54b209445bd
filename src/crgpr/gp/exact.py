"""Fast evaluation of a fitted GP's EXACT posterior mean (issue 11, part 3; R&W eq. 2.41 with basis).

    mean(x*) = y_mean + y_scale [ h(u*)^T beta + sum_j alpha_j k(u*, u_j) ],  u = (x - x_mean) / x_scale

with alpha, beta of ``GP._factorise`` over ALL n training points (no inducing points, no
subset). The kernel sum is truncated where the SE kernel falls below ``tol`` sigma_f^2, i.e. at
scaled distance r^2 > 2 ln(1/tol); the neglected part is bounded by tol sigma_f^2 sum_j |alpha_j|
(stored as ``truncation_bound``, output units). Neighbours are found in lengthscale-scaled
inputs: the training points are sorted along the scaled dimension with the widest spread, and
each query sums only the window |Delta u_k / ell_k| <= r_cut of that dimension (bisection),
checking the full distance inside the window. Compiled with numba; rows are independent.

Interface as ``gp.load_evaluator``'s evaluators: built from a saved model stem, ``__call__(X)`` on
feature rows (n, d); 1-D models also give ``slope(x)`` (analytic derivative of the mean).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import njit, prange

from crgpr.gp._gpr import GP, SQRT5, basis_matrix_std

_BASIS_ID = {"none": 0, "constant": 1, "linear": 2, "pure_quadratic": 3}
_KERNEL_ID = {"se": 0, "matern52": 1}


def cutoff_radius(kernel: str, tol: float) -> float:
    """Scaled distance beyond which k / sigma_f^2 < tol (SE: sqrt(2 ln 1/tol); Matern-5/2 by bisection)."""
    if tol <= 0.0:
        return math.inf
    if kernel == "se":
        return math.sqrt(2.0 * math.log(1.0 / tol))
    lo, hi = 0.0, 1.0
    while (1 + SQRT5 * hi + 5.0 / 3.0 * hi * hi) * math.exp(-SQRT5 * hi) > tol:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if (1 + SQRT5 * mid + 5.0 / 3.0 * mid * mid) * math.exp(-SQRT5 * mid) > tol:
            lo = mid
        else:
            hi = mid
    return hi


@njit(cache=True, parallel=True)
def _exact_eval(Ul, key, alpha, rcut, kernel_id, out_k, out_d):
    """out_k[i] = sum_j alpha_j k(ul_i, Ul_j) / sigma_f^2 over |r| <= rcut; out_d its d/du (1-D)."""
    n, d = Ul.shape
    nq = out_k.shape[0]
    rc2 = rcut * rcut
    for i in prange(nq):
        q = key[i]
        lo = np.searchsorted(Ul[:, 0], q[0] - rcut)
        hi = np.searchsorted(Ul[:, 0], q[0] + rcut, side="right")
        acc = 0.0
        dacc = 0.0
        for j in range(lo, hi):
            r2 = 0.0
            for k in range(d):
                dd = q[k] - Ul[j, k]
                r2 += dd * dd
            if r2 > rc2:
                continue
            if kernel_id == 0:
                e = math.exp(-0.5 * r2)
                acc += alpha[j] * e
                dacc -= alpha[j] * e * (q[0] - Ul[j, 0])
            else:
                r = math.sqrt(r2)
                e = math.exp(-SQRT5 * r)
                acc += alpha[j] * (1.0 + SQRT5 * r + (5.0 / 3.0) * r2) * e
                dacc -= alpha[j] * (5.0 / 3.0) * (1.0 + SQRT5 * r) * e * (q[0] - Ul[j, 0])
        out_k[i] = acc
        out_d[i] = dacc


@njit(cache=True, parallel=True)
def _fill_kernel(Ul, kernel_id, sf2, noise2, K):
    """K = k(U, U) + noise2 I (lower triangle and diagonal) for scaled inputs, in place."""
    n, d = Ul.shape
    for i in prange(n):
        for j in range(i + 1):
            r2 = 0.0
            for k in range(d):
                dd = Ul[i, k] - Ul[j, k]
                r2 += dd * dd
            if kernel_id == 0:
                v = sf2 * math.exp(-0.5 * r2)
            else:
                r = math.sqrt(r2)
                v = sf2 * (1.0 + SQRT5 * r + (5.0 / 3.0) * r2) * math.exp(-SQRT5 * r)
            K[i, j] = v
        K[i, i] += noise2


def exact_weights(gp: GP) -> tuple[np.ndarray, np.ndarray]:
    """(alpha (n,), beta (m,)) of the exact posterior mean over all n points (R&W 2.41-2.42).

    Same algebra as ``GP._factorise`` but with one n x n array (filled in place, Cholesky
    in place), so n ~ 2e4 fits in memory.
    """
    import scipy.linalg as sla

    ell = np.broadcast_to(np.ravel(gp.lengthscales), (gp.dim,)).astype(float)
    U = gp.standardise_x(gp.X)
    K = np.empty((gp.n, gp.n), order="F")
    _fill_kernel(np.ascontiguousarray(U / ell), _KERNEL_ID[gp.kernel], gp.sigma_f**2, gp.sigma_n**2, K)
    L = sla.cholesky(K, lower=True, overwrite_a=True, check_finite=False)
    V = np.ravel(gp._V()[:, 0])
    H = basis_matrix_std(gp.basis, U)
    KiV = sla.cho_solve((L, True), V, check_finite=False)
    if H.shape[1]:
        KiH = sla.cho_solve((L, True), H, check_finite=False)
        beta = np.linalg.solve(H.T @ KiH, H.T @ KiV)
        return KiV - KiH @ beta, beta
    return KiV, np.zeros(0)


class ExactMean:
    """Exact posterior mean of one saved GP (stem.npz/.json, ``GP.save``), truncated at ``tol``."""

    def __init__(self, stem: str | Path | GP, tol: float = 1e-12):
        gp = stem if isinstance(stem, GP) else GP.load(stem)
        if gp.multi:
            raise ValueError("ExactMean: single-output GPs only")
        if gp.alpha is not None:
            alpha_all = np.ravel(gp.alpha[:, 0])
            beta = np.ravel(gp.beta[:, 0]) if gp.beta.size else np.zeros(0)
        else:
            alpha_all, beta = exact_weights(gp)
        self.gp = gp
        self.name = str(stem) if not isinstance(stem, GP) else "gp"
        self.dim = gp.dim
        self.kernel_id = _KERNEL_ID[gp.kernel]
        ell = np.broadcast_to(np.ravel(gp.lengthscales), (gp.dim,)).astype(float)
        self.ell = ell
        Ul = gp.standardise_x(gp.X) / ell
        spread = Ul.max(0) - Ul.min(0)
        k0 = int(np.argmax(spread))
        self.perm = np.array([k0] + [k for k in range(gp.dim) if k != k0], dtype=np.int64)
        Ul = Ul[:, self.perm]
        order = np.argsort(Ul[:, 0], kind="stable")
        self.Ul = np.ascontiguousarray(Ul[order])
        self.alpha = np.ascontiguousarray(alpha_all[order])
        self.beta = beta
        self.sf2 = gp.sigma_f**2
        self.tol = tol
        self.rcut = cutoff_radius(gp.kernel, tol)
        self.y_mean = float(np.ravel(gp.y_mean)[0])
        self.y_scale = float(np.ravel(gp.y_scale)[0])
        self.truncation_bound = float(tol * self.sf2 * np.abs(self.alpha).sum() * self.y_scale)

    def _sums(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        U = self.gp.standardise_x(np.asarray(X, dtype=float).reshape(-1, self.dim))
        key = np.ascontiguousarray((U / self.ell)[:, self.perm])
        ok = np.empty(key.shape[0])
        od = np.empty(key.shape[0])
        _exact_eval(self.Ul, key, self.alpha, self.rcut, self.kernel_id, ok, od)
        return U, ok, od

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        shape = X.shape[:-1] if (self.dim > 1 or (X.ndim >= 2 and X.shape[-1] == 1)) else X.shape
        U, ok, _ = self._sums(X)
        val = self.sf2 * ok
        if self.beta.size:
            val = val + basis_matrix_std(self.gp.basis, U) @ self.beta
        return (self.y_mean + self.y_scale * val).reshape(shape)

    def slope(self, x: np.ndarray) -> np.ndarray:
        """d mean / dx of a 1-D model (for the integrator's exact damping flow)."""
        if self.dim != 1:
            raise ValueError("ExactMean.slope: 1-D models only")
        x = np.asarray(x, dtype=float)
        U, _, od = self._sums(x.reshape(-1, 1))
        xs = float(self.gp.x_scale[0])
        d = self.sf2 * od / self.ell[0]
        u = U[:, 0]
        b = self.beta
        if b.size >= 2:
            d = d + b[1]
        if b.size >= 3 and self.gp.basis in ("pure_quadratic", "quadratic"):
            d = d + 2.0 * b[2] * u
        return (self.y_scale * d / xs).reshape(x.shape)
