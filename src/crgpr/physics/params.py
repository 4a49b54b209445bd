"""Physical and simulation parameters (paper Table I, Sec. IV).

Symbols follow the paper; units are SI and stated next to each field. The rod's own values
have no defaults here: they come from the config (``config.yaml``; the schema's defaults for
``crgpr simulate`` without a config). The extra fields after ``kappa0`` are the physical
effects of the missing-physics workflow; their defaults switch them off.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from crgpr.physics.material import Material


@dataclass(frozen=True)
class RodParams:
    """Planar Cosserat rod parameters (paper Table I plus the choices it leaves out)."""

    L0: float  # rod length [m]
    N: int  # number of segments [-] (N + 1 nodes, node 0 clamped)
    r: float  # cross-section "radius" [m]; the paper's A = pi r^2 / 4
    E: float  # Young's modulus [Pa]
    nu: float  # Poisson ratio [-] (not given in the paper: our choice)
    rho: float  # density [kg/m^3]
    zeta: float  # damping coefficient of R = diag(0, zeta I3) [N s/m^2]
    g: float  # gravity [m/s^2], acting in -y
    nu1_0: float  # intrinsic stretch [-]
    nu2_0: float  # intrinsic shear [-]
    kappa0: float  # intrinsic (rest) curvature [1/m], uniform
    # --- effects for the missing-physics workflow (all off by default) ---
    viscous_drag: float = 0.0  # external force -c v per length, c [N s/m^2]
    air_drag: float = 0.0  # external force -c |v| v per length, c [N s^2/m^3]
    tip_mass: float = 0.0  # point mass at the free tip [kg]
    nonlinear_stiffness: float = 0.0  # b in m = EI dk (1 + b dk^2) [m^2]
    stiffness_gradient: float = 0.0  # g in EI(s) = EI (1 - g s / L0) [-]
    base_spring: float = math.inf  # rotational base spring k [N m/rad]; inf = clamp
    internal_damping: float = 0.0  # Kelvin-Voigt bending damping m += c dkappa/dt, c [N m^2 s]
    stiffness_scale: float = 0.0  # a in E = E_nominal (1 + a): EA, GA, EI scale together [-]
    # --- material laws (config rod.material; material.py; the default is the linear rod) ---
    material: Material = Material()

    # ---- derived quantities -------------------------------------------------
    @property
    def ds(self) -> float:
        """Spatial step L0 / N [m]."""
        return self.L0 / self.N

    @property
    def A(self) -> float:
        """Cross-section area pi r^2 / 4 [m^2] (paper's definition)."""
        return math.pi * self.r**2 / 4.0

    @property
    def I(self) -> float:  # noqa: E743 - the paper's symbol
        """Area moment of inertia A^2 / (4 pi) [m^4]."""
        return self.A**2 / (4.0 * math.pi)

    @property
    def E_eff(self) -> float:
        """Young's modulus of the rod, E (1 + stiffness_scale) [Pa]."""
        return self.E * (1.0 + self.stiffness_scale)

    @property
    def G(self) -> float:
        """Shear modulus E_eff / (2 (1 + nu)) [Pa]."""
        return self.E_eff / (2.0 * (1.0 + self.nu))

    @property
    def EA(self) -> float:
        return self.E_eff * self.A

    @property
    def GA(self) -> float:
        return self.G * self.A

    @property
    def EI(self) -> float:
        return self.E_eff * self.I

    @property
    def rhoA(self) -> float:
        """Line density [kg/m]."""
        return self.rho * self.A

    @property
    def rhoI(self) -> float:
        """Rotational inertia per length [kg m]."""
        return self.rho * self.I

    @property
    def s(self) -> np.ndarray:
        """Arc length of the nodes, s_i = i ds [m]."""
        return np.arange(self.N + 1) * self.ds

    @property
    def clamped(self) -> bool:
        return math.isinf(self.base_spring)

    def replace(self, **changes: Any) -> RodParams:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["material"] = self.material.to_dict()
        if math.isinf(d["base_spring"]):
            d["base_spring"] = None
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> RodParams:
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise KeyError(f"unknown rod parameter(s): {sorted(unknown)}; known: {sorted(known)}")
        d = dict(d)
        if d.get("base_spring", 0.0) is None:
            d["base_spring"] = math.inf
        if "N" in d:
            d["N"] = int(d["N"])
        if "material" in d:
            d["material"] = _material_from_config(d["material"], d)
        return cls(**d)

    def max_frequency(self) -> float:
        """Gershgorin bound on the highest angular frequency of the discrete rod [rad/s].

        Translational rows: 4 max(EA, GA) / (rhoA ds^2); rotational rows:
        4 E / (rho ds^2) + GA / (rho I) (bending plus the shear couple of the
        mid-segment angle); a base spring k adds 2 k / (rho I ds) to the base node's
        rotational row (half a segment of inertia). A material's EI(s) profile raises the
        bending term by its largest factor; the bound is that of the laws' tangent at zero
        strain (the stiffening laws stiffen further under load). The Kelvin-Voigt damping is
        integrated with the rotational kick as one exact flow (``dissipation.kelvin_voigt_flow``)
        and sets no bound. Used to reject a time step that cannot be stable.
        """
        ds = self.ds
        w2_t = 4.0 * max(self.EA, self.GA) / (self.rhoA * ds**2)
        w2_r = 4.0 * self.E_eff / (self.rho * ds**2) + self.GA / self.rhoI
        if not self.material.is_linear:  # the stiffest point of EI(s); at zero strain
            w2_r += 4.0 * self.E_eff * (self.material.max_ei_factor() - 1.0) / (self.rho * ds**2)
        if not self.clamped:
            w2_r += 2.0 * self.base_spring / (self.rhoI * ds)
        return math.sqrt(max(w2_t, w2_r))

    def dt_stable(self) -> float:
        """Largest Stormer-Verlet step the Gershgorin bound allows, 2 / omega_max [s]."""
        return 2.0 / self.max_frequency()


# Spatial discretisations of the rod (config key simulation.scheme): the variational one of
# rod.py (the project's ground truth), the collocated nodal finite differences of
# collocated.py (the stencils of the paper's GPR 3 inputs), and its fully nodal variant
# (summation-by-parts, but with a zero-energy odd-even mode; see collocated.py).
SCHEMES: tuple[str, ...] = ("variational", "collocated", "collocated_nodal")


@dataclass(frozen=True)
class SimSettings:
    """Time integration settings (paper Sec. IV: dt = 1e-4 s, T = 2 s, 4001 samples) and the
    spatial scheme (``SCHEMES``; the paper does not state its own, 'variational' is ours)."""

    dt: float  # time step [s]
    t_end: float  # final time [s]
    record_every: int  # record every k-th step
    scheme: str  # spatial discretisation of the elastic forces (SCHEMES)

    def __post_init__(self) -> None:
        if self.scheme not in SCHEMES:
            raise ValueError(f"unknown spatial scheme {self.scheme!r}; expected one of {SCHEMES}")

    @property
    def n_steps(self) -> int:
        return int(round(self.t_end / self.dt))

    @property
    def n_records(self) -> int:
        return self.n_steps // self.record_every + 1

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _material_from_config(value: Any, d: dict[str, Any]) -> Material:
    """``rod.material`` as a Material; its ``kelvin_voigt`` key sets ``internal_damping`` in ``d``."""
    if isinstance(value, Material):
        return value
    if not isinstance(value, dict):
        raise TypeError(f"rod.material: expected a mapping, got {type(value).__name__}")
    value = dict(value)
    c = value.pop("kelvin_voigt", 0.0)
    if c:  # 0 leaves the internal_damping effect (missing-physics workflow, --set) as given
        if d.get("internal_damping", 0.0) not in (0.0, c):
            raise ValueError("rod.material.kelvin_voigt: conflicts with the internal_damping effect")
        d["internal_damping"] = c
    return Material.from_dict(value)


# RodParams fields given as numbers (``crgpr simulate --set KEY=VALUE``): the material is a section
PARAM_FIELDS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(RodParams) if f.name != "material")
