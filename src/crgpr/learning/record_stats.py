"""Statistics of the record fit (``learning.record_fit``): its held-out decision, the covariance
of a kept warp's coefficients, the Wald statistic of a block of them and the warp's truncation
estimate."""

from __future__ import annotations

from typing import Any

import numpy as np

from crgpr.learning.laws import consistent_gain, heldout_blocks, log_error_ratio
from crgpr.stats import autocorrelation_time


def warp_covariance(r: np.ndarray, J: np.ndarray, n_frames: int, K: int) -> np.ndarray:
    """Covariance (K, K) of the warp coefficients (the last K columns of J) of a least-squares fit
    with residuals r (frames x nodes, time-major) and Jacobian J: s^2 (J^T J)^-1, s^2 the residual
    variance, times the residuals' correlation times along the record and along the rod (an
    effective number of independent residuals; the Gauss-Newton covariance alone would count
    every frame and node as independent)."""
    R = np.asarray(r, dtype=float).reshape(n_frames, -1)
    s2 = float(np.sum(R**2)) / max(R.size - J.shape[1], 1)
    inflate = autocorrelation_time(R, 0) * autocorrelation_time(R, 1)
    C = s2 * inflate * np.linalg.pinv(J.T @ J)
    return C[-K:, -K:]


def decide(e_start: np.ndarray, e_warp: np.ndarray, blocks: int) -> tuple[float, float, bool]:
    """Held-out forecast comparison: per-block squared errors of the start-only and the warped
    fits over the record's last part (``blocks`` contiguous blocks) -> ``consistent_gain``."""
    masks = heldout_blocks(e_start.shape[0], blocks)
    d = np.array([log_error_ratio(float(np.mean(e_start[m])), float(np.mean(e_warp[m]))) for m in masks])
    return consistent_gain(d)


def truncation(fits: list[np.ndarray], terms: list[int], i: int, w0: int) -> dict[str, Any]:
    """The truncation estimate of the warp of ``terms[i]`` terms among the candidates' fits on the
    same first part of the record (``fits``, parameter rows whose warp starts at column ``w0``):
    the warp of the next number of terms less this one's, d_k = a'_k - a_k (the next larger
    candidate's where there is one, it estimates this one's error; else the next smaller one's,
    or no warp: conservative). ``warp.warp_sd`` adds it to the law's band."""
    j = i + 1 if i + 1 < len(terms) else i - 1
    K = max(terms)
    other = fits[j][w0:w0 + K] if j >= 0 else np.zeros(K)
    return {"truncation_coefficients": [float(v) for v in other - fits[i][w0:w0 + K]],
            "truncation_terms": terms[j] if j >= 0 else 0}


def coefficient_wald(r: np.ndarray, J: np.ndarray, n_frames: int, free: np.ndarray, block: np.ndarray,
                     a: np.ndarray) -> tuple[float, list[float]]:
    """The Wald statistic a_b^T C_b^-1 a_b of the free parameters ``block`` (indices) of a fit at
    ``a`` (residuals r, Jacobian J over the ``free`` parameters, ``n_frames`` frames), C_b their
    covariance (``warp_covariance``, inflated by the residuals' correlation times),
    and their sd."""
    cols = np.searchsorted(np.flatnonzero(free), block)
    C = warp_covariance(r, J, n_frames, J.shape[1])[np.ix_(cols, cols)]
    ab = np.asarray(a, dtype=float)[block]
    return float(ab @ np.linalg.pinv(C) @ ab), [float(v) for v in np.sqrt(np.maximum(np.diag(C), 0.0))]


__all__ = ["coefficient_wald", "decide", "truncation", "warp_covariance"]
