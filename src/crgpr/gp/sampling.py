"""Posterior function samples of the SE / ARD-SE gradient GPs (paper Sec. III-B, "Uncertainty
Quantification via RFF Sampling").

Model (Rasmussen & Williams 2006, Sec. 2.7): f(x) = h(x)^T beta + g(x), g ~ GP(0, k),
k(x, x') = sigma_f^2 exp(-|(x - x') / l|^2 / 2) on standardised inputs, vague prior on beta,
y = f(X) + eps, eps ~ N(0, sigma_n^2 I). With K_y = K + sigma_n^2 I and A = H^T K_y^-1 H:

    beta | y ~ N(beta_bar, A^-1),   beta_bar = A^-1 H^T K_y^-1 y

and, given beta, g is an ordinary GP posterior. A joint function sample is therefore

    f_s(x) = h(x)^T beta_s + g_s(x) + k(x, X) K_y^-1 (y - H beta_s - g_s(X) - eps_s)      (*)

with beta_s ~ N(beta_bar, A^-1), g_s a prior sample, eps_s ~ N(0, sigma_n^2 I) independent.
(*) has exactly the R&W eq. (2.42) mean and covariance (mean h^T beta_bar + k K_y^-1 (y - H
beta_bar); covariance k** - k*^T K_y^-1 k* + R^T A^-1 R): this is Matheron's rule /
pathwise conditioning (Wilson et al. 2020, the paper's reference for RFF sampling).

Choice: pathwise conditioning, not the weight-space posterior the paper writes.
    The paper's weight-space sampler w ~ N(mu_w, Sigma_w) of f = phi(x)^T w replaces the
    kernel by its D-feature approximation everywhere, including in the data fit. With
    n = 8000-19000 training points, sigma_n / sigma_f ~ 1e-3 and D ~ 1e3 features, the
    D-dimensional posterior is over-determined by the data: its variance collapses away from
    the data ("variance starvation", Wilson et al. 2020 Fig. 1; ``weight_space_samples`` and
    tests/test_rff.py show it) and its mean carries the RFF error of k. In (*) the RFF only
    approximate the *prior* sample g_s; the data update uses the kernel itself, so near the
    data the samples have the exact posterior statistics and far from it they revert to the
    prior, as they should. Each sample gets its own RFF draw (``RFFBatch``): then the ensemble
    covariance of the prior part is exactly k for any D (E[phi phi^T] = k), instead of every
    sample sharing one draw's O(1 / sqrt(D)) kernel error.

Samples for the rollout (the default, ``SparsePosterior``, "sparse pathwise"): the update
term k(x, X) K_y^-1 (...) costs O(n) kernel evaluations per point; 10 samples x 26 nodes x
20000 steps x n ~ 35000 is ~2e11 evaluations, far beyond the budget. The CR-GPR rollout
(gradient_models.py) already replaces each GP's posterior mean by the DTC / subset-of-
regressors mean on M = 600 inducing inputs Z fitted to all n points. We condition on the same
Z: the DTC likelihood y ~ N(H beta + K_XZ K_ZZ^-1 u, sigma_n^2 I) with u ~ N(0, K_ZZ) and a flat
prior on beta is a Bayesian linear model in (beta, u) (O(n M^2)); its posterior mean is exactly
the rollout's DTC mean, and a joint sample is (Wilson et al. 2020, eq. 13)

    f_s(x) = h(x)^T beta_s + k(x, Z) K_ZZ^-1 u_s + [phi_s(x) - k(x, Z) K_ZZ^-1 phi_s(Z)]^T w_s,

(beta_s, u_s) from the DTC posterior, the bracket an RFF sample of the prior residual k - Q
(Q = K_xZ K_ZZ^-1 K_Zx) that the inducing set cannot represent. Its predictive is the DTC one:
equal to the exact posterior when Q = K on the data (checked against the exact posterior in
the UQ diagnostics and in the tests), never variance-starved (the residual term restores the
prior variance away from Z). A sample costs D cosines + M exponentials per point, evaluated by
compiled loops with polynomial cos / exp (``CompressedSamples``).

Alternative (``pathwise_samples`` + ``compress``): exact-GP pathwise samples (O(n^3)) whose
update term is fitted onto k(x, Z) a_s by least squares at all training inputs; the fit error
is measured by ``compression_error``. Used for tests, the exact_pathwise option and the 1D
momentum GPs, which the rollout tabulates (uq.TabulatedSamples).
"""

from __future__ import annotations

import dataclasses
import logging
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
from numba import njit

from crgpr.gp._gpr import GP, basis_matrix_std, kernel_matrix
from crgpr.gp.evaluators import _SE_POLY, KernelMean, kernel_sum_fast, truncated_sum_batch
from crgpr.gp.sparse import nystrom_reduce, select_inducing

log = logging.getLogger(__name__)


def basis_matrix(Xs: np.ndarray, basis: str) -> np.ndarray:
    """Explicit basis h(u) (n, p) on standardised inputs, exactly as ``crgpr.gp`` defines it
    (none, constant, linear, pure_quadratic [1, u, u^2] = MATLAB 'PureQuadratic', quadratic)."""
    return basis_matrix_std(basis, np.atleast_2d(np.asarray(Xs, dtype=float)))


def spec_from_gp(gp: GP, name: str = "gp") -> GP:
    """Check that a fitted ``crgpr.gp.GP`` can be sampled here (single output, SE / ARD-SE
    kernel) and name it; the samplers use its standardised view (``Xs``, ``y``, ``ell``)."""
    if gp.kernel != "se":
        raise ValueError(f"{name}: RFF sampling needs an SE / ARD-SE kernel, got {gp.kernel!r}")
    if gp.multi:
        raise ValueError(f"{name}: multi-output GPs are not supported")
    gp.name = name
    return gp


def se_kernel(A: np.ndarray, B: np.ndarray, sigma_f: float, lengthscales: np.ndarray) -> np.ndarray:
    """k(A, B) = sigma_f^2 exp(-|(a - b) / l|^2 / 2) (SE / ARD-SE) on standardised inputs."""
    return kernel_matrix("se", A, B, sigma_f, lengthscales)


# ----------------------------------------------------------------------------------------
# exact posterior (reference for tests and for the compression error)


