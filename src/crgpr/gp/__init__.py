"""Gaussian-process regression (paper Sec. III-B steps 2-3, Table II; R&W 2006 Sec. 2.2, 2.7).

Public API:
* ``GP``, ``fit_gp``, ``ELL_BOUNDS_STD``: exact GP with explicit basis, marginal-likelihood fit (``_gpr``);
* ``smooth_series``: a 1-D Matern-5/2 smoother with analytic derivatives (the prefilter);
* ``kernel_matrix``, ``basis_matrix_std``, ``GPError``;
* evaluators of the posterior mean (``evaluators``): ``KernelMean`` (the exact mean over all n
  points with truncated kernel sums on a cell grid, ``exact_weights``; or the DTC mean),
  ``Table1D`` (1-D with slope), ``load_evaluator`` (from a saved model), the one compiled
  ``kernel_sum``;
* sparse means (``sparse``): ``select_inducing``, ``dtc_fit``;
* ``sampling``: posterior function samples (RFF, pathwise conditioning; paper Sec. III-B, RFF sampling).
"""

from crgpr.gp._gpr import (
    BASES,
    ELL_BOUNDS_STD,
    GP,
    KERNELS,
    GPError,
    basis_matrix_std,
    fit_gp,
    kernel_matrix,
    smooth_series,
)
from crgpr.gp.evaluators import KernelMean, Table1D, cutoff_radius, exact_weights, load_evaluator, load_model
from crgpr.gp.sparse import dtc_fit, select_inducing

__all__ = [
    "BASES", "ELL_BOUNDS_STD", "GP", "GPError", "KERNELS", "KernelMean", "Table1D", "basis_matrix_std",
    "cutoff_radius",
    "dtc_fit", "exact_weights", "fit_gp", "kernel_matrix", "load_evaluator", "load_model", "select_inducing",
    "smooth_series",
]
