"""The bending moment, not the curvature, as the smooth profile along s of a camera record's
reconstruction (beyond the paper; ``learning.camera``, ``measured.kinematics.weighted_angle_fit``).

The clamped angle fit rebuilds each frame's curvatures from chord angles under a prior that
their profile along s is smooth (``measured.kinematics.clamped_angle_fit``). The rod's moment
balance makes the bending moment m(s) the smooth profile (m'' = distributed load, continuous
whatever the material); the curvature is m mapped through the law. Where the law is linear
and uniform the two priors agree; where it softens (stiffens), the curvature is sharper
(flatter) than the moment where the rod bends most, at the clamp, and the curvature prior
smooths the largest curvatures away: the law learned from such samples is too stiff at its
edge and too soft next to it. So the reconstruction is repeated with the prior on
w * (kappa - centre), w the secant stiffness of the law the samples themselves show:

* the law: a polynomial m(kappa) pooled over the segments that resolve the curvature
  (``camera.learn.snr_min``), its degree raised from 1 to the next degree, else the one after
  it, while that predicts contiguous held-out time blocks better (``law_choice.
  compare_heldout`` on the total errors, the rule of every choice the data decide in
  ``learning``), up to ``camera.learn.moment_prior.degree_max``. Degree 1 (a linear law, as
  far as the data tell) leaves the curvature prior, which is then exact: the reconstruction is
  the same, bit for bit.
* the weights: the law's secant stiffness about the samples' median curvature, relative to
  its tangent there, at each frame's rebuilt curvatures (clipped to the covered range). A law
  whose secant is not positive over the covered range is not used (reported).
* ``camera.learn.moment_prior.passes`` rounds: each refits the law to the samples of the
  previous reconstruction and rebuilds with its weights.

Off by default (``passes: 0``): measured on the rods of ``benchmarks/materials_unseen.py``, it
rebuilds softening rods' curvatures closer to the truth, and the camera models learned from
them were worse at the test angles on four of the six (docs/camera.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crgpr.learning.law_choice import compare_heldout, poly_design


@dataclass(frozen=True)
class MomentPriorSettings:
    """Section ``camera.learn.moment_prior`` of config.yaml."""

    passes: int
    degree_max: int
    blocks: int

    @classmethod
    def from_config(cls, c: dict) -> MomentPriorSettings:
        return cls(passes=int(c["passes"]), degree_max=int(c["degree_max"]), blocks=int(c["blocks"]))


@dataclass(frozen=True)
class PolynomialLaw:
    """m(kappa) = sum_k a_k u^k, u = (kappa - centre) / scale, kappa clipped to [lo, hi]."""

    coefficients: np.ndarray
    centre: float
    scale: float
    lo: float
    hi: float
    steps: list

    @property
    def degree(self) -> int:
        return self.coefficients.size - 1

    def _u(self, kappa: np.ndarray) -> np.ndarray:
        return (np.clip(kappa, self.lo, self.hi) - self.centre) / self.scale

    def __call__(self, kappa: np.ndarray) -> np.ndarray:
        return np.polynomial.polynomial.polyval(self._u(kappa), self.coefficients)

    def tangent(self, kappa: np.ndarray) -> np.ndarray:
        """dm/dkappa [N m^2] (of the clipped law: the edge values' slope beyond the range)."""
        d = np.polynomial.polynomial.polyder(self.coefficients)
        return np.polynomial.polynomial.polyval(self._u(kappa), d) / self.scale

    def relative_secant(self, kappa: np.ndarray) -> np.ndarray:
        """(m(kappa) - m(centre)) / (kappa - centre) over the tangent at the centre [-]; the
        tangent there where kappa is within 1e-9 of the scale of the centre."""
        k = np.clip(np.asarray(kappa, dtype=float), self.lo, self.hi)
        d = k - self.centre
        near = np.abs(d) <= 1e-9 * self.scale
        rise = self(k) - self(np.array(self.centre))
        sec = np.where(near, self.tangent(k), rise / np.where(near, 1.0, d))
        return sec / float(self.tangent(np.array(self.centre)))

    def admissible(self, n_grid: int = 201) -> bool:
        """The secant about the centre is positive over the covered range: the moment grows with
        the curvature's distance from the centre, both ways (a softening law's tangent may come
        near zero at the edge of its covered range, and its polynomial's below it)."""
        return bool(self.tangent(np.array(self.centre)) > 0.0
                    and np.all(self.relative_secant(np.linspace(self.lo, self.hi, n_grid)) > 0.0))


def polynomial_law(kappa: np.ndarray, m: np.ndarray, degree_max: int, blocks: int) -> PolynomialLaw:
    """The pooled law of the module docstring: degree from 1, raised to the next degree (else the
    one after it: an odd law gains nothing from an even term) whose total held-out error over
    ``blocks`` contiguous blocks of the time-ordered samples is lower
    (``law_choice.compare_heldout``, pooled), while one is; ``steps`` records each degree tried
    (degree, against, log ratio, se, taken)."""
    kappa = np.asarray(kappa, dtype=float).ravel()
    m = np.asarray(m, dtype=float).ravel()
    degree, steps = 1, []
    while degree < degree_max:
        taken = False
        for d in range(degree + 1, min(degree + 2, degree_max) + 1):
            c = compare_heldout(m, poly_design(kappa, degree), poly_design(kappa, d), blocks, d, pooled=True)
            steps.append({"degree": d, "against": degree, "heldout_log_ratio": c.heldout_log_ratio,
                          "heldout_log_ratio_se": c.heldout_log_ratio_se, "taken": c.richer})
            if c.richer:
                degree, taken = d, True
                break
        if not taken:
            break
    centre, scale = float(np.median(kappa)), float(np.std(kappa)) or 1.0
    coef = np.linalg.lstsq(np.polynomial.polynomial.polyvander((kappa - centre) / scale, degree), m,
                           rcond=None)[0]
    return PolynomialLaw(coef, centre, scale, float(kappa.min()), float(kappa.max()), steps)