@dataclass
class ExactPosterior:
    """Cholesky factor of K_y and the basis-coefficient posterior of one GP (R&W Sec. 2.7)."""

    spec: GP
    chol: np.ndarray  # lower Cholesky factor of K_y
    H: np.ndarray  # basis at the training inputs (n, p)
    beta_bar: np.ndarray  # (p,)
    beta_cov: np.ndarray  # (p, p) = A^-1
    alpha: np.ndarray  # K_y^-1 (y - H beta_bar)

    def solve(self, r: np.ndarray) -> np.ndarray:
        return sla.cho_solve((self.chol, True), r, check_finite=False)

    def mean_var(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Exact posterior mean and variance of f at raw inputs x (R&W eq. 2.42)."""
        sp = self.spec
        xs = sp.standardise(x)
        Ks = kernel_matrix(sp.kernel, sp.Xs, xs, sp.sigma_f, sp.ell)  # (n, m)
        hs = sp.basis_fn(xs)
        mean = sp.to_output(hs @ self.beta_bar + Ks.T @ self.alpha)
        v = sla.solve_triangular(self.chol, Ks, lower=True, check_finite=False)
        var = sp.sigma_f**2 - (v * v).sum(0)
        if self.H.shape[1]:
            R = hs.T - self.H.T @ self.solve(Ks)  # (p, m)
            var = var + np.einsum("pm,pq,qm->m", R, self.beta_cov, R)
        return mean, var * sp.out_scale**2

    def cov(self, x: np.ndarray) -> np.ndarray:
        """Exact posterior covariance matrix of f at raw inputs x (m, m)."""
        sp = self.spec
        xs = sp.standardise(x)
        Ks = kernel_matrix(sp.kernel, sp.Xs, xs, sp.sigma_f, sp.ell)
        v = sla.solve_triangular(self.chol, Ks, lower=True, check_finite=False)
        C = kernel_matrix(sp.kernel, xs, xs, sp.sigma_f, sp.ell) - v.T @ v
        if self.H.shape[1]:
            R = sp.basis_fn(xs).T - self.H.T @ self.solve(Ks)
            C = C + R.T @ self.beta_cov @ R
        return C * sp.out_scale**2


def exact_posterior(spec: GP, block: int = 4096) -> ExactPosterior:
    """Factorise K_y = K + sigma_n^2 I and the basis posterior (O(n^3), done once per GP), with the
    GP's own kernel (the sparse posterior and the RFF samplers need SE / ARD-SE)."""
    n = spec.Xs.shape[0]
    K = np.empty((n, n))
    for i in range(0, n, block):
        K[i:i + block] = kernel_matrix(spec.kernel, spec.Xs[i:i + block], spec.Xs, spec.sigma_f, spec.ell)
    K[np.diag_indices(n)] += spec.sigma_n**2
    chol = sla.cholesky(K, lower=True, overwrite_a=True, check_finite=False)
    del K
    H = spec.basis_fn(spec.Xs)
    y = spec.y
    solve = lambda r: sla.cho_solve((chol, True), r, check_finite=False)  # noqa: E731
    p = H.shape[1]
    if p:
        KiH = solve(H)
        A = H.T @ KiH
        A = 0.5 * (A + A.T)
        beta_cov = np.linalg.inv(A)
        beta_cov = 0.5 * (beta_cov + beta_cov.T)
        beta_bar = beta_cov @ (KiH.T @ y)
    else:
        beta_cov = np.zeros((0, 0))
        beta_bar = np.zeros(0)
    alpha = solve(y - H @ beta_bar)
    return ExactPosterior(spec, chol, H, beta_bar, beta_cov, alpha)


def posterior_from_gp(gp: GP, name: str = "gp") -> ExactPosterior:
    """ExactPosterior reusing the Cholesky factors ``crgpr.gp.GP`` already holds (no new
    O(n^3) factorisation); falls back to ``exact_posterior`` if they are missing."""
    spec = spec_from_gp(gp, name)
    if gp._chol is None:
        return exact_posterior(spec)
    chol = np.tril(gp._chol[0]) if not gp._chol[1] else gp._chol[0]
    H = spec.basis_fn(spec.Xs)
    if H.shape[1]:
        LA = gp._A_chol[0] if gp._A_chol[1] else gp._A_chol[0].T
        Ainv = sla.cho_solve((np.tril(LA), True), np.eye(H.shape[1]), check_finite=False)
        beta_cov = 0.5 * (Ainv + Ainv.T)
        beta_bar = np.ravel(gp.beta)
    else:
        beta_cov, beta_bar = np.zeros((0, 0)), np.zeros(0)
    return ExactPosterior(spec, chol, H, beta_bar, beta_cov, np.ravel(gp.alpha))


# ----------------------------------------------------------------------------------------
# random Fourier features


@dataclass
class RFF:
    """D random Fourier features of an SE / ARD-SE kernel on standardised inputs."""

    omega: np.ndarray  # (D, d)
    phase: np.ndarray  # (D,)
    sigma_f: float

    @property
    def n_features(self) -> int:
        return self.omega.shape[0]

    @property
    def scale(self) -> float:
        return math.sqrt(2.0 * self.sigma_f**2 / self.n_features)

    def __call__(self, Xs: np.ndarray) -> np.ndarray:
        """Feature matrix phi(X) (n, D); phi(x)^T phi(x') ~ k(x, x')."""
        return self.scale * np.cos(Xs @ self.omega.T + self.phase)


def draw_rff(spec: GP, n_features: int, rng: np.random.Generator) -> RFF:
    """Omega ~ N(0, diag(1 / l^2)), b ~ U[0, 2 pi] (paper Sec. III)."""
    if n_features < 1:
        raise ValueError(f"n_features must be >= 1, got {n_features}")
    omega = rng.standard_normal((n_features, spec.dim)) / spec.ell
    phase = rng.uniform(0.0, 2.0 * np.pi, n_features)
    return RFF(omega, phase, spec.sigma_f)


@dataclass
class RFFBatch:
    """Independent RFF draws, one per sample: ``omega`` (S, D, d), ``phase`` (S, D).

    Sample s uses its own frequencies, so the ensemble covariance of the prior part,
    E[phi_s(x)^T phi_s(x')] = k(x, x'), is exact for any D (only each sample's marginal
    law is approximately Gaussian); with one shared draw every sample would carry the same
    O(1 / sqrt(D)) kernel error."""

    omega: np.ndarray
    phase: np.ndarray
    sigma_f: float

    @property
    def n_features(self) -> int:
        return self.omega.shape[1]

    @property
    def scale(self) -> float:
        return math.sqrt(2.0 * self.sigma_f**2 / self.n_features)

    def features(self, Xs: np.ndarray) -> np.ndarray:
        """phi_s(X) (S, m, D) at standardised inputs X (m, d)."""
        return self.scale * np.cos(np.einsum("md,sjd->smj", Xs, self.omega) + self.phase[:, None, :])

    def prior(self, xs: np.ndarray, w: np.ndarray) -> np.ndarray:
        """phi_s(x_s)^T w_s (S, m) at standardised inputs xs (S, m, d) or (m, d) (compiled)."""
        S = self.omega.shape[0]
        xs = np.asarray(xs, dtype=float)
        if xs.ndim == 2:
            xs = np.broadcast_to(xs, (S, *xs.shape))
        out = np.empty(xs.shape[:2])
        _rff_sum(np.ascontiguousarray(xs), self.omega, self.phase, np.ascontiguousarray(w), self.scale, out)
        return out


def draw_rff_batch(spec: GP, n_samples: int, n_features: int, rng: np.random.Generator) -> RFFBatch:
    """S independent RFF draws (Omega ~ N(0, diag(1 / l^2)), b ~ U[0, 2 pi])."""
    if n_features < 1:
        raise ValueError(f"n_features must be >= 1, got {n_features}")
    omega = rng.standard_normal((n_samples, n_features, spec.dim)) / spec.ell
    phase = rng.uniform(0.0, 2.0 * np.pi, (n_samples, n_features))
    return RFFBatch(np.ascontiguousarray(omega), np.ascontiguousarray(phase), spec.sigma_f)


@njit(cache=True, fastmath=True)
def _cos_poly(t):
    """cos(t) by reduction to [-pi, pi] and a degree-22 Horner polynomial (|error| < 2e-12):
    vectorisable, ~70x faster than libm cos here."""
    r = t - 6.283185307179586 * np.floor(t * 0.15915494309189535 + 0.5)
    r2 = r * r
    p = 1.0
    for k in range(11, 0, -1):
        p = 1.0 - r2 / ((2 * k - 1) * (2 * k)) * p
    return p


@njit(cache=True, fastmath=True)
def _rff_sum_t(xs, omegaT, phase, w, scale, out):
    """out[s, i] = scale sum_j w[s, j] cos(omega_s,j . xs[s, i] + phase[s, j]), omegaT (S, d, D)."""
    S, m, d = xs.shape
    D = omegaT.shape[2]
    t = np.empty(D)
    for s in range(S):
        for i in range(m):
            for j in range(D):
                t[j] = phase[s, j]
            for k in range(d):
                xk = xs[s, i, k]
                for j in range(D):
                    t[j] += omegaT[s, k, j] * xk
            acc = 0.0
            for j in range(D):
                acc += w[s, j] * _cos_poly(t[j])
            out[s, i] = scale * acc


def _rff_sum(xs, omega, phase, w, scale, out):
    """As ``_rff_sum_t`` with omega (S, D, d)."""
    _rff_sum_t(xs, np.ascontiguousarray(np.transpose(omega, (0, 2, 1))), phase, w, scale, out)


# ----------------------------------------------------------------------------------------
# pathwise samples


@dataclass
class PathwiseSamples:
    """S joint posterior samples of one GP in the form (*) with the exact update term.

    ``beta`` (S, p), ``w`` (S, D) prior weights, ``alpha`` (S, n) update weights on the
    training inputs: g_s(u) = h(u)^T beta_s + phi(u)^T w_s + k(u, X) alpha_s in standardised
    units, f_s(x) = y_mean + y_scale g_s(u).
    """

    post: ExactPosterior
    rff: RFFBatch
    beta: np.ndarray
    w: np.ndarray
    alpha: np.ndarray

    @property
    def n_samples(self) -> int:
        return self.w.shape[0]

    def update_at_train(self) -> np.ndarray:
        """u_s(X) = K alpha_s (S, n), from the residual identity K alpha = r - sigma_n^2 alpha."""
        return self._resid - self.post.spec.sigma_n**2 * self.alpha

    _resid: np.ndarray = field(default=None, repr=False)  # y - H beta_s - g_s(X) - eps_s (S, n)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """All S samples at raw inputs x (m, d) -> (S, m), exact (O(n m))."""
        sp = self.post.spec
        xs = sp.standardise(np.atleast_2d(x))
        Ks = se_kernel(xs, sp.Xs, sp.sigma_f, sp.ell)  # (m, n)
        out = self.beta @ sp.basis_fn(xs).T + self.rff.prior(xs, self.w) + self.alpha @ Ks.T
        return sp.to_output(out)


def pathwise_samples(post: ExactPosterior, n_samples: int, n_features: int,
                     rng: np.random.Generator) -> PathwiseSamples:
    """Draw S samples by pathwise conditioning (*) on RFF prior samples (Wilson et al. 2020),
    each sample with its own feature draw (RFFBatch)."""
    sp = post.spec
    n = sp.Xs.shape[0]
    rff = draw_rff_batch(sp, n_samples, n_features, rng)
    p = post.H.shape[1]
    if p:
        Lb = np.linalg.cholesky(post.beta_cov + 1e-14 * np.trace(post.beta_cov) / p * np.eye(p))
        beta = post.beta_bar + rng.standard_normal((n_samples, p)) @ Lb.T
    else:
        beta = np.zeros((n_samples, 0))
    w = rng.standard_normal((n_samples, n_features))
    eps = sp.sigma_n * rng.standard_normal((n_samples, n))
    g_X = rff.prior(sp.Xs, w)
    resid = sp.y[None, :] - beta @ post.H.T - g_X - eps
    alpha = post.solve(resid.T).T
    out = PathwiseSamples(post, rff, beta, w, alpha)
    out._resid = resid
    return out


def pathwise_covariance(post: ExactPosterior, rff: RFF, x: np.ndarray) -> np.ndarray:
    """Covariance of (*) at raw inputs x for *these* features (no Monte Carlo).

    f = h^T beta + (phi - k K_y^-1 Phi)^T w - k K_y^-1 (H beta + eps): with c_x = K_y^-1 k_x,
    Cov = P^T P + sigma_n^2 C^T C + R^T A^-1 R, P = phi(x)^T - Phi(X)^T C. Equals the exact
    posterior covariance when phi phi^T = k (D -> infinity); used by the convergence test.
    """
    sp = post.spec
    xs = sp.standardise(np.atleast_2d(x))
    Ks = se_kernel(sp.Xs, xs, sp.sigma_f, sp.ell)  # (n, m)
    C = post.solve(Ks)  # (n, m)
    P = rff(xs).T - rff(sp.Xs).T @ C  # (D, m)
    cov = P.T @ P + sp.sigma_n**2 * C.T @ C
    if post.H.shape[1]:
        R = sp.basis_fn(xs).T - post.H.T @ C
        cov = cov + R.T @ post.beta_cov @ R
    return cov * sp.out_scale**2


def weight_space_samples(spec: GP, n_samples: int, n_features: int,
                         rng: np.random.Generator) -> tuple[RFF, np.ndarray, np.ndarray]:
    """The paper's sampler: Bayesian linear regression on [h(x), phi(x)], w ~ N(0, I), flat
    prior on beta; returns (rff, beta (S, p), w (S, D)). For comparison only (variance
    starvation, see the module docstring)."""
    rff = draw_rff(spec, n_features, rng)
    Phi = np.hstack([spec.basis_fn(spec.Xs), rff(spec.Xs)])
    p = Phi.shape[1] - n_features
    prec = Phi.T @ Phi / spec.sigma_n**2
    prec[p:, p:] += np.eye(n_features)
    Lp = np.linalg.cholesky(prec)
    mu = sla.cho_solve((Lp, True), Phi.T @ spec.y / spec.sigma_n**2)
    z = rng.standard_normal((n_samples, p + n_features))
    theta = mu + sla.solve_triangular(Lp, z.T, lower=True, trans="T").T
    return rff, theta[:, :p], theta[:, p:]


# ----------------------------------------------------------------------------------------
# compression of the update term for the rollout


def inducing_indices(spec: GP, n_inducing: int, seed: int) -> np.ndarray:
    """Indices of M training inputs for the inducing set: ``crgpr.gp.select_inducing``
    (farthest points in lengthscale-scaled inputs, the selector of the rollout's DTC mean)."""
    return select_inducing(spec.Xs / spec.ell, n_inducing, seed)


@dataclass
class CompressedSamples:
    """S samples for the rollout: f_s(x) = y_mean + y_scale (h(u)^T beta_s + phi_s(u)^T w_s
    + k(u, Z) a_s), u the standardised input.

    All arrays are plain (saved to npz): ``omega`` (S, D, d), ``phase`` (S, D) (one RFF draw
    per sample), ``w`` (S, D), ``Z`` (M, d) standardised inducing inputs, ``a`` (S, M),
    ``beta`` (S, p), plus the kernel hyperparameters, standardisation and basis name.
    Evaluation: the RFF sums in a compiled loop with a polynomial cosine, the kernel part as
    a compiled loop with a polynomial exp (both vectorisable, no temporaries). ``kernel_tol`` > 0
    (``truncate``): the kernel part skips the centres with k < kernel_tol sigma_f^2, found on the
    cell grid of ``crgpr.gp.KernelMean`` (same polynomial exp); |change| <= ``truncation_bound``.
    """

    omega: np.ndarray
    phase: np.ndarray
    w: np.ndarray
    Z: np.ndarray
    a: np.ndarray
    beta: np.ndarray
    sigma_f: float
    lengthscales: np.ndarray
    x_mean: np.ndarray
    x_std: np.ndarray
    basis: str
    y_mean: float = 0.0
    y_scale: float = 1.0
    kernel_tol: float = 0.0

    def __post_init__(self) -> None:
        self.omega = np.ascontiguousarray(self.omega, dtype=float)
        self.phase = np.ascontiguousarray(self.phase, dtype=float)
        if self.omega.ndim != 3 or self.omega.shape[0] != self.w.shape[0]:
            raise ValueError(f"omega must be (S, D, d) with S = {self.w.shape[0]}, got {self.omega.shape}")
        self._ZlT = np.ascontiguousarray((self.Z / self.lengthscales).T)
        self._omegaT = np.ascontiguousarray(np.transpose(self.omega, (0, 2, 1)))
        self._scale = math.sqrt(2.0 * self.sigma_f**2 / self.omega.shape[1])
        self._a = np.ascontiguousarray(self.a, dtype=float)
        self._grid: KernelMean | None = None
        #: bound on |truncated - dense kernel part| at any input, output units
        self.truncation_bound = 0.0
        if self.kernel_tol > 0:
            M = self.Z.shape[0]
            g = KernelMean("se", "none", self.sigma_f, self.lengthscales, self.x_mean, self.x_std, 0.0, 1.0,
                           self.Z, np.zeros(M), np.zeros(0), tol=self.kernel_tol)
            self._grid = g
            self._a_sorted = np.ascontiguousarray(self._a[:, g.order])
            self.truncation_bound = float(self.kernel_tol * self.sigma_f**2 * self.y_scale
                                          * np.abs(self._a).sum(1).max())

    def truncate(self, kernel_tol: float) -> CompressedSamples:
        """The same samples evaluated with kernel sums truncated below kernel_tol sigma_f^2."""
        return dataclasses.replace(self, kernel_tol=float(kernel_tol))

    @property
    def n_samples(self) -> int:
        return self.w.shape[0]

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"omega": self.omega, "phase": self.phase, "w": self.w, "Z": self.Z, "a": self.a,
                "beta": self.beta, "sigma_f": np.array(self.sigma_f),
                "lengthscales": self.lengthscales, "x_mean": self.x_mean, "x_std": self.x_std,
                "basis": np.array(self.basis), "y_mean": np.array(self.y_mean),
                "y_scale": np.array(self.y_scale)}

    @classmethod
    def from_arrays(cls, arr: dict[str, np.ndarray]) -> CompressedSamples:
        return cls(arr["omega"], arr["phase"], arr["w"], arr["Z"], arr["a"], arr["beta"],
                   np.asarray(arr["sigma_f"]).item(), arr["lengthscales"], arr["x_mean"], arr["x_std"],
                   str(arr["basis"]), np.asarray(arr["y_mean"]).item(), np.asarray(arr["y_scale"]).item())

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Evaluate sample s at x[s]: x (S, m, d) raw inputs -> (S, m)."""
        x = np.asarray(x, dtype=float)
        if x.ndim != 3 or x.shape[0] != self.n_samples:
            raise ValueError(f"expected inputs (S={self.n_samples}, m, d), got {x.shape}")
        xs = np.ascontiguousarray((x - self.x_mean) / self.x_std)
        S, m, d = xs.shape
        out = np.empty((S, m))
        _rff_sum_t(xs, self._omegaT, self.phase, self.w, self._scale, out)
        xl = np.ascontiguousarray(xs / self.lengthscales)
        g = self._grid
        if g is None:
            kernel_sum_fast(xl, self._ZlT, self._a, self.sigma_f**2, _SE_POLY, out)
        else:
            ks = np.empty((S, m))
            truncated_sum_batch(xl, g.ZT_sorted, self._a_sorted, g.key1, g.starts, g.lo0, g.h, g.k0, g.k1,
                                g.rcut, 0, ks)
            out += self.sigma_f**2 * ks
        if self.beta.shape[1]:
            H = basis_matrix(xs.reshape(S * m, d), self.basis).reshape(S, m, -1)
            out += np.einsum("smp,sp->sm", H, self.beta)
        return self.y_mean + self.y_scale * out


def reduce_update_rank(comp: CompressedSamples, tol: float) -> CompressedSamples:
    """The same samples with the update term k(u, Z) a_s on the pivoted-Cholesky subset of Z
    (``crgpr.gp.sparse.nystrom_reduce``, residual diagonal of K_ZZ below tol sigma_f^2): a smooth
    kernel's K_ZZ has a small numerical rank, so the rollout's kernel part shrinks from M to r
    terms; the caller measures the change (``crgpr.uq.samples``)."""
    piv, a = nystrom_reduce(comp.Z, comp.a.T, "se", comp.lengthscales, tol)
    return dataclasses.replace(comp, Z=comp.Z[piv].copy(), a=np.ascontiguousarray(a.T))


def compress(samples: PathwiseSamples, inducing: np.ndarray, ridge: float = 1e-8) -> CompressedSamples:
    """Fit k(x, Z) a_s to the exact update u_s(X) at all n training inputs (subset-of-regressors
    least squares). The ridge (ridge sigma_n)^2 a^T K_ZZ a only stabilises the solve: it must be
    far below sigma_n^2, else the fit error is of the size of the posterior sd near the data.
    Solved by QR of the stacked system [K_XZ; ridge sigma_n L_Z^T] (O(n M^2))."""
    post = samples.post
    sp = post.spec
    Z = sp.Xs[inducing]
    M = Z.shape[0]
    Kzz = se_kernel(Z, Z, sp.sigma_f, sp.ell)
    Lz = np.linalg.cholesky(Kzz + 1e-12 * sp.sigma_f**2 * np.eye(M))
    Kxz = se_kernel(sp.Xs, Z, sp.sigma_f, sp.ell)  # (n, M)
    A = np.vstack([Kxz, ridge * sp.sigma_n * Lz.T])
    del Kxz
    U = samples.update_at_train()  # (S, n)
    rhs = np.vstack([U.T, np.zeros((M, U.shape[0]))])
    Q, R = np.linalg.qr(A, mode="reduced")
    a = sla.solve_triangular(R, Q.T @ rhs, check_finite=False).T
    return CompressedSamples(samples.rff.omega, samples.rff.phase, samples.w, Z, a, samples.beta,
                             sp.sigma_f, sp.ell, sp.x_mean, sp.x_std, sp.basis, sp.out_mean,
                             sp.out_scale)


@dataclass
class SparsePosterior:
    """Sparse (DTC) posterior of one GP on M inducing inputs Z, incl. the basis coefficients.

    Nystrom features psi(u) = k(u, Z) L_Z^-T (psi psi^T = Q = K_uZ K_ZZ^-1 K_Zu) turn the DTC
    likelihood y ~ N(H beta + Psi v, sigma_n^2 I), v ~ N(0, I), flat prior on beta, into a
    Bayesian linear model in theta = (beta, v): precision P = F^T F / sigma_n^2 + diag(0, I),
    F = [H, Psi], mean P^-1 F^T y / sigma_n^2 (O(n M^2), no O(n^3) factorisation). The
    predictive is the DTC one (Quinonero-Candela & Rasmussen 2005): [h, psi] P^-1 [h, psi]^T
    + k** - Q**. With Z = X it is the exact posterior of R&W Sec. 2.7.
    """

    spec: GP
    Z: np.ndarray  # (M, d) standardised
    LZ: np.ndarray  # lower Cholesky factor of K_ZZ (+ jitter)
    RP: np.ndarray  # upper triangular, P = RP^T RP
    mu: np.ndarray  # (p + M,)

    @property
    def n_basis(self) -> int:
        return self.mu.shape[0] - self.Z.shape[0]

    def features(self, xs: np.ndarray) -> np.ndarray:
        """[h(u), psi(u)] at standardised inputs (m, p + M)."""
        sp = self.spec
        Kxz = se_kernel(xs, self.Z, sp.sigma_f, sp.ell)
        psi = sla.solve_triangular(self.LZ, Kxz.T, lower=True, check_finite=False).T
        return np.hstack([sp.basis_fn(xs), psi])

    def mean_var(self, x: np.ndarray, jackknife: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """DTC predictive mean and variance of f at raw inputs (original units). With
        ``jackknife`` (B, p + M) leave-one-block-out coefficient vectors: the variance of the
        samples ``sample(..., jackknife=...)`` draws (``jackknife_covariance``), same mean."""
        sp = self.spec
        xs = sp.standardise(np.atleast_2d(x))
        F = self.features(xs)
        mean = F @ self.mu
        G = sla.solve_triangular(self.RP, F.T, trans="T", check_finite=False)
        psi = F[:, self.n_basis:]
        if jackknife is None:
            var = (G * G).sum(0)
        else:
            B = jackknife.shape[0]
            dev = F @ (jackknife - jackknife.mean(0)).T  # (m, B)
            PiF = sla.solve_triangular(self.RP, G, check_finite=False)[self.n_basis:]  # Lambda^1/2 P^-1 F^T
            var = (B - 1) / B * (dev * dev).sum(1) + (PiF * PiF).sum(0)
        var = var + sp.sigma_f**2 - (psi * psi).sum(1)
        return sp.to_output(mean), var * sp.out_scale**2

    def jackknife_covariance(self, jackknife: np.ndarray) -> np.ndarray:
        """The covariance of theta = (beta, v) that ``sample(..., jackknife=...)`` draws from
        (``jackknife_covariance``): C_jk + P^-1 Lambda P^-1, with C_jk = (B - 1) / B sum_b
        (theta_-b - mean) (theta_-b - mean)^T over the B leave-one-block-out posterior means and
        Lambda = diag(0_p, I_M) the prior precision of the kernel weights."""
        B = jackknife.shape[0]
        d = jackknife - jackknife.mean(0)
        Pi = sla.solve_triangular(self.RP, sla.solve_triangular(self.RP, np.eye(self.mu.shape[0]), trans="T",
                                                                 check_finite=False), check_finite=False)
        Pv = Pi[:, self.n_basis:]
        return (B - 1) / B * d.T @ d + Pv @ Pv.T

    def scaled(self, c: float) -> SparsePosterior:
        """The DTC posterior of ``scaled_spec(spec, c)`` (sigma_f, sigma_n x c) without a new
        O(n M^2) factorisation: with D = diag(I_p / c, I_M) the stacked system of the scaled GP
        is the unscaled one times D, so P_c = D P D, RP_c = RP D, L_Z,c = c L_Z and
        mu_c = diag(I_p, I_M / c) mu (same mean function, covariance x c^2)."""
        if not c > 0:
            raise ValueError(f"{self.spec.name}: posterior scale must be > 0, got {c}")
        p = self.n_basis
        d = np.concatenate([np.full(p, 1.0 / c), np.ones(self.Z.shape[0])])
        mu = self.mu.copy()
        mu[p:] /= c
        return SparsePosterior(scaled_spec(self.spec, c), self.Z, c * self.LZ, self.RP * d[None, :], mu)

    def mean_coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """(beta_bar, a_bar): the posterior mean as h(u)^T beta_bar + k(u, Z) a_bar."""
        p = self.n_basis
        a = sla.solve_triangular(self.LZ, self.mu[p:], lower=True, trans="T", check_finite=False)
        return self.mu[:p].copy(), a

    def sample(self, n_samples: int, n_features: int, rng: np.random.Generator,
               jackknife: np.ndarray | None = None) -> CompressedSamples:
        """S joint samples f_s = h^T beta_s + psi^T v_s + (phi - k_Z K_ZZ^-1 Phi_Z)^T w_s: the
        DTC posterior of (beta, v) plus an RFF sample of the prior residual k - Q (Wilson et al.
        2020, eq. 13 with the optimal q(u)), as compressed samples k(u, Z) a_s + ...

        ``jackknife`` (B, p + M): the coefficient vectors theta_-b of the B leave-one-block-out
        posteriors (``heldout_block_scale(..., block_coefficients=...)``). Then theta_s - mu is
        drawn from the cluster-robust ("sandwich") covariance instead of P^-1:

            theta_s = mu + sqrt((B - 1) / B) sum_b xi_sb (theta_-b - mean_b theta_-b)
                         + P^-1 [0; zeta_s],      xi_sb, zeta_s ~ N(0, 1) iid,

        covariance C_jk + P^-1 Lambda P^-1 (``jackknife_covariance``). P^-1 = P^-1 (F^T F /
        sigma_n^2 + Lambda) P^-1: its data part, the variance of the posterior mean if the target
        errors were iid N(0, sigma_n^2), is replaced by the delete-a-block jackknife of that mean
        (Kuensch 1989; for a linear law the cluster-robust covariance of its coefficients, errors
        correlated within blocks, independent between them), while the prior part of the kernel
        weights, which no data determine, is kept. For a GP whose kernel the LML switched off
        (sigma_f at its bound: a Bayesian linear law in its basis) this is the jackknife
        covariance of the basis coefficients; data-determined directions get the law's observed
        spread across blocks (rank <= B - 1), the rest the prior's."""
        sp = self.spec
        rff = draw_rff_batch(sp, n_samples, n_features, rng)
        if jackknife is None:
            z = rng.standard_normal((n_samples, self.mu.shape[0]))
            theta = self.mu + sla.solve_triangular(self.RP, z.T, check_finite=False).T
        else:
            J = np.asarray(jackknife, dtype=float)
            B = J.shape[0]
            if J.ndim != 2 or J.shape[1] != self.mu.shape[0] or B < 2:
                raise ValueError(f"{sp.name}: jackknife coefficients must be (B >= 2, {self.mu.shape[0]}), "
                                 f"got {J.shape}")
            xi = rng.standard_normal((n_samples, B))
            zeta = np.zeros((n_samples, self.mu.shape[0]))
            zeta[:, self.n_basis:] = rng.standard_normal((n_samples, self.Z.shape[0]))
            half = sla.solve_triangular(self.RP, zeta.T, trans="T", check_finite=False)
            prior = sla.solve_triangular(self.RP, half, check_finite=False)
            theta = self.mu + np.sqrt((B - 1) / B) * xi @ (J - J.mean(0)) + prior.T
        p = self.n_basis
        beta, v = theta[:, :p], theta[:, p:]
        w = rng.standard_normal((n_samples, n_features))
        # k(u, Z) a_s = psi(u) v_s - k(u, Z) K_ZZ^-1 Phi(Z) w_s,  psi = k L_Z^-T
        a_v = sla.solve_triangular(self.LZ, v.T, lower=True, trans="T", check_finite=False)
        a_w = sla.cho_solve((self.LZ, True), rff.prior(self.Z, w).T, check_finite=False)
        a = (a_v - a_w).T
        return CompressedSamples(rff.omega, rff.phase, w, self.Z.copy(), a, beta, sp.sigma_f,
                                 sp.ell, sp.x_mean, sp.x_std, sp.basis, sp.out_mean, sp.out_scale)


