"""Candidate physical effects of the missing-physics workflow and their force signatures.

Each effect is a named, physically parameterised term of the planar rod dPHS with its
place in the structure (paper eq. (dphs_form)), so that the augmented model stays passive:

=====================  ===============  ==========================================  =========
name                   unit             term                                        place
=====================  ===============  ==========================================  =========
viscous_drag           N s/m^2          force -c v per length                       R >= 0
air_drag               N s^2/m^3        force -c |v| v per length                   R(z) >= 0
tip_mass               kg               point mass at the free tip                  H (+ G u)
nonlinear_stiffness    m^2              m = EI dk (1 + b dk^2), b >= 0              H
rest_curvature         1/m              uniform intrinsic curvature kappa0          H
stiffness_gradient     -                EI(s) = EI (1 - g s / L0), g < 1            H
base_compliance        N m/rad          rotational base spring k (inf = clamp)      H
internal_damping       N m^2 s          Kelvin-Voigt bending damping m += c dk/dt   R >= 0
stiffness_scale        -                E = E_nominal (1 + a): EA, GA, EI together  H
=====================  ===============  ==========================================  =========

The cut-moment residual and each candidate's signature are in ``crgpr.discovery.residual``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from crgpr.physics.params import RodParams


@dataclass(frozen=True)
class Effect:
    """One candidate effect: its RodParams field, unit and admissible range.

    ``reg_lo``/``reg_hi`` bound the regression parameter (the coefficient itself, except for
    base_compliance which is regressed as the compliance C = 1/k [rad/(N m)]).
    """

    name: str
    field: str
    unit: str
    place: str
    description: str
    reg_lo: float
    reg_hi: float
    probe: float  # a small step of the regression parameter (finite-difference sensitivities)

    def to_coefficient(self, reg: float) -> float:
        """Regression parameter -> reported coefficient (k = 1/C for base_compliance)."""
        if self.name == "base_compliance":
            return math.inf if reg <= 0 else 1.0 / reg
        return reg

    def coefficient_std(self, reg: float, reg_std: float) -> float:
        if self.name == "base_compliance":
            return math.inf if reg <= 0 else reg_std / reg**2
        return reg_std

    def apply(self, params: RodParams, reg: float) -> RodParams:
        """Augmented parameters with this effect at regression value ``reg`` added."""
        if self.name == "base_compliance":
            return params.replace(base_spring=self.to_coefficient(reg))
        return params.replace(**{self.field: getattr(params, self.field) + reg})


EFFECTS: dict[str, Effect] = {e.name: e for e in (
    Effect("viscous_drag", "viscous_drag", "N s/m^2", "R",
           "linear (viscous) drag force -c v per unit length", 0.0, math.inf, 0.01),
    Effect("air_drag", "air_drag", "N s^2/m^3", "R",
           "quadratic (form) drag force -c |v| v per unit length", 0.0, math.inf, 0.01),
    Effect("tip_mass", "tip_mass", "kg", "H, G u",
           "point mass at the free tip (inertia and weight)", 0.0, math.inf, 0.002),
    Effect("nonlinear_stiffness", "nonlinear_stiffness", "m^2", "H",
           "cubic stiffening of the bending moment EI dk (1 + b dk^2)", 0.0, math.inf, 0.002),
    Effect("rest_curvature", "kappa0", "1/m", "H",
           "uniform intrinsic curvature kappa0", -math.inf, math.inf, 0.2),
    Effect("stiffness_gradient", "stiffness_gradient", "-", "H",
           "linear taper of the bending stiffness EI (1 - g s / L0)", -math.inf, 0.999, 0.1),
    Effect("base_compliance", "base_spring", "N m/rad", "H",
           "rotational spring k at the base instead of a clamp", 0.0, math.inf, 1.0),
    Effect("internal_damping", "internal_damping", "N m^2 s", "R",
           "Kelvin-Voigt bending damping m += c dkappa/dt", 0.0, math.inf, 1.0e-5),
    Effect("stiffness_scale", "stiffness_scale", "-", "H",
           "uniform stiffness error E = E_nominal (1 + a) (EA, GA, EI together)", -0.9, math.inf, 0.05),
)}
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)


def effect_params(params: RodParams, effects: dict[str, float]) -> RodParams:
    """RodParams with named effects set to the given coefficients (k for base_compliance)."""
    changes = {}
    for name, val in effects.items():
        if name not in EFFECTS:
            raise KeyError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
        changes[EFFECTS[name].field] = float(val)
    return params.replace(**changes)
