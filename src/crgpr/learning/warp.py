"""The record fit's warp of a bending law (``learning.record_fit``): m(kappa) w(kappa).

w = 1 + sum_{k < K} a_k u^(2k), u = (kappa - c) / kappa_s clipped to [-1, 1]: even in u (the law
keeps its symmetry about its centre c), multiplicative (m(c) = 0 is kept), constant beyond the
covered range |kappa - c| <= kappa_s (the polynomial is not extrapolated).
"""

from __future__ import annotations

from typing import Any

import numpy as np

Warp = tuple[float, float, np.ndarray]  # (center c [1/m], kappa scale kappa_s [1/m], coefficients a_k)


def _u2(kappa: np.ndarray, center: float, scale: float) -> np.ndarray:
    """u^2, u = (kappa - center) / scale clipped to [-1, 1]."""
    return np.minimum(((np.asarray(kappa, dtype=float) - center) / scale) ** 2, 1.0)


def warp_factor(kappa: np.ndarray, center: float, scale: float, coefficients: np.ndarray) -> np.ndarray:
    """w(kappa) = 1 + sum_k a_k u^(2k), u = (kappa - center) / scale clipped to [-1, 1] (beyond the
    covered range the warp stays at its edge value: the polynomial is not extrapolated);
    ``coefficients`` (K,) or, for a batch of rods, (B, K) against kappa (B, ...)."""
    a = np.asarray(coefficients, dtype=float)
    u2 = _u2(kappa, center, scale)
    w = np.ones_like(u2)
    for k in range(a.shape[-1]):
        ak = a[..., k] if a.ndim == 1 else a[:, k].reshape((-1,) + (1,) * (u2.ndim - 1))
        w = w + ak * u2**k
    return w


def admissible(coefficients: np.ndarray, n_grid: int = 201) -> np.ndarray:
    """Whether each row of warp coefficients (B, K) keeps the law's sign: w(u) > 0 for u in
    [0, 1] (a warp that reverses the law where few samples constrain it, at the edge of the
    covered range, is refused)."""
    a = np.atleast_2d(np.asarray(coefficients, dtype=float))
    u = np.broadcast_to(np.linspace(0.0, 1.0, n_grid), (a.shape[0], n_grid))
    return np.all(warp_factor(u, 0.0, 1.0, a) > 0.0, axis=1)


def warp_sd(kappa: np.ndarray, center: float, scale: float, cov: np.ndarray) -> np.ndarray:
    """The sd of w(kappa) from the covariance ``cov`` (K, K) of its coefficients (the record
    fit's ``coefficient_cov``): sqrt(g^T cov g), g_k = u^(2k) as in ``warp_factor``."""
    C = np.asarray(cov, dtype=float)
    u2 = _u2(kappa, center, scale)
    g = np.stack([u2**k for k in range(C.shape[0])], axis=-1)
    return np.sqrt(np.maximum(np.einsum("...k,kl,...l->...", g, C, g), 0.0))


class BendingWarp:
    """A bending-law component (``learned.Component``, objective features: column 0 is kappa)
    times ``warp_factor``; coefficients (B, K) warp member b of a batched rollout by row b. A
    wrapper like ``nominal.SelectedInputs``: ``component`` is the law it wraps (a posterior
    sample set for the UQ rollout), ``rewrap`` the same warp around another."""

    def __init__(self, component: Any, center: float, scale: float, coefficients: np.ndarray):
        self.component, self.center, self.scale = component, float(center), float(scale)
        self.coefficients = np.asarray(coefficients, dtype=float)
        self.meta = getattr(component, "meta", {})

    def __call__(self, X: np.ndarray) -> np.ndarray:
        return self.component(X) * warp_factor(X[..., 0], self.center, self.scale, self.coefficients)

    def rewrap(self, component: Any) -> BendingWarp:
        return BendingWarp(component, self.center, self.scale, self.coefficients)


def manifest_warp(record_fit: dict[str, Any] | None) -> Warp | None:
    """(center, kappa_scale, coefficients) of a manifest's kept warp, else None."""
    if not record_fit or not record_fit.get("kept"):
        return None
    return (float(record_fit["center"]), float(record_fit["kappa_scale"]),
            np.asarray(record_fit["coefficients"], dtype=float))


def manifest_warp_cov(record_fit: dict[str, Any] | None) -> np.ndarray | None:
    """The covariance of a manifest's kept warp's coefficients, else None (none kept, or a
    manifest written before the record fit recorded it)."""
    if manifest_warp(record_fit) is None or record_fit.get("coefficient_cov") is None:
        return None
    return np.asarray(record_fit["coefficient_cov"], dtype=float)