def sparse_posterior(spec: GP, Z: np.ndarray, jitter: float = 1e-10, block: int = 8192
                     ) -> SparsePosterior:
    """Factorise the DTC posterior on standardised inducing inputs Z (see SparsePosterior);
    the stacked system [F / sigma_n; diag(0, I)] is reduced by blocked QR for stability."""
    Z = np.atleast_2d(np.asarray(Z, dtype=float))
    M = Z.shape[0]
    LZ = np.linalg.cholesky(se_kernel(Z, Z, spec.sigma_f, spec.ell)
                            + jitter * spec.sigma_f**2 * np.eye(M))
    p = spec.basis_fn(spec.Xs[:1]).shape[1]
    prior = np.zeros((M, p + M))
    prior[:, p:] = np.eye(M)
    R = prior
    rhs = np.zeros(M)
    n = spec.Xs.shape[0]
    for i in range(0, n, block):
        xs = spec.Xs[i:i + block]
        Kxz = se_kernel(xs, Z, spec.sigma_f, spec.ell)
        psi = sla.solve_triangular(LZ, Kxz.T, lower=True, check_finite=False).T
        F = np.hstack([spec.basis_fn(xs), psi]) / spec.sigma_n
        Q, R = np.linalg.qr(np.vstack([R, F]), mode="reduced")
        rhs = Q.T @ np.concatenate([rhs, spec.y[i:i + block] / spec.sigma_n])
    mu = sla.solve_triangular(R, rhs, check_finite=False)
    return SparsePosterior(spec, Z, LZ, R, mu)


