"""Exact Gaussian-process regression with explicit basis functions (numpy/scipy only).

Used by every GP of the CR-GPR pipeline (paper Sec. III-B steps 2-3, Table II):

* kernels ``'se'`` (squared exponential) and ``'matern52'``, isotropic or ARD
  (``ard=True``; ``'ard_se'`` is an alias of ``'se'`` with ``ard=True``);
* explicit basis h(x): ``'none'``, ``'constant'`` [1], ``'linear'`` [1, x_k],
  ``'pure_quadratic'`` [1, x_k, x_k^2] (no cross terms), ``'quadratic'`` (full: adds the
  cross terms x_k x_l; in 1D this is [1, x, x^2]);
* the basis coefficients are estimated jointly with the GP in the vague-prior limit of
  Rasmussen & Williams (2006) Sec. 2.7:
      beta_hat = (H K^-1 H^T)^-1 H K^-1 y,
      mean(x*) = h(x*)^T beta_hat + k*^T K^-1 (y - H^T beta_hat),              (R&W 2.41)
      var(x*)  = k** - k*^T K^-1 k* + R^T (H K^-1 H^T)^-1 R,  R = h* - H K^-1 k*  (R&W 2.42)
  and the log marginal likelihood is the vague-prior (restricted) one, R&W eq. (2.45):
      log p = -1/2 y^T P y - 1/2 log|K| - 1/2 log|H K^-1 H^T| - (n - m)/2 log 2 pi,
      P = K^-1 - K^-1 H^T (H K^-1 H^T)^-1 H K^-1,
  with the analytic gradient d log p / d th = 1/2 a^T dK a - 1/2 tr(P dK), a = P y;
* inputs standardised per dimension (u = (x - x_mean) / x_scale) and outputs per column
  (v = (y - y_mean) / y_scale); hyperparameters live in these standardised units;
* hyperparameters (sigma_f, lengthscales, sigma_n) maximise the log marginal likelihood
  (L-BFGS-B with bounds on the log parameters, a few restarts from a fixed seed); sigma_n
  has a configurable LOWER BOUND given in output units (or as a variance in standardised
  units for the paper's 1e-9 of the state GPs);
* several output columns may share one set of hyperparameters (their LMLs are summed;
  one Cholesky factor serves all columns), used by the time prefilter;
* analytic derivatives of the posterior mean w.r.t. a 1D input (first and second).

Everything a pathwise / random-Fourier-feature sampler needs is public on ``GP``:
``kernel``, ``ard``, ``basis``, ``sigma_f``, ``lengthscales`` and ``sigma_n`` (standardised
units), ``x_mean``, ``x_scale``, ``y_mean``, ``y_scale``, training ``X`` and ``Y`` (original
units), ``basis_matrix(x)`` (rows h(u)^T in standardised inputs), ``beta`` and ``alpha``.
In original units the function is f(x) = y_mean + y_scale * g((x - x_mean) / x_scale) where
g ~ GP(h(u)^T beta, k(u, u')) with k of ``sigma_f`` and ``lengthscales``.

Serialisation: ``save(stem)`` writes ``stem.npz`` (arrays) and ``stem.json`` (kernel, basis,
hyperparameters, standardisation, n); ``GP.load(stem)`` reads them with allow_pickle=False.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg as sla
from numba import njit

KERNELS = ("se", "matern52")
BASES = ("none", "constant", "linear", "pure_quadratic", "quadratic")
SQRT5 = math.sqrt(5.0)
KERNEL_ID = {"se": 0, "matern52": 1}
_LOG2PI = math.log(2.0 * math.pi)


class GPError(ValueError):
    """Bad GP input (shape, kernel name, non-finite data)."""


# ---------------------------------------------------------------------------------------------
# kernels (standardised inputs)
# ---------------------------------------------------------------------------------------------
def _sqdist_scaled(A: np.ndarray, B: np.ndarray, ell: np.ndarray) -> np.ndarray:
    """Squared distances sum_k ((a_k - b_k) / ell_k)^2 between rows of A and B."""
    a = A / ell
    b = B / ell
    if a.shape[1] <= 16:  # direct differences: no cancellation (smooth, exact derivatives)
        d2 = np.zeros((a.shape[0], b.shape[0]))
        for k in range(a.shape[1]):
            d2 += (a[:, k][:, None] - b[:, k][None, :]) ** 2
        return d2
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.maximum(d2, 0.0)


def kernel_matrix(kernel: str, A: np.ndarray, B: np.ndarray, sigma_f: float,
                  ell: np.ndarray) -> np.ndarray:
    """k(A, B) for standardised inputs (rows); ``ell`` has one entry per dimension."""
    r2 = _sqdist_scaled(A, B, ell)
    if kernel == "se":
        return sigma_f**2 * np.exp(-0.5 * r2)
    if kernel == "matern52":
        r = np.sqrt(r2)
        return sigma_f**2 * (1.0 + SQRT5 * r + (5.0 / 3.0) * r2) * np.exp(-SQRT5 * r)
    raise GPError(f"unknown kernel {kernel!r}; expected one of {KERNELS}")


@njit(cache=True, inline="always")
def _kernel_value(Ul, i, j, kernel_id, sf2):
    """k(Ul_i, Ul_j) for scaled inputs (SE: kernel_id 0, else Matern-5/2); the one scalar kernel
    of the compiled loops (``_fill_kernel`` here, ``_kernel_column`` / ``_kernel_matvec`` in
    ``evaluators``)."""
    r2 = 0.0
    for k in range(Ul.shape[1]):
        dd = Ul[i, k] - Ul[j, k]
        r2 += dd * dd
    if kernel_id == 0:
        return sf2 * math.exp(-0.5 * r2)
    r = math.sqrt(r2)
    return sf2 * (1.0 + SQRT5 * r + (5.0 / 3.0) * r2) * math.exp(-SQRT5 * r)


# Off-diagonal kernel entries below KERNEL_FLOOR noise2 / n are stored as 0 (``_fill_kernel``)
KERNEL_FLOOR = 1e-17


@njit(cache=True)
def _fill_kernel(Ul, kernel_id, sf2, noise2, K):
    """K = k(U, U) + noise2 I (lower triangle and diagonal) for scaled inputs, in place.

    Off-diagonal entries below ``KERNEL_FLOOR`` noise2 / n are stored as 0: what is dropped, E,
    has ||E||_2 <= n max|E_ij| <= 1e-17 noise2 <= 1e-17 lambda_min(K), below the round-off of
    K's diagonal, so the solve is the same to round-off; and a Cholesky factorisation of inputs
    far apart (SE: exp(-r^2 / 2) underflows to subnormal numbers, whose arithmetic is slow on
    x86) keeps the speed of normal numbers (``benchmarks/kernel_floor.py``)."""
    n = Ul.shape[0]
    floor = KERNEL_FLOOR * noise2 / n
    for i in range(n):
        for j in range(i):
            v = _kernel_value(Ul, i, j, kernel_id, sf2)
            K[i, j] = v if v >= floor else 0.0
        K[i, i] = _kernel_value(Ul, i, i, kernel_id, sf2) + noise2


@njit(cache=True)
def _lengthscale_traces(Ul: np.ndarray, sf2: float, kernel_id: int, W: np.ndarray) -> np.ndarray:
    """sum_ij W_ij dK_ij / d log ell_k for every input k (W symmetric; Ul = U / ell), without
    forming dK: dK_ij / d log ell_k = base_ij (Ul_ik - Ul_jk)^2."""
    n, d = Ul.shape
    g = np.zeros(d)
    t2 = np.empty(d)
    for i in range(n):
        for j in range(i):
            r2 = 0.0
            for k in range(d):
                t = Ul[i, k] - Ul[j, k]
                t2[k] = t * t
                r2 += t2[k]
            if kernel_id == 0:
                base = sf2 * math.exp(-0.5 * r2)
            else:
                r = math.sqrt(r2)
                base = sf2 * (5.0 / 3.0) * (1.0 + SQRT5 * r) * math.exp(-SQRT5 * r)
            w = 2.0 * W[i, j] * base
            for k in range(d):
                g[k] += w * t2[k]
    return g


def basis_matrix_std(basis: str, U: np.ndarray) -> np.ndarray:
    """Basis functions h(u) as rows (n, m) for standardised inputs U (n, d)."""
    n, d = U.shape
    cols = []
    if basis == "none":
        return np.zeros((n, 0))
    cols.append(np.ones(n))
    if basis == "constant":
        return np.stack(cols, axis=1)
    cols += [U[:, k] for k in range(d)]
    if basis == "linear":
        return np.stack(cols, axis=1)
    cols += [U[:, k] ** 2 for k in range(d)]
    if basis == "pure_quadratic":
        return np.stack(cols, axis=1)
    if basis == "quadratic":
        cols += [U[:, k] * U[:, l] for k in range(d) for l in range(k + 1, d)]
        return np.stack(cols, axis=1)
    raise GPError(f"unknown basis {basis!r}; expected one of {BASES}")


def _basis_derivs_1d(basis: str, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d h / du and d2 h / du2 for a 1D input (rows)."""
    n = u.shape[0]
    z, o = np.zeros(n), np.ones(n)
    if basis == "none":
        return np.zeros((n, 0)), np.zeros((n, 0))
    if basis == "constant":
        return z[:, None], z[:, None]
    if basis == "linear":
        return np.stack([z, o], 1), np.stack([z, z], 1)
    if basis in ("pure_quadratic", "quadratic"):
        return np.stack([z, o, 2.0 * u], 1), np.stack([z, z, 2.0 * o], 1)
    raise GPError(f"unknown basis {basis!r}")


