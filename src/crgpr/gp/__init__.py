"""Gaussian-process regression (paper Sec. III-B steps 2-3, Table II; R&W 2006 Sec. 2.2, 2.7).

Public API:
* ``GP``, ``fit_gp``: exact GP with explicit basis, marginal-likelihood fit (``_gpr``);
* ``smooth_series``: a 1-D Matern-5/2 smoother with analytic derivatives (the prefilter);
* ``kernel_matrix``, ``basis_matrix_std``, ``GPError``;
* ``sampling``: posterior function samples (RFF, pathwise conditioning; paper Sec. III-C);
* ``exact``: ``ExactMean``, a fitted GP's exact posterior mean, truncated and compiled (issue 11).
"""

from crgpr.gp._gpr import (
    BASES,
    GP,
    KERNELS,
    GPError,
    basis_matrix_std,
    fit_gp,
    kernel_matrix,
    smooth_series,
)

__all__ = [
    "BASES", "GP", "GPError", "KERNELS", "basis_matrix_std", "fit_gp", "kernel_matrix", "smooth_series",
]