def compression_error(samples: PathwiseSamples, comp: CompressedSamples, x: np.ndarray) -> dict[str, float]:
    """Max and RMS difference between exact (*) and compressed samples at raw inputs x (m, d),
    absolute and relative to the posterior standard deviation there."""
    exact = samples(x)  # (S, m)
    approx = comp(np.broadcast_to(x, (comp.n_samples, *np.atleast_2d(x).shape)))
    err = approx - exact
    _, var = samples.post.mean_var(x)
    sd = np.sqrt(np.maximum(var, 1e-300))
    return {"max_abs": float(np.abs(err).max()), "rms": float(np.sqrt(np.mean(err**2))),
            "max_rel_sd": float(np.abs(err / sd).max()),
            "rms_rel_sd": float(np.sqrt(np.mean((err / sd) ** 2))),
            "post_sd_median": float(np.median(sd))}


def subset_spec(spec: GP, idx: np.ndarray) -> GP:
    """The same GP (hyperparameters, standardisation) conditioned on the rows ``idx`` only."""
    return GP.from_standardised(spec.Xs[idx], spec.y[idx], spec.sigma_f, spec.ell, spec.sigma_n, spec.basis,
                                spec.x_mean, spec.x_std, spec.out_mean, spec.out_scale, spec.name,
                                kernel=spec.kernel)