def _kernel_derivs_1d(kernel: str, d: np.ndarray, sigma_f: float, ell: float
                      ) -> tuple[np.ndarray, np.ndarray]:
    """dk/dd and d2k/dd2 of a stationary 1D kernel at lag d = u* - u (standardised)."""
    if kernel == "se":
        k = sigma_f**2 * np.exp(-0.5 * d**2 / ell**2)
        return -d / ell**2 * k, (d**2 / ell**4 - 1.0 / ell**2) * k
    if kernel == "matern52":
        a = SQRT5 / ell
        ad = a * np.abs(d)
        e = np.exp(-ad)
        c = sigma_f**2 * a * a / 3.0
        return -c * d * (1.0 + ad) * e, -c * (1.0 + ad - ad * ad) * e
    raise GPError(f"unknown kernel {kernel!r}")


# ---------------------------------------------------------------------------------------------
# the model
# ---------------------------------------------------------------------------------------------
@dataclass
class GP:
    """A fitted exact GP (see module docstring for the formulas and units)."""

    kernel: str
    ard: bool
    basis: str
    sigma_f: float
    lengthscales: np.ndarray
    sigma_n: float
    x_mean: np.ndarray
    x_scale: np.ndarray
    y_mean: np.ndarray
    y_scale: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    lml: float = float("nan")
    info: dict[str, Any] = field(default_factory=dict)
    # derived by _factorise
    beta: np.ndarray = field(default=None, repr=False)  # (m, k) basis coefficients (std units)
    alpha: np.ndarray = field(default=None, repr=False)  # (n, k) K^-1 (v - H^T beta)
    _chol: Any = field(default=None, repr=False)
    _Hs: np.ndarray = field(default=None, repr=False)
    _A_chol: Any = field(default=None, repr=False)
    # standardised training data when built by ``from_standardised`` (kept exactly)
    _U: np.ndarray = field(default=None, repr=False)
    _v: np.ndarray = field(default=None, repr=False)
    name: str = "gp"

    @classmethod
    def from_standardised(cls, U: np.ndarray, v: np.ndarray, sigma_f: float, lengthscales: np.ndarray,
                          sigma_n: float, basis: str, x_mean: np.ndarray, x_scale: np.ndarray,
                          y_mean: float = 0.0, y_scale: float = 1.0, name: str = "gp",
                          kernel: str = "se") -> GP:
        """A single-output GP from standardised inputs U (n, d) and targets v (n,) with given
        hyperparameters (standardised units); U and v are kept exactly (``Xs``, ``y``)."""
        U = np.atleast_2d(np.asarray(U, dtype=float))
        v = np.asarray(v, dtype=float).ravel()
        d = U.shape[1]
        ell = np.broadcast_to(np.asarray(lengthscales, dtype=float), (d,)).copy()
        x_mean = np.broadcast_to(np.asarray(x_mean, dtype=float), (d,)).copy()
        x_scale = np.broadcast_to(np.asarray(x_scale, dtype=float), (d,)).copy()
        if v.shape[0] != U.shape[0]:
            raise GPError(f"{name}: {U.shape[0]} inputs but {v.shape[0]} targets")
        if not (sigma_f > 0 and sigma_n > 0 and np.all(ell > 0)):
            raise GPError(f"{name}: sigma_f, sigma_n and lengthscales must be > 0")
        basis_matrix_std(basis, U[:1])  # validates the name
        gp = cls(kernel=kernel, ard=True, basis=basis, sigma_f=float(sigma_f), lengthscales=ell,
                 sigma_n=float(sigma_n), x_mean=x_mean, x_scale=x_scale,
                 y_mean=np.array([float(y_mean)]), y_scale=np.array([float(y_scale)]),
                 X=x_mean + U * x_scale, Y=float(y_mean) + float(y_scale) * v, name=name)
        gp._U, gp._v = U, v
        return gp

    # ---- the standardised single-output view (posterior samplers, crgpr.gp.sampling) ---------
    @property
    def Xs(self) -> np.ndarray:
        """Standardised training inputs u = (x - x_mean) / x_scale (n, d)."""
        return self._U if self._U is not None else self.standardise_x(self.X)

    @property
    def y(self) -> np.ndarray:
        """Standardised targets v = (y - y_mean) / y_scale (n,) of a single-output GP."""
        return self._v if self._v is not None else self._V()[:, 0]

    @property
    def ell(self) -> np.ndarray:
        """Lengthscales (standardised units), one per input dimension (d,)."""
        return np.broadcast_to(np.ravel(self.lengthscales), (self.dim,)).astype(float)

    @property
    def x_std(self) -> np.ndarray:
        return self.x_scale

    @property
    def out_mean(self) -> float:
        """y_mean of a single-output GP as a float."""
        return float(np.ravel(self.y_mean)[0])

    @property
    def out_scale(self) -> float:
        """y_scale of a single-output GP as a float."""
        return float(np.ravel(self.y_scale)[0])

    def standardise(self, x: np.ndarray) -> np.ndarray:
        """(x - x_mean) / x_scale for inputs of any leading shape (..., d)."""
        return (np.asarray(x, dtype=float) - self.x_mean) / self.x_scale

    def basis_fn(self, U: np.ndarray) -> np.ndarray:
        """Basis rows h(u) (n, m) at standardised inputs U."""
        return basis_matrix_std(self.basis, np.atleast_2d(np.asarray(U, dtype=float)))

    def to_output(self, g: np.ndarray) -> np.ndarray:
        """Standardised function values -> original output units (single output)."""
        return self.out_mean + self.out_scale * g

    # ---- construction ------------------------------------------------------------------------
    @property
    def n(self) -> int:
        return int(self.X.shape[0])

    @property
    def dim(self) -> int:
        return int(self.X.shape[1])

    @property
    def multi(self) -> bool:
        """True when fitted to several output columns."""
        return self.Y.ndim == 2 and self.Y.shape[1] > 1 and self.info.get("multi", False)

    def standardise_x(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        if X.ndim == 1:
            X = X[:, None] if self.dim == 1 else X[None, :]
        if X.shape[1] != self.dim:
            raise GPError(f"input has {X.shape[1]} columns, the GP was fitted with {self.dim}")
        return (X - self.x_mean) / self.x_scale

    def basis_matrix(self, X: np.ndarray) -> np.ndarray:
        """Basis rows h(u) (n, m) at original-unit inputs X (standardised internally)."""
        return basis_matrix_std(self.basis, self.standardise_x(X))

    def _V(self) -> np.ndarray:
        if self._v is not None:
            return self._v[:, None]
        Y = self.Y if self.Y.ndim == 2 else self.Y[:, None]
        return (Y - self.y_mean) / self.y_scale

    def ensure_factorised(self) -> None:
        """Cholesky factor of K + sigma_n^2 I over all n points (done once, on demand)."""
        if self.alpha is None:
            self._factorise()

    def _factorise(self) -> None:
        U = self.Xs
        ell = np.broadcast_to(self.lengthscales, (self.dim,)).astype(float)
        K = kernel_matrix(self.kernel, U, U, self.sigma_f, ell)
        K[np.diag_indices_from(K)] += self.sigma_n**2
        self._chol = sla.cho_factor(K, lower=True, check_finite=False)
        V = self._V()
        Hs = basis_matrix_std(self.basis, U)  # (n, m)
        self._Hs = Hs
        KiV = sla.cho_solve(self._chol, V, check_finite=False)
        if Hs.shape[1]:
            KiH = sla.cho_solve(self._chol, Hs, check_finite=False)
            A = Hs.T @ KiH
            self._A_chol = sla.cho_factor(A, lower=True, check_finite=False)
            self.beta = sla.cho_solve(self._A_chol, Hs.T @ KiV, check_finite=False)
            self.alpha = KiV - KiH @ self.beta
        else:
            self.beta = np.zeros((0, V.shape[1]))
            self.alpha = KiV

    # ---- prediction --------------------------------------------------------------------------
    def _out(self, M: np.ndarray) -> np.ndarray:
        """Back to output units; squeeze the column axis of a single-output GP."""
        out = M * self.y_scale + self.y_mean
        return out if self.multi else out[:, 0]

    def predict(self, Xs: np.ndarray, return_var: bool = False, chunk: int = 4096):
        """Posterior mean (and latent variance, output units^2) at inputs Xs (original units)."""
        self.ensure_factorised()
        Us = self.standardise_x(Xs)
        U = self.Xs
        ell = np.broadcast_to(self.lengthscales, (self.dim,)).astype(float)
        means, vars_ = [], []
        for s in range(0, Us.shape[0], chunk):
            u = Us[s:s + chunk]
            Ks = kernel_matrix(self.kernel, u, U, self.sigma_f, ell)  # (c, n)
            Hs = basis_matrix_std(self.basis, u)
            means.append(Ks @ self.alpha + Hs @ self.beta)
            if return_var:
                v = sla.cho_solve(self._chol, Ks.T, check_finite=False)  # K^-1 k*
                var = self.sigma_f**2 - np.einsum("ij,ji->i", Ks, v)
                if self._Hs.shape[1]:
                    R = Hs.T - self._Hs.T @ v  # (m, c)
                    var = var + np.einsum("ij,ij->j", R, sla.cho_solve(self._A_chol, R,
                                                                         check_finite=False))
                vars_.append(np.maximum(var, 0.0))
        mean = self._out(np.concatenate(means, axis=0))
        if not return_var:
            return mean
        var = np.concatenate(vars_)[:, None] * self.y_scale**2
        return mean, (var if self.multi else var[:, 0])

    def predict_derivatives(self, xs: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Posterior mean and its analytic first and second derivatives for a 1D input."""
        if self.dim != 1:
            raise GPError("predict_derivatives needs a GP with a 1D input")
        us = self.standardise_x(np.asarray(xs, dtype=float).reshape(-1, 1))[:, 0]
        u = self.standardise_x(self.X)[:, 0]
        d = us[:, None] - u[None, :]
        k1, k2 = _kernel_derivs_1d(self.kernel, d, self.sigma_f, float(np.ravel(self.lengthscales)[0]))
        h1, h2 = _basis_derivs_1d(self.basis, us)
        m = self.predict(xs)  # factorises if needed
        xs_ = float(self.x_scale[0])
        d1 = (k1 @ self.alpha + h1 @ self.beta) * self.y_scale / xs_
        d2 = (k2 @ self.alpha + h2 @ self.beta) * self.y_scale / xs_**2
        if not self.multi:
            d1, d2 = d1[:, 0], d2[:, 0]
        return m, d1, d2

    def hyperparameters(self) -> dict[str, Any]:
        """Hyperparameters in standardised and in original units (for tables)."""
        ell = np.broadcast_to(self.lengthscales, (self.dim,)).astype(float)
        ys = float(np.mean(self.y_scale))
        return {
            "kernel": self.kernel, "ard": self.ard, "basis": self.basis, "n": self.n, "dim": self.dim,
            "sigma_f_std": self.sigma_f, "lengthscales_std": np.ravel(self.lengthscales).tolist(),
            "sigma_n_std": self.sigma_n,
            "sigma_f": self.sigma_f * ys, "lengthscales": (ell * self.x_scale).tolist(),
            "sigma_n": self.sigma_n * ys, "lml": self.lml,
        }

    # ---- (de)serialisation -------------------------------------------------------------------
    def save(self, stem: str | Path, extra: dict[str, Any] | None = None,
             extra_arrays: dict[str, np.ndarray] | None = None) -> tuple[Path, Path]:
        """Write ``stem.npz`` (arrays) and ``stem.json`` (everything else), atomically.

        ``extra_arrays`` (e.g. an approximation of the mean) are stored in the same npz;
        ``load`` ignores them.
        """
        from crgpr.io import write_json, write_npz

        stem = Path(stem)
        npz = stem.with_suffix(".npz")
        js = stem.with_suffix(".json")
        write_npz(npz, X=self.X, Y=self.Y, x_mean=self.x_mean, x_scale=self.x_scale,
                  y_mean=self.y_mean, y_scale=self.y_scale,
                  lengthscales=np.ravel(np.asarray(self.lengthscales, dtype=float)),
                  **(extra_arrays or {}))
        meta = {**self.hyperparameters(), "multi": self.multi, "info": self.info,
                "x_mean": self.x_mean, "x_scale": self.x_scale, "y_mean": self.y_mean,
                "y_scale": self.y_scale, "standardisation": "u = (x - x_mean) / x_scale; "
                "v = (y - y_mean) / y_scale; hyperparameters *_std in u, v units",
                **(extra or {})}
        write_json(meta, js)
        return npz, js

    @classmethod
    def load(cls, stem: str | Path) -> GP:
        stem = Path(stem)
        npz = stem.with_suffix(".npz")
        js = stem.with_suffix(".json")
        for p in (npz, js):
            if not p.exists():
                raise FileNotFoundError(f"{p}: GP model file missing")
        with np.load(npz, allow_pickle=False) as a:
            arr = {k: a[k] for k in a.files}
        meta = json.loads(js.read_text())
        gp = cls(kernel=meta["kernel"], ard=bool(meta["ard"]), basis=meta["basis"],
                 sigma_f=float(meta["sigma_f_std"]), lengthscales=arr["lengthscales"],
                 sigma_n=float(meta["sigma_n_std"]), x_mean=arr["x_mean"], x_scale=arr["x_scale"],
                 y_mean=arr["y_mean"], y_scale=arr["y_scale"], X=arr["X"], Y=arr["Y"],
                 lml=float(meta.get("lml", float("nan"))),
                 info={**meta.get("info", {}), "multi": bool(meta.get("multi", False))})
        return gp  # factorised on the first prediction (ensure_factorised)


# ---------------------------------------------------------------------------------------------
# fitting
# ---------------------------------------------------------------------------------------------
def _inverse_from_cholesky(L: np.ndarray) -> np.ndarray:
    """K^-1 from its lower Cholesky factor (LAPACK potri: 2/3 n^3 flops, a third of a solve with I)."""
    inv, info = sla.lapack.dpotri(L, lower=1)
    if info != 0:
        raise np.linalg.LinAlgError(f"potri failed (info {info})")
    return np.tril(inv) + np.tril(inv, -1).T


def _neg_lml(theta: np.ndarray, kernel: str, ard: bool, U: np.ndarray, V: np.ndarray,
             Hs: np.ndarray) -> tuple[float, np.ndarray]:
    """Negative (restricted) log marginal likelihood summed over columns, and its gradient.

    theta = [log sigma_f, log ell (1 or d), log sigma_n], standardised units (R&W 2.45).
    """
    d = U.shape[1]
    sf = math.exp(theta[0])
    ell = np.exp(theta[1:-1]) if ard else np.full(d, math.exp(theta[1]))
    sn = math.exp(theta[-1])
    n, k = V.shape
    if kernel not in KERNELS:
        raise GPError(f"unknown kernel {kernel!r}; expected one of {KERNELS}")
    kid = KERNEL_ID[kernel]
    Ul = np.ascontiguousarray(U / ell)
    K = np.empty((n, n))
    _fill_kernel(Ul, kid, sf * sf, sn**2, K)  # lower triangle and diagonal, noise included
    try:
        L = sla.cholesky(K, lower=True, check_finite=False)
    except np.linalg.LinAlgError:
        return 1e25, np.zeros_like(theta)
    Kinv = _inverse_from_cholesky(L)
    logdet = 2.0 * np.log(np.diag(L)).sum()
    m = Hs.shape[1]
    if m:
        KiH = Kinv @ Hs
        A = Hs.T @ KiH
        try:
            LA = sla.cholesky(A, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            return 1e25, np.zeros_like(theta)
        P = Kinv - KiH @ sla.cho_solve((LA, True), KiH.T, check_finite=False)
        logdetA = 2.0 * np.log(np.diag(LA)).sum()
    else:
        P = Kinv
        logdetA = 0.0
    Alpha = P @ V  # (n, k)
    lml = -0.5 * np.einsum("ij,ij->", V, Alpha) - 0.5 * k * (logdet + logdetA) - 0.5 * k * (n - m) * _LOG2PI
    W = Alpha @ Alpha.T - k * P  # d lml / dth = 1/2 tr(W dK)
    trW = float(np.trace(W))
    # dK / d log sigma_f = 2 K without the noise; K holds its lower triangle and the noisy diagonal
    g = [2.0 * np.einsum("ij,ij->", W, np.tril(K, -1)) + sf * sf * trW]
    gl = 0.5 * _lengthscale_traces(Ul, sf * sf, kid, W)
    g += list(gl) if ard else [float(gl.sum())]
    g.append(0.5 * trW * 2.0 * sn**2)
    return -lml, -np.asarray(g)


ELL_BOUNDS_STD: tuple[float, float] = (1e-3, 1e2)  # fit_gp's default lengthscale box, standardised units


def fit_gp(X: np.ndarray, Y: np.ndarray, kernel: str = "se", basis: str = "none", ard: bool = False,
           sigma_n_min: float | None = None, noise_var_min_std: float | None = None,
           n_restarts: int = 3, seed: int = 0, hyper_subset: int | None = None,
           standardise_y: bool = True, init: dict[str, Any] | None = None,
           fixed: dict[str, Any] | None = None, maxiter: int = 200, factorise: bool = True,
           ell_bounds: tuple[np.ndarray, np.ndarray] | None = None,
           sigma_f_bounds: tuple[float, float] | None = None) -> GP:
    """Fit an exact GP by maximising the log marginal likelihood (R&W Sec. 2.7, eq. 2.45).

    X (n, d) or (n,); Y (n,) or (n, k) with k columns sharing the hyperparameters.
    ``sigma_n_min``: lower bound on sigma_n in OUTPUT units (paper Table II for the gradient
    GPs); ``noise_var_min_std``: lower bound on the noise VARIANCE in standardised units (the
    paper's 1e-9 of the state GPs); the larger bound wins. ``hyper_subset``: optimise on a
    random subset of this many points (seeded), then condition on all points.
    ``fixed``: skip the optimisation and use these standardised hyperparameters
    ({'sigma_f', 'lengthscales', 'sigma_n'}). ``factorise=False`` defers the O(n^3) Cholesky
    factorisation over all n points to the first prediction. ``ell_bounds`` (lower, upper),
    one entry per input dimension, and ``sigma_f_bounds`` (lower, upper): box constraints of
    the search in standardised units (default: sigma_f in [1e-2, 1e1], every ell in [1e-3, 1e2]);
    an isotropic kernel takes the widest of the per-dimension bounds.
    """
    if kernel == "ard_se":
        kernel, ard = "se", True
    if kernel not in KERNELS:
        raise GPError(f"unknown kernel {kernel!r}; expected one of {KERNELS} or 'ard_se'")
    if basis not in BASES:
        raise GPError(f"unknown basis {basis!r}; expected one of {BASES}")
    X = np.asarray(X, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    Y = np.asarray(Y, dtype=float)
    multi = Y.ndim == 2
    Y2 = Y if multi else Y[:, None]
    if X.shape[0] != Y2.shape[0]:
        raise GPError(f"X has {X.shape[0]} rows but Y has {Y2.shape[0]}")
    if not (np.all(np.isfinite(X)) and np.all(np.isfinite(Y2))):
        raise GPError("non-finite values in the GP training data")
    n, d = X.shape
    x_mean = X.mean(0)
    x_scale = X.std(0)
    x_scale[x_scale <= 1e-300] = 1.0
    if standardise_y:
        y_mean = Y2.mean(0)
        y_scale = Y2.std(0)
        y_scale[y_scale <= 1e-300] = 1.0
    else:
        y_mean, y_scale = np.zeros(Y2.shape[1]), np.ones(Y2.shape[1])
    U = (X - x_mean) / x_scale
    V = (Y2 - y_mean) / y_scale
    # noise lower bound in standardised units (columns share sigma_n: use the largest bound)
    lo = 1e-6
    if sigma_n_min is not None:
        lo = max(lo, float(np.max(sigma_n_min / y_scale)))
    if noise_var_min_std is not None:
        lo = max(lo, math.sqrt(noise_var_min_std))
    n_ell = d if ard else 1
    info: dict[str, Any] = {"multi": multi, "sigma_n_lower_std": lo, "n_restarts": n_restarts,
                            "seed": seed}
    if fixed is not None:
        sf = float(fixed["sigma_f"])
        ell = np.broadcast_to(np.asarray(fixed["lengthscales"], float), (n_ell,)).copy()
        sn = max(float(fixed["sigma_n"]), lo)
        lml = float("nan")
        info["hyper"] = "fixed"
    else:
        rng = np.random.default_rng(seed)
        idx = np.arange(n)
        if hyper_subset is not None and hyper_subset < n:
            idx = np.sort(rng.choice(n, size=hyper_subset, replace=False))
        info["hyper_n"] = int(idx.size)
        Us, Vs = U[idx], V[idx]
        Hs = basis_matrix_std(basis, Us)
        # standardised units: sigma_f in [1e-2, 1e1] (the basis carries the trend) and
        # lengthscales in [1e-3, 1e2]; wider bounds only buy ill-conditioning
        sf_lo, sf_hi = sigma_f_bounds if sigma_f_bounds is not None else (1e-2, 1e1)
        if ell_bounds is None:
            ell_b = [tuple(math.log(b) for b in ELL_BOUNDS_STD)] * n_ell
        else:
            el_lo = np.broadcast_to(np.asarray(ell_bounds[0], float), (d,))
            el_hi = np.broadcast_to(np.asarray(ell_bounds[1], float), (d,))
            if np.any(el_lo <= 0) or np.any(el_hi <= el_lo):
                raise GPError(f"lengthscale bounds must satisfy 0 < lower < upper, got {ell_bounds}")
            ell_b = ([(math.log(a), math.log(b)) for a, b in zip(el_lo, el_hi, strict=True)] if ard
                     else [(math.log(el_lo.min()), math.log(el_hi.max()))])
            info["ell_bounds_std"] = [el_lo.tolist(), el_hi.tolist()]
        info["sigma_f_bounds_std"] = [sf_lo, sf_hi]
        bounds = [(math.log(sf_lo), math.log(sf_hi))] + ell_b \
            + [(math.log(lo), math.log(max(10.0 * lo, 1.0)))]
        init = init or {}
        x0s = [np.array([math.log(init.get("sigma_f", 1.0))]
                        + [math.log(v) for v in np.broadcast_to(init.get("lengthscales", 1.0), (n_ell,))]
                        + [math.log(max(init.get("sigma_n", 0.1), lo * 1.01))])]
        for _ in range(n_restarts):
            x0s.append(np.array([rng.uniform(-1.0, 1.0)] + list(rng.uniform(-1.5, 1.5, n_ell))
                                + [rng.uniform(math.log(lo), math.log(max(10.0 * lo, 1.0)))]))
        from scipy.optimize import minimize  # here: a rule that only evaluates a GP skips its import

        best = None
        for x0 in x0s:
            x0 = np.clip(x0, [b[0] for b in bounds], [b[1] for b in bounds])
            res = minimize(_neg_lml, x0, args=(kernel, ard, Us, Vs, Hs), jac=True,
                           method="L-BFGS-B", bounds=bounds, options={"maxiter": maxiter})
            if best is None or res.fun < best.fun:
                best = res
        th = best.x
        sf, ell, sn = math.exp(th[0]), np.exp(th[1:-1]), math.exp(th[-1])
        lml = -float(best.fun)
        info["hyper"] = "lml"
        info["optimizer_message"] = str(best.message)
    gp = GP(kernel=kernel, ard=ard, basis=basis, sigma_f=sf, lengthscales=np.asarray(ell, float),
            sigma_n=sn, x_mean=x_mean, x_scale=x_scale, y_mean=y_mean, y_scale=y_scale,
            X=X, Y=Y, lml=lml, info=info)
    if factorise:
        gp._factorise()
    return gp


def smooth_series(t: np.ndarray, y: np.ndarray, t_out: np.ndarray | None = None,
                  noise_std_min: float = 0.0, noise_var_min_std: float = 1e-9,
                  kernel: str = "matern52", basis: str = "quadratic", seed: int = 0,
                  n_restarts: int = 2, max_points: int | None = 1500
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, GP]:
    """Smooth and differentiate one (possibly noisy, non-uniformly sampled) time series.

    Fits a 1D GP (default Matern-5/2 + quadratic basis, paper Table II state GPs) to y(t)
    (several columns share hyperparameters) and returns the posterior mean and its analytic
    first and second time derivatives at ``t_out`` (default: ``t``), plus the GP. For noisy
    data give ``noise_std_min`` (output units), e.g. the sensor noise level. ``max_points``:
    fit on at most this many (evenly spaced in index) samples.
    """
    t = np.asarray(t, dtype=float).ravel()
    y = np.asarray(y, dtype=float)
    if y.shape[0] != t.size:
        raise GPError(f"t has {t.size} samples but y has {y.shape[0]}")
    idx = np.arange(t.size)
    if max_points is not None and t.size > max_points:
        idx = np.unique(np.linspace(0, t.size - 1, max_points).round().astype(int))
    gp = fit_gp(t[idx], y[idx], kernel=kernel, basis=basis, sigma_n_min=noise_std_min or None,
                noise_var_min_std=noise_var_min_std, n_restarts=n_restarts, seed=seed,
                init={"lengthscales": 0.3, "sigma_n": max(1e-3, math.sqrt(noise_var_min_std))})
    m, d1, d2 = gp.predict_derivatives(t if t_out is None else t_out)
    return m, d1, d2, gp
