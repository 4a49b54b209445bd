"""Statistics shared by the learning and discovery packages."""

from __future__ import annotations

import numpy as np


def autocorrelation_time(series: np.ndarray, axis: int) -> float:
    """Integrated autocorrelation time 1 + 2 sum_k rho_k of ``series`` along ``axis`` (Geyer's
    initial positive sequence: lags until the first non-positive autocorrelation; the other
    axes pooled); 1 for fewer than three samples or a constant series. The number of samples
    over it is an effective number of independent ones."""
    x = np.moveaxis(series, axis, 0)
    x = x - x.mean(axis=0, keepdims=True)
    n = x.shape[0]
    var = float(np.mean(x**2))
    if n < 3 or var <= 0:
        return 1.0
    tau = 1.0
    for k in range(1, n // 2):
        rho = float(np.mean(x[k:] * x[:-k])) / var
        if rho <= 0.0:
            break
        tau += 2.0 * rho
    return max(1.0, tau)


__all__ = ["autocorrelation_time"]