def scaled_spec(spec: GP, c: float) -> GP:
    """The GP with sigma_f and sigma_n both multiplied by ``c``: the posterior mean is unchanged
    (K_y^-1 scales by c^-2, k_* by c^2; the vague-prior basis coefficients likewise) and the
    posterior covariance of f, basis part included, is multiplied by c^2 (R&W eq. 2.42)."""
    if not c > 0:
        raise ValueError(f"{spec.name}: posterior scale must be > 0, got {c}")
    return GP.from_standardised(spec.Xs, spec.y, c * spec.sigma_f, spec.ell, c * spec.sigma_n, spec.basis,
                                spec.x_mean, spec.x_std, spec.out_mean, spec.out_scale, spec.name,
                                kernel=spec.kernel)


def _posterior_mean_std(post: ExactPosterior | SparsePosterior, xs: np.ndarray) -> np.ndarray:
    """Posterior mean of f in standardised output units at standardised inputs ``xs`` (m, d):
    h^T beta_bar + k(x, Z) a_bar (sparse) or h^T beta_bar + k(x, X) alpha (exact), O(m M) /
    O(m n), without the variance's triangular solves."""
    sp = post.spec
    if isinstance(post, SparsePosterior):
        beta, a = post.mean_coefficients()
        return sp.basis_fn(xs) @ beta + se_kernel(xs, post.Z, sp.sigma_f, sp.ell) @ a
    k = kernel_matrix(sp.kernel, xs, sp.Xs, sp.sigma_f, sp.ell)
    return sp.basis_fn(xs) @ post.beta_bar + k @ post.alpha


