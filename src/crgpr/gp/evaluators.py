"""Evaluators of a GP's posterior mean: the functions a learned rod integrates (Sec. III-B step 4).

Every evaluator is a callable on feature rows, ``f(X)`` with X (..., d) in original units ->
(...,), and the 1-D ones also give ``slope(x)`` (the momentum GPs' dH_p/dp for the damping
flow). They share one representation of a single-output GP mean in the units of ``crgpr.gp``
(u = (x - x_mean) / x_scale, R&W 2006 eq. (2.41)):

    f(x) = y_mean + y_scale (sigma_f^2 sum_m a_m k(u / ell, z_m / ell) + h(u)^T beta),

* ``KernelMean.exact(gp, tol)``: the exact posterior mean, centres z_m = ALL n training
  inputs, a = K_y^-1 (v - H beta_hat), beta = beta_hat (R&W eq. (2.41)), the weights from one
  in-place Cholesky factorisation (``exact_weights``, O(n^3) once, one n x n array). With
  ``tol > 0`` the kernel sum is truncated where k / sigma_f^2 < tol (scaled distance r > r_cut,
  ``cutoff_radius``); the neglected part is at most tol sigma_f^2 sum_m |a_m| (standardised
  units; ``truncation_bound`` in output units), at EVERY input. The centres within r_cut are
  found with a cell grid in lengthscale-scaled inputs: cells of width r_cut / 2 along the scaled
  input with the widest spread, the centres of each cell sorted along the second widest, so a
  query visits 5 cells and bisects a window |du_2| <= r_cut in each, then sums the window with
  the full distance masked at r_cut (SIMD loops; SE exp by a polynomial of relative error
  < 1e-13); ``tol = 0`` is the dense sum;
* ``KernelMean.dtc(gp, Z, w, beta)``: the sparse DTC / subset-of-regressors mean (``dtc_fit``),
  centres the M inducing inputs; O(M) per point;
* ``Table1D``: a 1-D mean tabulated on a grid (``law_grid``), linear interpolation, 0 (the
  prior mean) outside, with the segment slope; ``interp_uniform``: the compiled interpolation
  of rows of tables on one uniform grid (posterior samples of a 1-D law, a law of (kappa, s) at
  the rollout's fixed s: ``crgpr.learning.nominal.SliceTables``);
* posterior samples (``crgpr.gp.sampling.CompressedSamples``) are the same kernel expansion per
  sample plus an RFF prior term, evaluated by the same compiled ``kernel_sum``.

``kernel_sum`` is the one compiled kernel sum of the package: ``kernel_sum`` (IEEE, used by
the means) and ``kernel_sum_fast`` (the same source compiled with fastmath and a polynomial
exp (``_exp_neg_half``, relative error < 1e-13, shared with the exact mean's truncated sums),
used by the posterior samples). ``load_evaluator(stem)`` builds an evaluator from a saved
model (``stem.npz`` + ``stem.json``, ``allow_pickle=False``): its table, else its exact-mean
weights (``mean_alpha``, ``mean_beta``, truncation ``exact_tol`` in the JSON), else its DTC
arrays, else the exact mean factorised on load.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from crgpr.gp._gpr import GP, KERNEL_ID, SQRT5, GPError, _fill_kernel, _kernel_value, basis_matrix_std

BASIS_ID = {"none": 0, "constant": 1, "linear": 2, "pure_quadratic": 3}
_SE_POLY = 2  # kernel id of the SE kernel with the polynomial exp (kernel_sum_fast only)


@njit(cache=True, fastmath=True, inline="always")
def _exp_neg_half(r2):
    """exp(-r2 / 2) for 0 <= r2 <= 80 (clipped above; exp(-40) = 4e-18 is 0 for a kernel):
    exp(u / 256)^256 with a degree-11 Taylor polynomial, relative error < 1e-13 (measured
    3.8e-14 on [0, 80]); vectorisable. Used by the posterior samples' and the exact mean's sums."""
    u = -0.5 * min(r2, 80.0) * 0.00390625
    p = 1.0
    for k in range(11, 0, -1):
        p = 1.0 + u / k * p
    for _ in range(8):
        p = p * p
    return p


@njit(inline="always")
def _kernel_sum_body(xl, ZlT, a, sf2, kernel_id, out):
    """out[s, i] += sf2 sum_m a[s, m] k(xl[s, i], Zl[m]), inputs divided by the lengthscales.

    ``xl`` (S, m, d), ``ZlT`` (d, M) (transposed: the inner loops run over contiguous
    centres), ``a`` (S, M). kernel_id: 0 SE, 1 Matern-5/2, 2 SE with the polynomial exp.
    """
    S, m, d = xl.shape
    M = ZlT.shape[1]
    r2 = np.empty(M)
    for s in range(S):
        for i in range(m):
            r2[:] = 0.0
            for k in range(d):
                xk = xl[s, i, k]
                for j in range(M):
                    dd = xk - ZlT[k, j]
                    r2[j] += dd * dd
            acc = 0.0
            if kernel_id == 0:
                for j in range(M):
                    acc += a[s, j] * math.exp(-0.5 * r2[j])
            elif kernel_id == 1:
                for j in range(M):
                    r = math.sqrt(r2[j])
                    s5r = 2.23606797749979 * r
                    acc += a[s, j] * (1.0 + s5r + (5.0 / 3.0) * r2[j]) * math.exp(-s5r)
            else:
                for j in range(M):
                    acc += a[s, j] * _exp_neg_half(r2[j])
            out[s, i] += sf2 * acc


@njit(cache=True)
def kernel_sum(xl, ZlT, a, sf2, kernel_id, out):
    """The kernel sum in IEEE arithmetic (the posterior means)."""
    _kernel_sum_body(xl, ZlT, a, sf2, kernel_id, out)


@njit(cache=True, fastmath=True)
def kernel_sum_fast(xl, ZlT, a, sf2, kernel_id, out):
    """The same kernel sum compiled with fastmath (vectorised; the posterior samples)."""
    _kernel_sum_body(xl, ZlT, a, sf2, kernel_id, out)


@njit(cache=True)
def _add_basis(u, beta, basis_id, out):
    """out[i] += h(u_i)^T beta, term by term (constant, linear, pure quadratic)."""
    n, d = u.shape
    for i in range(n):
        acc = out[i]
        if basis_id >= 1:
            acc += beta[0]
        if basis_id >= 2:
            for k in range(d):
                acc += beta[1 + k] * u[i, k]
        if basis_id >= 3:
            for k in range(d):
                acc += beta[1 + d + k] * u[i, k] * u[i, k]
        out[i] = acc


@njit(cache=True)
def _kernel_mean(X, x_mean, x_scale, ell, ZlT, a, sf2, beta, basis_id, kernel_id, y_mean, y_scale, out):
    """out[i] = y_mean + y_scale (kernel_sum at u_i / ell + h(u_i)^T beta), u = (x - x_mean) / x_scale."""
    n, d = X.shape
    U = np.empty((n, d))
    Ul = np.empty((1, n, d))
    for i in range(n):
        for k in range(d):
            U[i, k] = (X[i, k] - x_mean[k]) / x_scale[k]
            Ul[0, i, k] = U[i, k] / ell[k]
    acc = np.zeros((1, n))
    kernel_sum(Ul, ZlT, a, sf2, kernel_id, acc)
    _add_basis(U, beta, basis_id, acc[0])
    for i in range(n):
        out[i] = y_mean + y_scale * acc[0, i]


def cutoff_radius(kernel: str, tol: float) -> float:
    """Scaled distance beyond which k / sigma_f^2 < tol (SE: sqrt(2 ln 1/tol); Matern-5/2 by
    bisection); ``inf`` for tol <= 0 (no truncation)."""
    if tol <= 0.0:
        return math.inf
    if kernel == "se":
        return math.sqrt(2.0 * math.log(1.0 / tol))
    def k(r: float) -> float:
        return (1 + SQRT5 * r + 5.0 / 3.0 * r * r) * math.exp(-SQRT5 * r)
    lo, hi = 0.0, 1.0
    while k(hi) > tol:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if k(mid) > tol else (lo, mid)
    return hi


@njit(cache=True)
def _kernel_column(Ul, i, kernel_id, sf2, out):
    """out[j] = k(Ul_i, Ul_j) (no noise) for scaled inputs."""
    for j in range(Ul.shape[0]):
        out[j] = _kernel_value(Ul, i, j, kernel_id, sf2)


@njit(cache=True)
def _kernel_matvec(Ul, kernel_id, sf2, noise2, X, out):
    """out = (K + noise2 I) X for a block X (n, k) without forming K (symmetric pass)."""
    n = Ul.shape[0]
    m = X.shape[1]
    for i in range(n):
        for c in range(m):
            out[i, c] = (sf2 + noise2) * X[i, c]
    for i in range(n):
        for j in range(i):
            v = _kernel_value(Ul, i, j, kernel_id, sf2)
            for c in range(m):
                out[i, c] += v * X[j, c]
                out[j, c] += v * X[i, c]


#: low-rank path of ``exact_weights``: largest pivoted-Cholesky rank tried, the residual trace
#: (x sigma_n^2) at which the preconditioner is complete, CG relative residual and iterations
_LOWRANK_MAX_RANK = 600
_LOWRANK_TRACE = 1e-3
_CG_RTOL = 1e-13
_CG_MAXITER = 60


def _pivoted_factor(Ul: np.ndarray, kernel_id: int, sf2: float, trace_tol: float, rmax: int
                    ) -> np.ndarray | None:
    """Pivoted Cholesky k(Ul, Ul) ~ L L^T, kernel columns computed on demand, until the residual
    trace is below trace_tol; L (n, r), or None if that needs more than rmax pivots."""
    n = Ul.shape[0]
    dg = np.full(n, sf2)
    L = np.zeros((n, min(n, rmax)))
    col = np.empty(n)
    r = 0
    while dg.sum() > trace_tol:
        if r == L.shape[1]:
            return None
        i = int(np.argmax(dg))
        _kernel_column(Ul, i, kernel_id, sf2, col)
        v = (col - L[:, :r] @ L[i, :r]) / math.sqrt(dg[i])
        L[:, r] = v
        dg = np.maximum(dg - v * v, 0.0)
        dg[i] = 0.0
        r += 1
    return L[:, :r]


def _lowrank_solve(Ul: np.ndarray, kernel_id: int, sf2: float, noise2: float, B: np.ndarray
                   ) -> np.ndarray | None:
    """(K + noise2 I)^-1 B for a kernel matrix of small numerical rank, or None.

    Pivoted Cholesky K ~ L L^T (kernel columns on demand) until the residual trace is below
    ``_LOWRANK_TRACE`` noise2 (then P = L L^T + noise2 I differs from K + noise2 I by a PSD E with
    ||E|| <= 1e-3 noise2: cond(P^-1 A) <= 1.001); preconditioned CG on every column of B (one
    matrix-free kernel pass per iteration) to relative residual ``_CG_RTOL``. None when the rank
    exceeds ``_LOWRANK_MAX_RANK`` or CG does not converge or breaks down (non-finite iterates:
    noise2 / sf2 near round-off, where the factor's residual trace is below what double precision
    resolves); the caller then factorises densely."""
    import scipy.linalg as sla

    n = Ul.shape[0]
    if noise2 <= 0.0:
        return None
    # a random subset of n_sub rows needing the rank cap already (at the same residual trace
    # per row) means the full matrix needs more: decline before the O(n r^2) work
    n_sub = min(n, 4 * _LOWRANK_MAX_RANK)
    if n_sub < n:
        sub = np.random.default_rng(0).choice(n, size=n_sub, replace=False)
        if _pivoted_factor(np.ascontiguousarray(Ul[sub]), kernel_id, sf2, _LOWRANK_TRACE * noise2 * n_sub / n,
                           _LOWRANK_MAX_RANK // 2) is None:
            return None
    L = _pivoted_factor(Ul, kernel_id, sf2, _LOWRANK_TRACE * noise2, _LOWRANK_MAX_RANK)
    if L is None:
        return None
    r = L.shape[1]
    C = sla.cho_factor(noise2 * np.eye(r) + L.T @ L, lower=True)

    def precond(R: np.ndarray) -> np.ndarray:
        return (R - L @ sla.cho_solve(C, L.T @ R)) / noise2

    B = np.asarray(B, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):  # a breakdown is detected and declined
        return _pcg(Ul, kernel_id, sf2, noise2, B, precond)


def _pcg(Ul: np.ndarray, kernel_id: int, sf2: float, noise2: float, B: np.ndarray,
         precond: Callable[[np.ndarray], np.ndarray]) -> np.ndarray | None:
    """Preconditioned CG for (K + noise2 I) X = B, column by column in one block (one
    matrix-free kernel pass per iteration); None on breakdown or no convergence."""
    X = precond(B)
    AX = np.empty_like(B)
    _kernel_matvec(Ul, kernel_id, sf2, noise2, X, AX)
    R = B - AX
    if not np.all(np.isfinite(R)):
        return None
    Zp = precond(R)
    P = Zp.copy()
    rz = (R * Zp).sum(0)
    bnorm = np.maximum(np.linalg.norm(B, axis=0), 1e-300)
    AP = np.empty_like(B)
    for _ in range(_CG_MAXITER):
        if np.all(np.linalg.norm(R, axis=0) <= _CG_RTOL * bnorm):
            return X
        _kernel_matvec(Ul, kernel_id, sf2, noise2, P, AP)
        alpha = rz / np.maximum((P * AP).sum(0), 1e-300)
        X += alpha * P
        R -= alpha * AP
        if not (np.all(np.isfinite(X)) and np.all(np.isfinite(R))):
            return None
        Zp = precond(R)
        rz_new = (R * Zp).sum(0)
        P = Zp + (rz_new / np.maximum(rz, 1e-300)) * P
        rz = rz_new
    return X if np.all(np.linalg.norm(R, axis=0) <= _CG_RTOL * bnorm) else None


def exact_weights(gp: GP) -> tuple[np.ndarray, np.ndarray]:
    """(alpha (n,), beta (m,)) of a single-output GP's exact posterior mean over ALL its n
    training points (R&W eqs. (2.41)-(2.42), vague prior on beta):

        beta = (H^T K_y^-1 H)^-1 H^T K_y^-1 v,   alpha = K_y^-1 (v - H beta).

    K_y^-1 applied by ``_lowrank_solve`` where the kernel matrix has a small numerical rank
    (long lengthscales: pivoted-Cholesky-preconditioned CG to relative residual 1e-13,
    O(n^2) per iteration, no n x n array), else as in ``GP._factorise`` by one in-place Cholesky
    factorisation of one n x n array (8 n^2 bytes, 2.9 GB at n = 18 975), O(n^3 / 3).
    """
    import scipy.linalg as sla

    if gp.multi:
        raise GPError("exact_weights needs a single-output GP")
    U = gp.Xs
    Ul = np.ascontiguousarray(U / gp.ell)
    kid, sf2, sn2 = KERNEL_ID[gp.kernel], gp.sigma_f**2, gp.sigma_n**2
    V = np.ravel(gp._V()[:, 0])
    H = basis_matrix_std(gp.basis, U)
    sol = _lowrank_solve(Ul, kid, sf2, sn2, np.column_stack([V, H]))
    if sol is not None:
        KiV, KiH = sol[:, 0], sol[:, 1:]
    else:
        K = np.empty((gp.n, gp.n), order="F")
        _fill_kernel(Ul, kid, sf2, sn2, K)
        L = sla.cholesky(K, lower=True, overwrite_a=True, check_finite=False)
        KiV = sla.cho_solve((L, True), V, check_finite=False)
        KiH = sla.cho_solve((L, True), H, check_finite=False) if H.shape[1] else H
    if H.shape[1]:
        beta = np.linalg.solve(H.T @ KiH, H.T @ KiV)
        return KiV - KiH @ beta, beta
    return KiV, np.zeros(0)


@njit(cache=True, fastmath=True)
def _truncated_sum(Ql, ZT, a, key1, starts, lo0, h, k0, k1, rcut, kernel_id, out):
    """out[i] = sum_j a_j k(Ql_i, Z_j) / sigma_f^2 over the centres with r <= rcut (cell grid:
    ``KernelMean._grid``); centres ZT (d, M) sorted by (cell along k0, key1 = coordinate k1).
    Inner loops run over contiguous centres (SIMD): the squared distances of a window, then
    the masked kernel sum (SE: ``_exp_neg_half``)."""
    nq, d = Ql.shape
    ncell = starts.shape[0] - 1
    rc2 = rcut * rcut
    r2 = np.empty(ZT.shape[1])
    for i in range(nq):
        q0 = Ql[i, k0]
        q1 = Ql[i, k1]
        c_lo = max(int(math.floor((q0 - rcut - lo0) / h)), 0)
        c_hi = min(int(math.floor((q0 + rcut - lo0) / h)), ncell - 1)
        acc = 0.0
        for c in range(c_lo, c_hi + 1):
            s, e = starts[c], starts[c + 1]
            if s == e:
                continue
            j0 = s + int(np.searchsorted(key1[s:e], q1 - rcut))
            j1 = s + int(np.searchsorted(key1[s:e], q1 + rcut, side="right"))
            m = j1 - j0  # the window, indexed from 0 (slices: the loops vectorise)
            for t in range(m):
                r2[t] = 0.0
            for k in range(d):
                qk = Ql[i, k]
                zk = ZT[k, j0:j1]
                for t in range(m):
                    dd = qk - zk[t]
                    r2[t] += dd * dd
            aw = a[j0:j1]
            if kernel_id == 0:
                for t in range(m):
                    w = aw[t] if r2[t] <= rc2 else 0.0
                    acc += w * _exp_neg_half(r2[t])
            else:
                for t in range(m):
                    if r2[t] <= rc2:
                        r = math.sqrt(r2[t])
                        acc += aw[t] * (1.0 + SQRT5 * r + (5.0 / 3.0) * r2[t]) * math.exp(-SQRT5 * r)
        out[i] = acc


@njit(cache=True, fastmath=True)
def truncated_sum_batch(xl, ZT, a, key1, starts, lo0, h, k0, k1, rcut, kernel_id, out):
    """``_truncated_sum`` for S weight vectors: out[s, i] = sum_j a[s, j] k(xl[s, i], Z_j) /
    sigma_f^2 over the centres with r <= rcut; xl (S, m, d), a (S, M) in the grid's order."""
    for s in range(xl.shape[0]):
        _truncated_sum(xl[s], ZT, a[s], key1, starts, lo0, h, k0, k1, rcut, kernel_id, out[s])


