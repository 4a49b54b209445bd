"""Evaluators of a GP's posterior mean: the functions a learned rod integrates (Sec. III-B step 4).

Every evaluator is a callable on feature rows, ``f(X)`` with X (..., d) in original units ->
(...,), and the 1-D ones also give ``slope(x)`` (the momentum GPs' dH_p/dp for the damping
flow). They share one representation of a single-output GP mean in the units of ``crgpr.gp``
(u = (x - x_mean) / x_scale, R&W 2006 eq. (2.41)):

    f(x) = y_mean + y_scale (sigma_f^2 sum_m a_m k(u / ell, z_m / ell) + h(u)^T beta),

* ``KernelMean.exact(gp)``: the exact posterior mean, centres z_m = the n training inputs,
  a = K_y^-1 (v - H beta_hat), beta = beta_hat (R&W eq. (2.41)); O(n) per point;
* ``KernelMean.dtc(gp, Z, w, beta)``: the sparse DTC / subset-of-regressors mean (``dtc_fit``),
  centres the M inducing inputs; O(M) per point;
* ``Table1D``: a 1-D mean tabulated on a grid, linear interpolation, 0 (the prior mean)
  outside, with the segment slope;
* posterior samples (``crgpr.gp.sampling.CompressedSamples``) are the same kernel expansion per
  sample plus an RFF prior term, evaluated by the same compiled ``kernel_sum``.

``kernel_sum`` is the one compiled kernel sum of the package: ``kernel_sum`` (IEEE, used by
the means) and ``kernel_sum_fast`` (the same source compiled with fastmath and a polynomial
exp, used by the posterior samples, where 1e-10 relative error is far below the sample
spread). ``load_evaluator(stem)`` builds an evaluator from a saved model (``stem.npz`` +
``stem.json``, ``allow_pickle=False``): its table, else its DTC arrays, else the exact mean.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from crgpr.gp._gpr import GP, GPError

BASIS_ID = {"none": 0, "constant": 1, "linear": 2, "pure_quadratic": 3}
KERNEL_ID = {"se": 0, "matern52": 1}
_SE_POLY = 2  # kernel id of the SE kernel with the polynomial exp (kernel_sum_fast only)


@njit(cache=True, fastmath=True)
def _exp_neg_half(r2):
    """exp(-r2 / 2) for r2 >= 0: r2 clipped at 80 (exp(-40) = 4e-18, i.e. 0 for a kernel),
    exp(u / 64)^64 with a degree-12 Taylor polynomial (relative error < 1e-10): vectorisable."""
    u = -0.5 * min(r2, 80.0) * 0.015625
    p = 1.0
    for k in range(12, 0, -1):
        p = 1.0 + u / k * p
    for _ in range(6):
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


class KernelMean:
    """f(x) = y_mean + y_scale (sigma_f^2 sum_m a_m k(u, z_m) + h(u)^T beta) (module docstring).

    ``Z`` (M, d) standardised centres, ``a`` (M,), ``beta`` (p,) in standardised units.
    """

    def __init__(self, kernel: str, basis: str, sigma_f: float, lengthscales: np.ndarray,
                 x_mean: np.ndarray, x_scale: np.ndarray, y_mean: float, y_scale: float,
                 Z: np.ndarray, a: np.ndarray, beta: np.ndarray, kind: str = "kernel"):
        if kernel not in KERNEL_ID or basis not in BASIS_ID:
            raise GPError(f"compiled mean supports kernels {tuple(KERNEL_ID)} and bases "
                          f"{tuple(BASIS_ID)}, got {kernel!r} / {basis!r}")
        Z = np.atleast_2d(np.asarray(Z, dtype=float))
        self.dim = Z.shape[1]
        self.kind = kind
        self.kernel_id, self.basis_id = KERNEL_ID[kernel], BASIS_ID[basis]
        self.ell = np.broadcast_to(np.ravel(np.asarray(lengthscales, dtype=float)), (self.dim,)).copy()
        self.x_mean = np.ravel(np.asarray(x_mean, dtype=float))
        self.x_scale = np.ravel(np.asarray(x_scale, dtype=float))
        self.y_mean, self.y_scale = float(y_mean), float(y_scale)
        self.sf2 = float(sigma_f) ** 2
        self.ZlT = np.ascontiguousarray((Z / self.ell).T)
        self.a = np.ascontiguousarray(np.ravel(a), dtype=float)[None, :]
        self.beta = np.ascontiguousarray(np.ravel(beta), dtype=float)
        if self.a.shape[1] != Z.shape[0]:
            raise GPError(f"{self.a.shape[1]} weights for {Z.shape[0]} centres")

    @classmethod
    def exact(cls, gp: GP) -> KernelMean:
        """The exact posterior mean of a fitted single-output GP (R&W eq. (2.41))."""
        if gp.multi:
            raise GPError("KernelMean needs a single-output GP")
        gp.ensure_factorised()
        return cls(gp.kernel, gp.basis, gp.sigma_f, gp.lengthscales, gp.x_mean, gp.x_scale,
                   float(np.ravel(gp.y_mean)[0]), float(np.ravel(gp.y_scale)[0]),
                   gp.standardise_x(gp.X), gp.alpha[:, 0], gp.beta[:, 0], kind="exact")

    @classmethod
    def dtc(cls, gp: GP, Z: np.ndarray, w: np.ndarray, beta: np.ndarray) -> KernelMean:
        """The DTC mean with inducing inputs Z and coefficients (w, beta) of ``dtc_fit``."""
        return cls(gp.kernel, gp.basis, gp.sigma_f, gp.lengthscales, gp.x_mean, gp.x_scale,
                   float(np.ravel(gp.y_mean)[0]), float(np.ravel(gp.y_scale)[0]), Z, w, beta,
                   kind="dtc")

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        X2 = np.ascontiguousarray(X.reshape(-1, X.shape[-1]))
        out = np.empty(X2.shape[0])
        _kernel_mean(X2, self.x_mean, self.x_scale, self.ell, self.ZlT, self.a, self.sf2, self.beta,
                     self.basis_id, self.kernel_id, self.y_mean, self.y_scale, out)
        return out.reshape(X.shape[:-1])


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
    """The rollout evaluator of a saved model: ``table_x/table_y`` -> ``Table1D``,
    ``dtc_Z/dtc_w/dtc_beta`` -> DTC ``KernelMean``, else the exact mean (factorises once).
    The evaluator carries the model's JSON metadata as ``.meta``."""
    arr, meta = load_model(stem)
    ev: KernelMean | Table1D
    if "table_x" in arr:
        ev = Table1D(arr["table_x"], arr["table_y"])
    elif "dtc_Z" in arr:
        ev = KernelMean(meta["kernel"], meta["basis"], float(meta["sigma_f_std"]), arr["lengthscales"],
                        arr["x_mean"], arr["x_scale"], float(np.ravel(arr["y_mean"])[0]),
                        float(np.ravel(arr["y_scale"])[0]), arr["dtc_Z"], arr["dtc_w"][:, 0],
                        arr["dtc_beta"][:, 0], kind="dtc")
    else:
        ev = KernelMean.exact(GP.load(stem))
    ev.meta = meta
    ev.name = meta.get("name", Path(stem).name)
    return ev