def jackknife_variance(posts: list[ExactPosterior | SparsePosterior], x: np.ndarray) -> np.ndarray:
    """The delete-a-block jackknife variance V_jk(x) = (B - 1) / B sum_b (m_-b(x) - mean_b
    m_-b(x))^2 of a posterior mean (Kuensch 1989) at raw inputs x (m, d), from the B
    leave-one-block-out posteriors ``posts`` (``heldout_block_scale``'s ``posteriors``), in
    output units squared."""
    return _jackknife_var(np.asarray([_posterior_mean_std(p, p.spec.standardise(x)) * p.spec.out_scale
                                      for p in posts]))


def _jackknife_var(mj: np.ndarray) -> np.ndarray:
    """(B - 1) / B sum_b (m_-b - mean_b m_-b)^2 of the B leave-one-block-out means ``mj`` (B, m)."""
    return (mj.shape[0] - 1) / mj.shape[0] * np.sum((mj - mj.mean(0)) ** 2, axis=0)


HELDOUT_STATISTICS = ("rms", "median", "split", "jackknife")


def heldout_block_scale(spec: GP, n_blocks: int, Z: np.ndarray | None = None, statistic: str = "median",
                        eval_points: int = 2000, full: ExactPosterior | SparsePosterior | None = None,
                        block_coefficients: list[np.ndarray] | None = None,
                        posteriors: list[ExactPosterior | SparsePosterior] | None = None
                        ) -> tuple[float, dict[str, Any]]:
    """Posterior scale c from held-out contiguous blocks of the training rows (blocked CV).

    The rows are split into ``n_blocks`` contiguous blocks (for the gradient GPs: time blocks of
    the training trajectory, whose rows are time-major); each block is predicted by the GP with
    the same hyperparameters conditioned on the other blocks (DTC posterior on the inducing
    inputs ``Z`` if given, else exact), giving residuals r_i = y_i - m_-b(x_i) and latent
    variances v_i, z_i = r_i / sqrt(v_i) (the latent predictive, because the targets' errors are
    correlated along the trajectory: an iid noise term would average them away). ``statistic``
    'rms': c^2 = mean(z_i^2), which maximises the held-out Gaussian log-likelihood of
    N(m_-b, c^2 v); 'median': c = median |z_i| / 0.6745 (the robust scale: the held-out z are
    heavy-tailed, a few extrapolated blocks dominate their mean square). 'split': the residuals
    are modelled as r_i ~ N(0, c^2 v_i + s^2), the function's error (the latent posterior, scaled)
    plus the targets' own error s (the prefilter's smoothing error: it is in every target, but
    not in the function the rollout integrates); (c, s) maximise the held-out Gaussian
    likelihood (``split_noise_scale``, computed only for this statistic: it is the costly one)
    and c is returned.

    'jackknife' (the delete-a-block jackknife, Kuensch 1989): the residuals above compare the
    mean with the *targets*, so they carry the targets' own error, which a law fitted to many
    blocks averages out; the jackknife instead measures how much the posterior mean itself moves
    when one block of data is left out. With m_-b the mean conditioned on all blocks but b, at
    ``eval_points`` training inputs x (evenly spaced rows),
        V_jk(x) = (B - 1) / B sum_b (m_-b(x) - mean_b m_-b(x))^2
    estimates the variance of the full-data mean under errors correlated within blocks and
    independent between them (for a linear law: the cluster-robust covariance of its
    coefficients), and c = sqrt(median_x V_jk(x) / v(x)), v the full-data posterior's latent
    variance (``full``, built here when not given). The median, because where one block alone
    determines the mean (its states appear nowhere else) the jackknife measures that block's
    extrapolation, not the estimator's spread (a known failure of the jackknife for local
    estimators), and those points are outliers of the ratio.

    Scaling sigma_f and sigma_n by c (``scaled_spec``) multiplies every posterior variance by c^2
    and keeps the mean. Returns (c, diagnostics with the held-out z statistics).
    ``block_coefficients`` (a list, sparse case only): receives the coefficient vector
    theta_-b = (beta, v) of each leave-one-block-out DTC posterior, for
    ``SparsePosterior.sample(..., jackknife=...)`` (the jackknife covariance, not a scale).
    ``posteriors`` (a list): receives each leave-one-block-out posterior, for the pointwise
    ``jackknife_variance`` elsewhere than at the training inputs.
    """
    n = spec.Xs.shape[0]
    if not 2 <= n_blocks <= n // 2:
        raise ValueError(f"{spec.name}: {n_blocks} held-out blocks for n = {n} rows")
    edges = np.linspace(0, n, n_blocks + 1).astype(int)
    if statistic not in HELDOUT_STATISTICS:
        raise ValueError(f"{spec.name}: held-out statistic {statistic!r}; "
                         f"expected one of {HELDOUT_STATISTICS}")
    ev = np.unique(np.linspace(0, n - 1, min(eval_points, n)).round().astype(int))
    xs_ev = spec.Xs[ev]
    z_all, r_all, v_all, m_jk = [], [], [], []
    for b in range(n_blocks):
        te = np.arange(edges[b], edges[b + 1])
        tr = np.concatenate([np.arange(0, edges[b]), np.arange(edges[b + 1], n)])
        sub = subset_spec(spec, tr)
        post = sparse_posterior(sub, Z) if Z is not None else exact_posterior(sub)
        if block_coefficients is not None:
            if Z is None:
                raise ValueError(f"{spec.name}: block coefficients need the sparse (inducing) posterior")
            block_coefficients.append(post.mu.copy())
        if posteriors is not None:
            posteriors.append(post)
        x_te = spec.Xs[te] * spec.x_std + spec.x_mean
        m, v = post.mean_var(x_te)
        r = spec.to_output(spec.y[te]) - m
        z_all.append(r / np.sqrt(np.maximum(v, 1e-300)))
        r_all.append(r)
        v_all.append(np.maximum(v, 0.0))
        m_jk.append(_posterior_mean_std(post, xs_ev) * spec.out_scale)
    z = np.concatenate(z_all)
    c_rms = float(np.sqrt(np.mean(z**2)))
    c_med = float(np.median(np.abs(z)) / 0.6744897501960817)
    # the split likelihood is the costly statistic (a profile over c, a root in s^2 for each c):
    # only when asked for
    c_split, s_split = (split_noise_scale(np.concatenate(r_all), np.concatenate(v_all))
                        if statistic == "split" else (None, None))
    if full is None:
        full = sparse_posterior(spec, Z) if Z is not None else exact_posterior(spec)
    _, v_ev = full.mean_var(xs_ev * spec.x_std + spec.x_mean)
    v_jk = _jackknife_var(np.asarray(m_jk))
    ratio = v_jk / np.maximum(v_ev, 1e-300)
    c_jk = float(np.sqrt(np.median(ratio)))
    c = {"rms": c_rms, "median": c_med, "split": c_split, "jackknife": c_jk}[statistic]
    info = {"posterior_scale": c, "heldout_statistic": statistic, "heldout_scale_rms": c_rms,
            "heldout_scale_median": c_med, "heldout_scale_split": c_split,
            "heldout_scale_jackknife": c_jk,
            "jackknife_scale_mean": float(np.sqrt(np.mean(ratio))),
            "jackknife_sd_median": float(np.median(np.sqrt(v_jk))),
            "jackknife_eval_points": int(ev.size),
            "heldout_target_error_split": s_split,
            "heldout_rms_residual": float(np.sqrt(np.mean(np.concatenate(r_all) ** 2))),
            "heldout_latent_sd_median": float(np.median(np.sqrt(np.concatenate(v_all)))),
            "latent_sd_median": float(np.median(np.sqrt(np.maximum(v_ev, 0.0)))),
            "heldout_blocks": int(n_blocks),
            "heldout_median_abs_z": float(np.median(np.abs(z))),
            "heldout_coverage95_unscaled": float(np.mean(np.abs(z) < 1.959964)),
            "heldout_coverage95_scaled": float(np.mean(np.abs(z) < 1.959964 * c)),
            "heldout_block_rms_z": [float(np.sqrt(np.mean(zb**2))) for zb in z_all]}
    return c, info


