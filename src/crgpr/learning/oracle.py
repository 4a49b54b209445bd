"""Oracle components: the best analytic function of the paper's OWN features.

Each learned component of the paper's CR-GPR model (Sec. III-B step 3, GPR 1-6, eqs. (14)-(16))
is replaced by the rod's constitutive law (eqs. (5), (6), (10)) written in the inputs that GP
receives, so that an ablation separates "the features cannot carry the information" from "a GP
cannot learn it from one trajectory". All are ``learning.learned.Component`` callables and plug
into ``LearnedRod(components, 'paper', params, theta_center)`` unchanged.

* ``q_x``, ``q_y`` (GPR 1, 2; inputs [theta_bar_j, x'_j, y'_j] per segment): EXACT. With
  nu1 = cos(tb) x' + sin(tb) y', nu2 = -sin(tb) x' + cos(tb) y', n1 = EA (nu1 - nu1^0),
  n2 = GA (nu2 - nu2^0): q_x = n1 cos(tb) - n2 sin(tb), q_y = n1 sin(tb) + n2 cos(tb), the
  discrete rod's segment resultants (rod.py), equal to the targets to round-off.
* ``dH_dtheta`` (GPR 3; inputs [theta_i, theta_{i-1}, theta_{i+1}, theta''_i, x'_i, y'_i] at
  node i): the discrete target is
      H_theta,i = -EI theta''_i - (c_{i-1} + c_i) / 2,  c_j = nu1_j n2_j - nu2_j n1_j,
  (tip: -EI theta''_N - c_{N-1}, with the tip stencil theta'' = 2 (theta_{N-1} - theta_N) / ds^2).
  The bending part is exact in these inputs. The couples need the two SEGMENT slopes e_{i-1},
  e_i, which the inputs only give through their nodal central difference x'_i = (e_{i-1} +
  e_i) / 2. What the inputs cannot express is reconstructed under the one assumption that the
  two segments share the node's stretch and shear: the mid-segment angles are exact,
  tb_{i-1} = (theta_{i-1} + theta_i) / 2, tb_i = (theta_i + theta_{i+1}) / 2, and the segment
  slopes are the nodal slope rotated by -/+ delta, delta = (tb_i - tb_{i-1}) / 2, with length
  |x'_i| / cos(delta) (the chord of two equal segments turning by 2 delta). The tip is
  recognised by its ghost stencil theta_{i+1} = theta_{i-1} (features.paper_theta_features);
  there e_{N-1} is recovered from the one-sided nodal slope 1.5 e_{N-1} - 0.5 e_{N-2} assuming the
  last two segments turn by the tip's own theta_N - theta_{N-1}. ``mode='nodal'`` instead evaluates both
  couples with the unrotated nodal slope (the naive stencil), for comparison.
* ``dH_dp_x``, ``dH_dp_y``, ``dH_dp_theta`` (GPR 4-6): EXACT, p / (rho A) and p / (rho I), with
  ``.slope`` for the exact damping flow of the integrator.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from crgpr.physics.params import RodParams

ORACLE_COMPONENTS: tuple[str, ...] = ("q_x", "q_y", "dH_dtheta", "dH_dp_x", "dH_dp_y", "dH_dp_theta")


def _resultants(tb: np.ndarray, ex: np.ndarray, ey: np.ndarray, P: RodParams):
    c, s = np.cos(tb), np.sin(tb)
    nu1 = c * ex + s * ey
    nu2 = -s * ex + c * ey
    n1 = P.EA * (nu1 - P.nu1_0)
    n2 = P.GA * (nu2 - P.nu2_0)
    return c, s, nu1, nu2, n1, n2


class SegmentResultant:
    """q_x or q_y of GPR 1, 2 from [theta_bar, x', y'] (exact constitutive law)."""

    def __init__(self, params: RodParams, axis: int):
        if params.nonlinear_stiffness or params.stiffness_gradient or not params.material.is_linear:
            raise ValueError("oracle: only the paper's linear, uniform rod is written in closed form")
        self.params, self.axis = params, axis

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        c, s, _, _, n1, n2 = _resultants(X[..., 0], X[..., 1], X[..., 2], self.params)
        return n1 * c - n2 * s if self.axis == 0 else n1 * s + n2 * c


class ThetaDerivative:
    """dH/dtheta of GPR 3 from the nodal stencils (see module docstring for the closure)."""

    def __init__(self, params: RodParams, mode: str = "rotated"):
        if (params.nonlinear_stiffness or params.stiffness_gradient or params.kappa0
                or not params.material.is_linear):
            raise ValueError("oracle: only the paper's linear, uniform, straight rod has a closed form")
        if mode not in ("rotated", "nodal"):
            raise ValueError(f"oracle dH_dtheta: unknown mode {mode!r}; expected 'rotated' or 'nodal'")
        self.params, self.mode = params, mode

    def _couple(self, tb: np.ndarray, ex: np.ndarray, ey: np.ndarray) -> np.ndarray:
        _, _, nu1, nu2, n1, n2 = _resultants(tb, ex, ey, self.params)
        return nu1 * n2 - nu2 * n1

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        P = self.params
        th, thm, thp, th2, ex, ey = (X[..., k] for k in range(6))
        tip = thp == thm  # ghost stencil theta_{N+1} = theta_{N-1}
        tbm = 0.5 * (thm + th)
        tbp = 0.5 * (th + thp)
        if self.mode == "nodal":
            cm, cp = self._couple(tbm, ex, ey), self._couple(tbp, ex, ey)
        else:
            delta = 0.5 * (tbp - tbm)
            scale = 1.0 / np.cos(delta)
            cd, sd = np.cos(delta), np.sin(delta)
            # e_{i-1} = R(-delta) x'_i / cos(delta), e_i = R(+delta) x'_i / cos(delta)
            exm, eym = scale * (cd * ex + sd * ey), scale * (-sd * ex + cd * ey)
            exp_, eyp = scale * (cd * ex - sd * ey), scale * (sd * ex + cd * ey)
            cm, cp = self._couple(tbm, exm, eym), self._couple(tbp, exp_, eyp)
            # tip: x'_N = (3 x_N - 4 x_{N-1} + x_{N-2}) / (2 ds) = 1.5 e_{N-1} - 0.5 e_{N-2}; with
            # e_{N-2} = R(-a) e_{N-1}, a = theta_N - theta_{N-1} (constant curvature over the last
            # two segments), e_{N-1} = (1.5 I - 0.5 R(-a))^-1 x'_N
            a = th - thm
            # 1.5 I - 0.5 R(-a) = [[m11, m12], [-m12, m11]]
            m11, m12 = 1.5 - 0.5 * np.cos(a), -0.5 * np.sin(a)
            det = m11 * m11 + m12 * m12
            ext, eyt = (m11 * ex - m12 * ey) / det, (m12 * ex + m11 * ey) / det
            cm = np.where(tip, self._couple(tbm, ext, eyt), cm)
        couples = np.where(tip, cm, 0.5 * (cm + cp))
        return -P.EI * th2 - couples


class MomentumVelocity:
    """H_p = p / (rho A) or p / (rho I) (GPR 4-6), with the slope the integrator needs."""

    def __init__(self, params: RodParams, axis: int):
        self.inv = 1.0 / (params.rhoI if axis == 2 else params.rhoA)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        x = np.asarray(X, dtype=float)
        return self.inv * (x[:, 0] if x.ndim == 2 and x.shape[1] == 1 else x)

    def slope(self, x: np.ndarray) -> np.ndarray:
        return np.full(np.shape(x), self.inv)


def oracle_components(params: RodParams, theta_mode: str = "rotated") -> dict[str, object]:
    """All six oracle components of the paper's model, keyed as LearnedRod expects."""
    return {"q_x": SegmentResultant(params, 0), "q_y": SegmentResultant(params, 1),
            "dH_dtheta": ThetaDerivative(params, theta_mode),
            "dH_dp_x": MomentumVelocity(params, 0), "dH_dp_y": MomentumVelocity(params, 1),
            "dH_dp_theta": MomentumVelocity(params, 2)}


def mixed_components(learned: Mapping[str, object], params: RodParams, learned_names: tuple[str, ...],
                     theta_mode: str = "rotated") -> dict[str, object]:
    """Oracle components except ``learned_names``, which come from ``learned``."""
    comps = oracle_components(params, theta_mode)
    for name in learned_names:
        if name not in comps:
            raise ValueError(f"oracle ablation: unknown component {name!r}; expected {ORACLE_COMPONENTS}")
        comps[name] = learned[name]
    return comps
