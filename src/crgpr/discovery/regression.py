"""Step 3 of the workflow, naming: the candidates' signatures regressed on the cut-moment residual.

The residual of the data against the current model (``crgpr.discovery.residual``) is
regressed on every candidate's signature by feasible generalised least squares with one
variance per segment and one for the clamp constraint (heteroscedastic Gaussian model), the
coefficients bounded to each effect's admissible range; the Bayesian information criterion
uses the sample size deflated by the integrated autocorrelation time of the residuals in
time and along s (``autocorrelation_time``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import lsq_linear

from crgpr.discovery.effects import EFFECT_NAMES, EFFECTS
from crgpr.discovery.residual import Residual
from crgpr.stats import autocorrelation_time


@dataclass
class Fit:
    names: list[str]
    coef: np.ndarray  # regression parameters (C = 1/k for base_compliance)
    std: np.ndarray
    m2ll: float  # effective -2 log likelihood
    bic: float


class Regression:
    """Weighted, bounded least squares of the residual on candidate signatures."""

    def __init__(self, res: Residual, rows: slice, candidates: tuple[str, ...] = EFFECT_NAMES,
                 first_segment: int = 1):
        # moment rows of segments first_segment..N-1 (segment 0 needs the extrapolated base
        # angle, which the base row models instead); base rows centred: the spring's rest
        # angle is a nuisance intercept
        seg = slice(first_segment, None)
        self.y_mom = -res.rho[rows, seg]  # (n_t, n_seg): what the missing terms must supply
        self.y_base = res.base_y[rows] - res.base_y[rows].mean()
        self.X_mom = {k: res.sig[k][rows, seg] for k in res.sig}
        self.X_base = res.base_sig[rows] - res.base_sig[rows].mean()
        self.candidates = candidates
        self.n_t, self.n_seg = self.y_mom.shape
        full = self.fit(list(candidates), deflate=False)
        r_mom, r_base = self._residuals(full.names, full.coef)
        z = r_mom / np.sqrt(np.mean(r_mom**2, axis=0, keepdims=True) + 1e-300)
        self.tau_t = autocorrelation_time(z, 0)
        self.tau_s = autocorrelation_time(z, 1)
        self.tau_b = autocorrelation_time(r_base[:, None], 0)
        self.n_eff = self.n_t * self.n_seg / (self.tau_t * self.tau_s) + self.n_t / self.tau_b

    def _design(self, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
        cols_m = [self.X_mom[k] if k != "base_compliance" else np.zeros_like(self.y_mom) for k in names]
        cols_b = [self.X_base if k == "base_compliance" else np.zeros_like(self.y_base) for k in names]
        Xm = np.stack(cols_m, axis=-1) if names else np.zeros(self.y_mom.shape + (0,))
        Xb = np.stack(cols_b, axis=-1) if names else np.zeros(self.y_base.shape + (0,))
        return Xm, Xb

    def _residuals(self, names: list[str], coef: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        Xm, Xb = self._design(names)
        return self.y_mom - Xm @ coef, self.y_base - Xb @ coef

    def fit(self, names: list[str], deflate: bool = True, iters: int = 6) -> Fit:
        """Feasible GLS with one variance per segment and one for the base row."""
        Xm, Xb = self._design(names)
        coef = np.zeros(len(names))
        lo = np.array([EFFECTS[k].reg_lo for k in names])
        hi = np.array([EFFECTS[k].reg_hi for k in names])
        s2m = np.mean(self.y_mom**2, axis=0) + 1e-300
        s2b = float(np.mean(self.y_base**2)) + 1e-300
        A = None
        for _ in range(iters):
            wm = 1.0 / np.sqrt(s2m)
            wb = 1.0 / math.sqrt(s2b)
            Am = (Xm * wm[None, :, None]).reshape(self.n_t * self.n_seg, Xm.shape[-1])
            A = np.concatenate([Am, Xb * wb])
            b = np.concatenate([(self.y_mom * wm[None, :]).ravel(), self.y_base * wb])
            if names:
                coef = lsq_linear(A, b, bounds=(lo, hi), method="bvls").x
            rm, rb = self._residuals(names, coef)
            floor_m = 1e-12 * float(np.mean(self.y_mom**2)) + 1e-300
            s2m = np.maximum(np.mean(rm**2, axis=0), floor_m)
            s2b = max(float(np.mean(rb**2)), 1e-12 * float(np.mean(self.y_base**2)) + 1e-300)
        ft = (self.tau_t * self.tau_s) if deflate else 1.0
        fb = self.tau_b if deflate else 1.0
        m2ll = float(self.n_t * np.sum(np.log(s2m)) / ft + self.n_t * math.log(s2b) / fb)
        n_eff = self.n_eff if deflate else self.n_t * (self.n_seg + 1)
        std = np.zeros(len(names))
        if names:
            try:
                cov = np.linalg.inv(A.T @ A) * (ft if deflate else 1.0)
                std = np.sqrt(np.maximum(np.diag(cov), 0.0))
            except np.linalg.LinAlgError:
                std = np.full(len(names), np.inf)
        return Fit(list(names), coef, std, m2ll, m2ll + len(names) * math.log(max(n_eff, 2.0)))