def split_noise_scale(r: np.ndarray, v: np.ndarray, c_min: float = 1e-3, n_grid: int = 301
                      ) -> tuple[float, float]:
    """Maximum-likelihood (c, s) of held-out residuals r_i ~ N(0, c^2 v_i + s^2) (``v_i``: the
    latent posterior variance at the held-out input; s: a target error no function of the input
    explains). For each c on a log grid over [c_min, 1e3] x the rms z, s^2 solves its score
    equation (bisection; the profile likelihood in s^2 is unimodal); the best c is refined by a
    golden-section search between its grid neighbours. c is floored at ``c_min`` x the rms z (a
    zero function error is not representable as a posterior scale). Returns (c, s)."""
    r = np.asarray(r, dtype=float).ravel()
    v = np.asarray(v, dtype=float).ravel()
    if r.size != v.size or r.size < 2:
        raise ValueError(f"split_noise_scale: {r.size} residuals and {v.size} variances")
    r2 = r**2
    c_ref = float(np.sqrt(np.mean(r2 / np.maximum(v, 1e-300))))
    if not np.isfinite(c_ref) or c_ref <= 0:
        return 1.0, 0.0

    def s2_hat(c2: float) -> float:
        # d/ds2 of sum log(c2 v + s2) + r2 / (c2 v + s2) = sum (tot - r2) / tot^2, increasing in s2
        # beyond its root; s2 = 0 if the score at 0 is already >= 0
        def score(s2: float) -> float:
            tot = c2 * v + s2
            return float(np.sum((tot - r2) / np.maximum(tot, 1e-300) ** 2))
        if score(0.0) >= 0:
            return 0.0
        lo, hi = 0.0, float(np.mean(r2)) * 4 + 1e-300
        while score(hi) < 0:
            hi *= 4
        for _ in range(100):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if score(mid) < 0 else (lo, mid)
        return 0.5 * (lo + hi)

    def nll(logc: float) -> tuple[float, float]:
        c2 = np.exp(2 * logc)
        s2 = s2_hat(c2)
        tot = np.maximum(c2 * v + s2, 1e-300)
        return float(np.mean(np.log(tot) + r2 / tot)), s2

    grid = np.log(c_ref) + np.linspace(np.log(c_min), np.log(1e3), n_grid)
    vals = [nll(g)[0] for g in grid]
    k = int(np.argmin(vals))
    a, b = grid[max(k - 1, 0)], grid[min(k + 1, n_grid - 1)]
    gr = (np.sqrt(5) - 1) / 2
    for _ in range(60):
        x1, x2 = b - gr * (b - a), a + gr * (b - a)
        if nll(x1)[0] < nll(x2)[0]:
            b = x2
        else:
            a = x1
    logc = 0.5 * (a + b)
    return float(np.exp(logc)), float(np.sqrt(nll(logc)[1]))