class KernelMean:
    """f(x) = y_mean + y_scale (sigma_f^2 sum_m a_m k(u, z_m) + h(u)^T beta) (module docstring).

    ``Z`` (M, d) standardised centres, ``a`` (M,), ``beta`` (p,) in standardised units.
    ``tol``: truncate the kernel sum below tol sigma_f^2 (0: the dense sum, IEEE, as before).
    """

    def __init__(self, kernel: str, basis: str, sigma_f: float, lengthscales: np.ndarray,
                 x_mean: np.ndarray, x_scale: np.ndarray, y_mean: float, y_scale: float,
                 Z: np.ndarray, a: np.ndarray, beta: np.ndarray, kind: str = "kernel",
                 tol: float = 0.0):
        if kernel not in KERNEL_ID or basis not in BASIS_ID:
            raise GPError(f"compiled mean supports kernels {tuple(KERNEL_ID)} and bases "
                          f"{tuple(BASIS_ID)}, got {kernel!r} / {basis!r}")
        Z = np.atleast_2d(np.asarray(Z, dtype=float))
        self.dim = Z.shape[1]
        self.kind = kind
        self.kernel, self.basis = kernel, basis
        self.kernel_id, self.basis_id = KERNEL_ID[kernel], BASIS_ID[basis]
        self.ell = np.broadcast_to(np.ravel(np.asarray(lengthscales, dtype=float)), (self.dim,)).copy()
        self.x_mean = np.ravel(np.asarray(x_mean, dtype=float))
        self.x_scale = np.ravel(np.asarray(x_scale, dtype=float))
        self.y_mean, self.y_scale = float(y_mean), float(y_scale)
        self.sf2 = float(sigma_f) ** 2
        self.Z = Z
        self.ZlT = np.ascontiguousarray((Z / self.ell).T)
        self.a = np.ascontiguousarray(np.ravel(a), dtype=float)[None, :]
        self.beta = np.ascontiguousarray(np.ravel(beta), dtype=float)
        if self.a.shape[1] != Z.shape[0]:
            raise GPError(f"{self.a.shape[1]} weights for {Z.shape[0]} centres")
        self.tol = float(tol)
        self.rcut = cutoff_radius(kernel, self.tol)
        #: bound on |truncated - dense| at any input, output units
        self.truncation_bound = (float(self.tol * self.sf2 * np.abs(self.a).sum() * self.y_scale)
                                 if self.tol > 0 else 0.0)
        if self.tol > 0:
            self._grid()

    def _grid(self) -> None:
        """The cell grid of the scaled centres (module docstring)."""
        Ul = self.ZlT.T
        spread = Ul.max(0) - Ul.min(0)
        order_dims = np.argsort(-spread, kind="stable")
        self.k0 = int(order_dims[0])
        self.k1 = int(order_dims[1]) if self.dim > 1 else self.k0
        self.lo0 = float(Ul[:, self.k0].min())
        M = Ul.shape[0]
        self.h = max(0.5 * self.rcut, float(spread[self.k0]) / (4.0 * M), 1e-300)
        cell = np.floor((Ul[:, self.k0] - self.lo0) / self.h).astype(np.int64)
        order = np.lexsort((Ul[:, self.k1], cell))
        self.order = order
        self.ZT_sorted = np.ascontiguousarray(Ul[order].T)
        self.a_sorted = np.ascontiguousarray(self.a[0, order])
        self.key1 = np.ascontiguousarray(self.ZT_sorted[self.k1])
        self.starts = np.searchsorted(cell[order], np.arange(int(cell.max()) + 2)).astype(np.int64)

    @classmethod
    def exact(cls, gp: GP, tol: float = 0.0, weights: tuple[np.ndarray, np.ndarray] | None = None
              ) -> KernelMean:
        """The exact posterior mean of a fitted single-output GP over all its n points (R&W eq.
        (2.41)); ``weights`` (alpha, beta) if already computed, else ``exact_weights(gp)`` (or the
        GP's own factorisation when it has one); ``tol`` see the class docstring."""
        if gp.multi:
            raise GPError("KernelMean needs a single-output GP")
        if weights is None:
            weights = ((np.ravel(gp.alpha[:, 0]), np.ravel(gp.beta[:, 0])) if gp.alpha is not None
                       else exact_weights(gp))
        return cls(gp.kernel, gp.basis, gp.sigma_f, gp.lengthscales, gp.x_mean, gp.x_scale,
                   gp.out_mean, gp.out_scale, gp.Xs, weights[0], weights[1], kind="exact", tol=tol)

    @classmethod
    def dtc(cls, gp: GP, Z: np.ndarray, w: np.ndarray, beta: np.ndarray) -> KernelMean:
        """The DTC mean with inducing inputs Z and coefficients (w, beta) of ``dtc_fit``."""
        return cls(gp.kernel, gp.basis, gp.sigma_f, gp.lengthscales, gp.x_mean, gp.x_scale,
                   float(np.ravel(gp.y_mean)[0]), float(np.ravel(gp.y_scale)[0]), Z, w, beta,
                   kind="dtc")

    def dense(self) -> KernelMean:
        """The same mean with the dense (untruncated) kernel sum, for checks."""
        return KernelMean(self.kernel, self.basis, math.sqrt(self.sf2), self.ell, self.x_mean,
                          self.x_scale, self.y_mean, self.y_scale, self.Z, self.a[0], self.beta,
                          kind=self.kind, tol=0.0)

    def _rows(self, X: np.ndarray) -> tuple[np.ndarray, tuple[int, ...]]:
        X = np.asarray(X, dtype=float)
        if self.dim == 1 and (X.ndim == 0 or X.shape[-1] != 1 or X.ndim == 1):
            X = X[..., None]  # 1-D models also take plain (...,) arrays
        return np.ascontiguousarray(X.reshape(-1, X.shape[-1])), X.shape[:-1]

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X2, shape = self._rows(X)
        out = np.empty(X2.shape[0])
        if self.tol <= 0:
            _kernel_mean(X2, self.x_mean, self.x_scale, self.ell, self.ZlT, self.a, self.sf2, self.beta,
                         self.basis_id, self.kernel_id, self.y_mean, self.y_scale, out)
            return out.reshape(shape)
        U = (X2 - self.x_mean) / self.x_scale
        _truncated_sum(np.ascontiguousarray(U / self.ell), self.ZT_sorted, self.a_sorted, self.key1,
                       self.starts, self.lo0, self.h, self.k0, self.k1, self.rcut, self.kernel_id, out)
        out *= self.sf2
        _add_basis(U, self.beta, self.basis_id, out)
        return (self.y_mean + self.y_scale * out).reshape(shape)

    def slope(self, x: np.ndarray) -> np.ndarray:
        """d f / dx of a 1-D mean (dense sum; the integrator's exact damping flow)."""
        if self.dim != 1:
            raise GPError("KernelMean.slope: 1-D means only")
        x = np.asarray(x, dtype=float)
        u = (x.reshape(-1) - self.x_mean[0]) / self.x_scale[0]
        z = self.Z[:, 0]
        ell = self.ell[0]
        dlt = (u[:, None] - z[None, :]) / ell
        if self.kernel == "se":
            dk = -dlt / ell * np.exp(-0.5 * dlt**2)
        else:
            r = np.abs(dlt)
            dk = -(5.0 / 3.0) * dlt / ell * (1.0 + SQRT5 * r) * np.exp(-SQRT5 * r)
        d = self.sf2 * dk @ self.a[0]
        b = self.beta
        if b.size >= 2:
            d = d + b[1]
        if b.size >= 3:
            d = d + 2.0 * b[2] * u
        return (self.y_scale * d / self.x_scale[0]).reshape(x.shape)


