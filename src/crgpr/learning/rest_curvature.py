"""The rest curvature of a rod from its bending samples: the zero of the moment law m(kappa).

A rod at rest curvature kappa0 carries no bending moment there: m(kappa0) = 0 (eq. (10) with
any law of docs/materials.md; a uniform kappa0, as the objective features' one law m(kappa)
assumes). ``rest_curvature_estimate`` fits a cubic polynomial to the samples (kappa_i, m_i) by
least squares, in standardised kappa, and returns its real root inside the sampled range where
the fitted law rises (m' > 0, a stable material), polished by Newton steps. For the linear law
the fit is exact and so is the root; for a nonlinear law sampled unevenly about kappa0 the
cubic is an approximation and so is its root (tests/test_rest_curvature.py). ``crgpr learn``
uses it as the centre of the odd-symmetric bending law (``camera.learn.bending_symmetry:
odd_estimated``) instead of the nominal rod's kappa0.
"""

from __future__ import annotations

import numpy as np


def rest_curvature_estimate(kappa: np.ndarray, m: np.ndarray) -> float:
    """kappa0 [1/m] with m(kappa0) = 0 of the least-squares cubic m(kappa) through the samples.

    Raises ValueError when the samples do not bracket a rising zero of the fitted law."""
    kappa = np.asarray(kappa, dtype=float).ravel()
    m = np.asarray(m, dtype=float).ravel()
    if kappa.size != m.size or kappa.size < 4:
        raise ValueError(f"rest curvature: need >= 4 (kappa, m) pairs of equal length, got "
                         f"{kappa.size} and {m.size}")
    mu, sd = kappa.mean(), kappa.std()
    if not sd > 0:
        raise ValueError("rest curvature: the samples do not vary in kappa")
    u = (kappa - mu) / sd
    coef = np.polynomial.polynomial.polyfit(u, m, 3)
    roots = np.polynomial.polynomial.polyroots(coef)
    slope = np.polynomial.polynomial.polyder(coef)
    real = roots[np.abs(roots.imag) <= 1e-9 * max(1.0, np.abs(roots).max())].real
    ok = [r for r in real if u.min() <= r <= u.max()
          and np.polynomial.polynomial.polyval(r, slope) > 0]
    if not ok:
        raise ValueError("rest curvature: the bending samples do not cross m = 0 with a rising law "
                         f"within kappa in [{kappa.min():.3g}, {kappa.max():.3g}] 1/m")
    r = min(ok, key=lambda x: abs(x - np.median(u)))
    for _ in range(3):  # Newton polish: the companion-matrix roots lose digits when the
        r -= np.polynomial.polynomial.polyval(r, coef) / np.polynomial.polynomial.polyval(r, slope)
    return float(mu + sd * r)
