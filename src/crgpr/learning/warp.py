"""The record fit's warp of a bending law (``learning.record_fit``): m(kappa - d(s), s) w(kappa - d(s)) v(s).

w = 1 + sum_{k < K} a_k u^(2k), u = (kappa - c) / kappa_s clipped to [-1, 1]: even in u (the law
keeps its symmetry about its centre c), multiplicative (m(c) = 0 is kept), constant beyond the
covered range |kappa - c| <= kappa_s (the polynomial is not extrapolated).

v = exp(sum_{j = 1..S} b_j P_j(2 s/L - 1)), P_j the Legendre polynomials: a stiffness profile
along the rod (S = 0: v = 1), offered where the bending law takes s as an input. Positive for any
b; evaluated at each segment's mid-point s_j = (j + 1/2) L / N. d = sum_{j = 0..R-1} c_j
P_j(2 s/L - 1) [1/m]: a correction of the law's rest curvature along the rod (R = 0: d = 0),
offered with v; it shifts the law's curvature inputs (kappa and its neighbours' columns).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

# (center c [1/m], kappa scale kappa_s [1/m], a_k, b_j, c_j [1/m])
Warp = tuple[float, float, np.ndarray, np.ndarray, np.ndarray]


def _u2(kappa: np.ndarray, center: float, scale: float) -> np.ndarray:
    """u^2, u = (kappa - center) / scale clipped to [-1, 1]."""
    return np.minimum(((np.asarray(kappa, dtype=float) - center) / scale) ** 2, 1.0)


def warp_factor(kappa: np.ndarray, center: float, scale: float, coefficients: np.ndarray) -> np.ndarray:
    """w(kappa) = 1 + sum_k a_k u^(2k), u = (kappa - center) / scale clipped to [-1, 1] (beyond the
    covered range the warp stays at its edge value: the polynomial is not extrapolated);
    ``coefficients`` (K,) or, for a batch of rods, (B, K) against kappa (B, ...)."""
    a = np.asarray(coefficients, dtype=float)
    k = np.asarray(kappa, dtype=float)
    if a.shape[-1] == 0:
        return np.ones_like(k)
    if a.ndim == 1 or a.shape[0] == 1:  # one warp for every kappa
        a, shape = a.reshape(1, -1), k.shape
    else:  # member b's warp against kappa[b]
        shape = a.shape[:1] + k.shape[1:]
    rows = (k if k.shape == shape else np.broadcast_to(k, shape)).reshape(a.shape[0], -1)
    out = np.empty(rows.shape)
    _warp_rows(np.ascontiguousarray(rows), float(center), float(scale), np.ascontiguousarray(a), out)
    return out.reshape(shape)


@njit(cache=True)
def _warp_rows(kappa, center, scale, a, out):  # pragma: no cover - compiled
    """``warp_factor`` of row b of ``kappa`` (B, n) with coefficients a[b] (B, K), term by term
    as 1 + a_0 + a_1 u^2 + a_2 (u^2)^2 + a_3 pow(u^2, 3) + ... (a rollout's hot path)."""
    K = a.shape[1]
    for b in range(kappa.shape[0]):
        for i in range(kappa.shape[1]):
            t = (kappa[b, i] - center) / scale
            u2 = t * t
            if u2 > 1.0:
                u2 = 1.0
            w = 1.0 + a[b, 0]
            for j in range(1, K):
                if j == 1:
                    pj = u2
                elif j == 2:
                    pj = u2 * u2
                else:
                    pj = math.pow(u2, float(j))  # C pow, as numpy's u2**j
                w = w + a[b, j] * pj
            out[b, i] = w


def _legendre(s_rel: np.ndarray, S: int, first: int = 1) -> np.ndarray:
    """P_j(2 s_rel - 1), j = first..first + S - 1, stacked on a last axis (..., S)."""
    x = 2.0 * np.asarray(s_rel, dtype=float) - 1.0
    P = [np.ones_like(x), x]
    for j in range(1, first + S):
        P.append(((2 * j + 1) * x * P[j] - j * P[j - 1]) / (j + 1))
    return np.stack(P[first:first + S], axis=-1) if S else np.zeros((*x.shape, 0))


def _along(s_rel: np.ndarray, coefficients: np.ndarray, first: int) -> np.ndarray:
    """sum_j coefficients_j P_(first + j)(2 s_rel - 1): (S,) -> (n,), (B, S) -> (B, n)."""
    b = np.asarray(coefficients, dtype=float)
    G = _legendre(s_rel, b.shape[-1], first)
    return (G @ b.T).T if b.ndim == 2 else G @ b


def rest_shift(s_rel: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """d(s) = sum_{j < R} c_j P_j(2 s_rel - 1) [1/m] at the relative arclengths ``s_rel`` (n,);
    ``coefficients`` (R,) -> (n,), or (B, R) for a batch of rods -> (B, n)."""
    return _along(s_rel, coefficients, 0)


def profile_factor(s_rel: np.ndarray, coefficients: np.ndarray) -> np.ndarray:
    """v(s) = exp(sum_j b_j P_j(2 s_rel - 1)) at the relative arclengths ``s_rel`` = s/L (n,);
    ``coefficients`` (S,) -> (n,), or (B, S) for a batch of rods -> (B, n)."""
    return np.exp(_along(s_rel, coefficients, 1))


def law_factor(kappa: np.ndarray, s_rel: np.ndarray | None, warp: Warp) -> np.ndarray:
    """w(kappa) v(s) of a ``Warp`` at curvatures ``kappa`` (already shifted by its ``rest_shift``:
    ``shifted_kappa``) and relative arclengths ``s_rel`` (broadcast together; None: a law without
    s, v = 1)."""
    w = warp_factor(kappa, warp[0], warp[1], warp[2])
    b = np.asarray(warp[3], dtype=float)
    return w if s_rel is None or b.size == 0 else w * profile_factor(np.asarray(s_rel, dtype=float).ravel(),
                                                                       b).reshape(np.shape(s_rel))


def has_rest_shift(warp: Warp | None) -> bool:
    """Whether a ``Warp`` shifts its law's rest curvature along the rod (``rest_shift`` terms)."""
    return warp is not None and np.asarray(warp[4]).size > 0


def shifted_kappa(kappa: np.ndarray, s_rel: np.ndarray | None, warp: Warp | None) -> np.ndarray:
    """kappa - d(s): the curvature at which a ``Warp`` evaluates the law (kappa where it has no
    rest shift or the law no s)."""
    kappa = np.asarray(kappa, dtype=float)
    if warp is None or s_rel is None or np.asarray(warp[4]).size == 0:
        return kappa
    return kappa - rest_shift(np.asarray(s_rel, dtype=float).ravel(), warp[4]).reshape(np.shape(s_rel))


def warp_sd(kappa: np.ndarray, s_rel: np.ndarray | None, warp: Warp, cov: np.ndarray,
            truncation: np.ndarray | None = None) -> np.ndarray:
    """The sd of w(kappa) v(s) (``law_factor``) from the covariance ``cov`` of its coefficients
    (a_k, b_j, then c_j; the record fit's ``coefficient_cov``), to first order: sqrt(g^T cov g),
    g = (v u^(2k), w v P_j) over the a_k and b_j (the rest shift's c_j move the law's input, not
    its factor: their part of the band is not included); with ``truncation`` (the record fit's
    ``truncation_coefficients`` d_k: the warp of the next number of terms less this one's), the
    warp's truncation error v sum_k d_k u^(2k) is added in quadrature: the covariance holds the
    coefficients' scatter, not the error of a warp with too few terms."""
    K = np.asarray(warp[2]).size
    S = np.asarray(warp[3]).size if s_rel is not None else 0
    C = np.asarray(cov, dtype=float)[:K + S, :K + S]
    u2 = np.broadcast_to(_u2(kappa, warp[0], warp[1]), np.broadcast_shapes(np.shape(kappa), np.shape(
        s_rel) if s_rel is not None else ()))
    w = warp_factor(kappa, warp[0], warp[1], warp[2]) * np.ones_like(u2)
    g = [u2**k for k in range(K)]
    v = np.ones_like(u2)
    if S:
        sr = np.broadcast_to(np.asarray(s_rel, dtype=float), u2.shape)
        v = profile_factor(sr.ravel(), np.asarray(warp[3], dtype=float)[:S]).reshape(u2.shape)
        P = _legendre(sr, S)
        g += [w * P[..., j] for j in range(S)]
    if g:
        G = np.stack(g, axis=-1) * v[..., None]
        var = np.maximum(np.einsum("...k,kl,...l->...", G, C, G), 0.0)
    else:  # no warp or profile coefficient kept (a record fit that kept the start or a damping alone)
        var = np.zeros_like(u2)
    if truncation is not None and np.asarray(truncation).size:
        d = warp_factor(kappa, warp[0], warp[1], np.asarray(truncation, dtype=float)) - 1.0
        var = var + (d * v) ** 2
    return np.sqrt(var)


def segment_positions(n_segments: int) -> np.ndarray:
    """The segments' mid-points s_j / L = (j + 1/2) / N."""
    return (np.arange(n_segments) + 0.5) / n_segments


def admissible(coefficients: np.ndarray, n_grid: int = 201) -> np.ndarray:
    """Whether each row of warp coefficients (B, K) keeps the law's sign: w(u) > 0 for u in
    [0, 1] (a warp that reverses the law where few samples constrain it, at the edge of the
    covered range, is refused)."""
    a = np.atleast_2d(np.asarray(coefficients, dtype=float))
    u = np.broadcast_to(np.linspace(0.0, 1.0, n_grid), (a.shape[0], n_grid))
    return np.all(warp_factor(u, 0.0, 1.0, a) > 0.0, axis=1)


def _coefficients(c: np.ndarray | None) -> np.ndarray | None:
    return None if c is None or np.asarray(c).shape[-1] == 0 else np.asarray(c, dtype=float)


class BendingWarp:
    """A bending-law component (``learned.Component``, objective features (..., N, k) of the N
    segments: columns 0-2 are kappa and its neighbours') times ``warp_factor`` and, with
    ``profile`` coefficients, ``profile_factor`` at each segment's s; with ``rest`` coefficients
    the law and its warp are evaluated at the curvature columns less ``rest_shift``.
    Coefficients (B, K), (B, S) and (B, R) warp member b of a batched rollout by row b. A wrapper
    like ``nominal.SelectedInputs``: ``component`` is the law it wraps (a posterior sample set
    for the UQ rollout), ``rewrap`` the same warp around another."""

    def __init__(self, component: Any, center: float, scale: float, coefficients: np.ndarray,
                 profile: np.ndarray | None = None, rest: np.ndarray | None = None):
        self.component, self.center, self.scale = component, float(center), float(scale)
        self.coefficients = np.asarray(coefficients, dtype=float)
        self.profile, self.rest = _coefficients(profile), _coefficients(rest)
        self.meta = getattr(component, "meta", {})
        self._along: dict[int, tuple[np.ndarray | None, np.ndarray | None]] = {}  # N -> (v, d) per segment

    def _factors(self, n: int) -> tuple[np.ndarray | None, np.ndarray | None]:
        """v(s_j) and d(s_j) of the N = n segments (None without them), computed once per n: they
        do not change between the time steps of a rollout."""
        if n not in self._along:
            s_rel = segment_positions(n)
            self._along[n] = (None if self.profile is None else profile_factor(s_rel, self.profile),
                              None if self.rest is None else rest_shift(s_rel, self.rest))
        return self._along[n]

    @staticmethod
    def _per_segment(v: np.ndarray, ndim: int) -> np.ndarray:
        """(N,) or (B, N) along s -> broadcastable against (..., N) of ``ndim`` axes (B leading)."""
        return v if v.ndim == 1 else v.reshape(v.shape[:1] + (1,) * (ndim - 2) + v.shape[1:])

    def __call__(self, X: np.ndarray) -> np.ndarray:
        along = self.profile is not None or self.rest is not None
        v, d = self._factors(X.shape[-2]) if along else (None, None)
        if d is not None:
            X = np.array(X, dtype=float)
            X[..., :3] -= self._per_segment(d, X.ndim - 1)[..., None]
        w = warp_factor(X[..., 0], self.center, self.scale, self.coefficients)
        if v is not None:
            w = w * self._per_segment(v, w.ndim)
        return self.component(X) * w

    def rewrap(self, component: Any) -> BendingWarp:
        return BendingWarp(component, self.center, self.scale, self.coefficients, self.profile, self.rest)


def manifest_warp(record_fit: dict[str, Any] | None) -> Warp | None:
    """(center, kappa_scale, coefficients, profile coefficients, rest-shift coefficients) of a
    manifest's kept warp, else None."""
    if not record_fit or not record_fit.get("kept"):
        return None
    return (float(record_fit["center"]), float(record_fit["kappa_scale"]),
            np.asarray(record_fit["coefficients"], dtype=float),
            np.asarray(record_fit.get("profile_coefficients") or [], dtype=float),
            np.asarray(record_fit.get("rest_coefficients") or [], dtype=float))


def manifest_warp_truncation(record_fit: dict[str, Any] | None) -> np.ndarray | None:
    """The truncation estimate of a manifest's kept warp (``warp_sd``), else None."""
    if manifest_warp(record_fit) is None or not record_fit.get("truncation_coefficients"):
        return None
    return np.asarray(record_fit["truncation_coefficients"], dtype=float)


def manifest_warp_cov(record_fit: dict[str, Any] | None) -> np.ndarray | None:
    """The covariance of a manifest's kept warp's coefficients, else None (none kept, or a
    manifest written before the record fit recorded it)."""
    if manifest_warp(record_fit) is None or record_fit.get("coefficient_cov") is None:
        return None
    return np.asarray(record_fit["coefficient_cov"], dtype=float)