@njit(cache=True)
def interp_uniform(x, g0, dg, values, slope, out):
    """out[s, i] = row s of ``values`` (S, G), tabulated on the uniform grid g0 + dg k, linearly
    interpolated at x[s, i] (its slope if ``slope``); 0 (the prior mean) off the grid."""
    S, m = x.shape
    G = values.shape[1]
    for s in range(S):
        for i in range(m):
            r = (x[s, i] - g0) / dg
            if not (r >= 0.0 and r <= G - 1):
                out[s, i] = 0.0
                continue
            j = min(int(r), G - 2)
            f = r - j
            if slope:
                out[s, i] = (values[s, j + 1] - values[s, j]) / dg
            else:
                out[s, i] = values[s, j] + f * (values[s, j + 1] - values[s, j])


TABLE_POINTS = 4001  # grid points of a tabulated 1-D law (``law_grid``), at the least
TABLE_STEP = 0.05  # ... and a grid step of at most this many lengthscales
TABLE_MAX_POINTS = 100_001  # ... up to this many points


def law_grid(x_train: np.ndarray, lengthscale: float) -> np.ndarray:
    """The grid a 1-D law is tabulated on: uniform over its training inputs' range widened by
    min(6 lengthscales, 10 ranges) on each side (the GP's mean has returned to its trend there),
    ``TABLE_POINTS`` points or as many as keep the step within ``TABLE_STEP`` lengthscales (a
    law that varies on a short scale: linear interpolation's error, step^2 / 8 times the law's
    second derivative, stays near 3e-4 of lengthscale^2 times it), at most ``TABLE_MAX_POINTS``."""
    x = np.asarray(x_train, dtype=float)
    ell = float(lengthscale)
    width = min(6.0 * ell, 10.0 * float(np.ptp(x)))
    span = float(np.ptp(x)) + 2.0 * width
    n = TABLE_POINTS
    if ell > 0:
        n = int(min(max(TABLE_POINTS, math.ceil(span / (TABLE_STEP * ell)) + 1), TABLE_MAX_POINTS))
    return np.linspace(x.min() - width, x.max() + width, n)


class Table1D:
    """A 1-D mean tabulated on an increasing grid: linear interpolation, 0 outside."""

    kind = "table"
    dim = 1

    def __init__(self, x: np.ndarray, y: np.ndarray):
        self.tx = np.asarray(x, dtype=float)
        self.ty = np.asarray(y, dtype=float)
        self.tslope = np.diff(self.ty) / np.diff(self.tx)
        # the slope by searchsorted index: 0 left of the grid and right of it
        self._slope_at = np.concatenate([[0.0], self.tslope, [0.0]])

    @classmethod
    def from_gp(cls, gp: GP, grid: np.ndarray) -> Table1D:
        """The exact posterior mean of a 1-D GP tabulated on ``grid``."""
        return cls(grid, gp.predict(np.asarray(grid, dtype=float)[:, None]))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        return np.interp(np.asarray(x, dtype=float), self.tx, self.ty, left=0.0, right=0.0)

    def slope(self, x: np.ndarray) -> np.ndarray:
        """Derivative of the interpolant (segment slope; 0 outside)."""
        return self._slope_at[np.searchsorted(self.tx, x)]


def load_model(stem: str | Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """npz arrays and JSON metadata of a saved model (allow_pickle=False, no factorisation)."""
    stem = Path(stem)
    npz, js = stem.with_suffix(".npz"), stem.with_suffix(".json")
    for p in (npz, js):
        if not p.exists():
            raise FileNotFoundError(f"{p}: GP model file missing")
    with np.load(npz, allow_pickle=False) as f:
        arr = {k: f[k] for k in f.files}
    return arr, json.loads(js.read_text())


def load_evaluator(stem: str | Path) -> KernelMean | Table1D:
    """The rollout evaluator of a saved model: ``table_x/table_y`` -> ``Table1D``;
    ``mean_alpha/mean_beta`` -> the exact posterior mean over all n training points
    (``KernelMean``, truncation ``exact_tol`` of the JSON); ``rollout_pivots/rollout_w`` (the DTC mean
    on a low-rank subset of its inducing inputs), else ``dtc_Z/dtc_w/dtc_beta`` -> DTC
    ``KernelMean``; else the exact mean (factorises once). The evaluator carries the model's
    JSON metadata as ``.meta``."""
    arr, meta = load_model(stem)
    ev: KernelMean | Table1D
    args = (meta["kernel"], meta["basis"], float(meta["sigma_f_std"]), arr["lengthscales"], arr["x_mean"],
            arr["x_scale"], float(np.ravel(arr["y_mean"])[0]), float(np.ravel(arr["y_scale"])[0]))
    if "table_x" in arr:
        ev = Table1D(arr["table_x"], arr["table_y"])
    elif "mean_alpha" in arr:
        U = (arr["X"].reshape(arr["X"].shape[0], -1) - arr["x_mean"]) / arr["x_scale"]
        ev = KernelMean(*args, U, arr["mean_alpha"], arr["mean_beta"], kind="exact",
                        tol=float(meta["exact_tol"]))
    elif "rollout_pivots" in arr:  # the DTC mean on a low-rank subset of its inducing inputs
        Zp = arr["dtc_Z"][arr["rollout_pivots"]]
        ev = KernelMean(*args, Zp, arr["rollout_w"][:, 0], arr["dtc_beta"][:, 0], kind="dtc")
    elif "dtc_Z" in arr:
        ev = KernelMean(*args, arr["dtc_Z"], arr["dtc_w"][:, 0], arr["dtc_beta"][:, 0], kind="dtc")
    else:
        ev = KernelMean.exact(GP.load(stem))
    ev.meta = meta
    ev.name = meta.get("name", Path(stem).name)
    return ev
