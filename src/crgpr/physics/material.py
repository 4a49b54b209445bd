"""Constitutive laws of the planar rod (paper Sec. II: unknown, nonlinear, varying along s).

The stored energy per length is W = W_b(dk; s) + W_s(e) + GA (nu2 - nu2^0)^2 / 2 (eq. (5) with
nonlinear bending and stretch parts), with dk = kappa - kappa^0(s), e = nu1 - nu1^0. Each law
is one energy density and its derivatives, implemented once here (``bend_law``,
``stretch_law``) and called by the variational force kernel (``rod._internal_forces``), its
tangent (``kernels._force_tangent``) and the vectorised ``rod.strains``:

bending (``bending_law``; EI = EI(s) of the profile and defect below; b = ``nonlinear_stiffness``)
    linear       m = EI dk (1 + b dk^2)             W_b = EI (dk^2 / 2 + b dk^4 / 4)
    exponential  m = EI sinh(beta dk) / beta + EI b dk^3
                 W_b = EI (cosh(beta dk) - 1) / beta^2 + EI b dk^4 / 4
    saturating   m = m_s tanh(EI dk / m_s) + EI b dk^3
                 W_b = (m_s^2 / EI) ln cosh(EI dk / m_s) + EI b dk^4 / 4
stretch (``stretch_law``)
    linear       n_1 = EA e                         W_s = EA e^2 / 2
    cubic        n_1 = EA e (1 + a e^2)             W_s = EA (e^2 / 2 + a e^4 / 4)
Shear stays linear. Every law tends to the linear one as its parameter tends to 0 (beta,
a -> 0; m_s -> infinity).

Profiles along s (fractions s / L0, piecewise linear between knots, evaluated at the segment
midpoints): EI(s) = EI (1 - g s / L0) f(s) D(s) with the graded profile f (``stiffness_profile``)
and the local defect D(s) = 1 + (d - 1) [tanh((s - s_a) / w) - tanh((s - s_b) / w)] / 2;
kappa^0(s) = kappa0 + k(s) (``rest_curvature_profile``). The Kelvin-Voigt bending damping
(config ``rod.material.kelvin_voigt``) is ``RodParams.internal_damping``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

BENDING_LAWS: tuple[str, ...] = ("linear", "exponential", "saturating")
STRETCH_LAWS: tuple[str, ...] = ("linear", "cubic")


def _knots(value: Any, key: str, positive: bool) -> tuple[tuple[float, float], ...]:
    """Validated (s / L0, value) knots: s strictly increasing from 0 to 1 ([] = none)."""
    try:
        pts = tuple((float(a), float(b)) for a, b in value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"rod.material.{key}: expected a list of [s/L0, value] pairs") from exc
    if not pts:
        return pts
    s = np.array([p[0] for p in pts])
    v = np.array([p[1] for p in pts])
    if len(pts) < 2 or s[0] != 0.0 or s[-1] != 1.0 or np.any(np.diff(s) <= 0):
        raise ValueError(f"rod.material.{key}: the s/L0 knots must increase strictly from 0 to 1")
    if not np.all(np.isfinite(v)) or (positive and np.any(v <= 0)):
        raise ValueError(f"rod.material.{key}: values must be finite{' and > 0' if positive else ''}")
    return pts


@dataclass(frozen=True)
class Material:
    """The rod's material laws (config ``rod.material``; the defaults are the linear rod)."""

    bending_law: str = "linear"  # BENDING_LAWS
    bending_beta: float = 0.0  # exponential law's beta [m] (> 0 when used)
    saturation_moment: float = 0.0  # saturating law's m_s [N m] (> 0 when used)
    stretch_law: str = "linear"  # STRETCH_LAWS
    stretch_stiffening: float = 0.0  # cubic stretch law's a [-] (>= 0)
    stiffness_profile: tuple[tuple[float, float], ...] = ()  # (s/L0, EI factor > 0) knots
    rest_curvature_profile: tuple[tuple[float, float], ...] = ()  # (s/L0, kappa [1/m]) knots
    defect_start: float = 0.0  # s_a / L0 [-]
    defect_end: float = 0.0  # s_b / L0 [-]
    defect_factor: float = 1.0  # d: EI factor inside the defect [-] (1 = no defect)
    defect_edge: float = 0.01  # w / L0: width of the smooth edges [-]

    def __post_init__(self) -> None:
        if self.bending_law not in BENDING_LAWS:
            raise ValueError(f"rod.material.bending_law: {self.bending_law!r} is not one of {BENDING_LAWS}")
        if self.stretch_law not in STRETCH_LAWS:
            raise ValueError(f"rod.material.stretch_law: {self.stretch_law!r} is not one of {STRETCH_LAWS}")
        if self.bending_law == "exponential" and not self.bending_beta > 0:
            raise ValueError("rod.material.bending_beta: the exponential law needs beta > 0 [m]")
        if self.bending_law == "saturating" and not self.saturation_moment > 0:
            raise ValueError("rod.material.saturation_moment: the saturating law needs m_s > 0 [N m]")
        for key, law, owner in (("bending_beta", self.bending_law, "exponential"),
                                ("saturation_moment", self.bending_law, "saturating"),
                                ("stretch_stiffening", self.stretch_law, "cubic")):
            if getattr(self, key) != 0.0 and law != owner:
                raise ValueError(f"rod.material.{key}: a parameter of the {owner} law, which is not "
                                 "selected (set it to 0)")
        for key in ("bending_beta", "saturation_moment", "stretch_stiffening", "defect_edge"):
            v = getattr(self, key)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"rod.material.{key}: must be finite and >= 0, got {v!r}")
        if not (math.isfinite(self.defect_factor) and self.defect_factor > 0):
            raise ValueError(f"rod.material.defect_factor: must be finite and > 0, got "
                             f"{self.defect_factor!r}")
        if self.defect_factor != 1.0 and not (0.0 <= self.defect_start < self.defect_end <= 1.0
                                              and self.defect_edge > 0):
            raise ValueError("rod.material.defect_start/defect_end/defect_edge: need "
                             "0 <= start < end <= 1 and edge > 0 for a defect")
        object.__setattr__(self, "stiffness_profile",
                           _knots(self.stiffness_profile, "stiffness_profile", True))
        object.__setattr__(self, "rest_curvature_profile",
                           _knots(self.rest_curvature_profile, "rest_curvature_profile", False))

    @property
    def is_linear(self) -> bool:
        """True for the linear, uniform, straight material (the defaults' physics; the defect's
        position and edge do not matter without a defect)."""
        return not (self.needs_variational or self.stiffness_profile or self.defect_factor != 1.0)

    @property
    def needs_variational(self) -> bool:
        """True when a nonlinear bending or stretch law or a rest-curvature profile is set: the
        collocated schemes do not implement these (EI(s) profiles and the defect they take, as
        segment stiffnesses)."""
        return (self.bending_law != "linear" or self.stretch_law != "linear"
                or bool(self.rest_curvature_profile))

    def law_vector(self) -> np.ndarray:
        """The kernels' law argument [bending id, its parameter, stretch id, its parameter]."""
        bend = {"linear": 0.0, "exponential": self.bending_beta, "saturating": self.saturation_moment}
        return np.array([float(BENDING_LAWS.index(self.bending_law)), bend[self.bending_law],
                         float(STRETCH_LAWS.index(self.stretch_law)), self.stretch_stiffening])

    def ei_factor(self, s_rel: np.ndarray) -> np.ndarray:
        """f(s) D(s) at the relative arc lengths s / L0 (module docstring)."""
        s_rel = np.asarray(s_rel, dtype=float)
        out = np.ones_like(s_rel)
        if self.stiffness_profile:
            k = np.array(self.stiffness_profile)
            out = out * np.interp(s_rel, k[:, 0], k[:, 1])
        if self.defect_factor != 1.0:
            w = self.defect_edge
            win = 0.5 * (np.tanh((s_rel - self.defect_start) / w) - np.tanh((s_rel - self.defect_end) / w))
            out = out * (1.0 + (self.defect_factor - 1.0) * win)
        return out

    def max_ei_factor(self) -> float:
        """Upper bound of ``ei_factor`` over the rod (for the time-step bound)."""
        f = max(p[1] for p in self.stiffness_profile) if self.stiffness_profile else 1.0
        return f * max(1.0, self.defect_factor)

    def rest_curvature(self, s_rel: np.ndarray) -> np.ndarray:
        """k(s) [1/m] at the relative arc lengths s / L0 (0 without a profile)."""
        s_rel = np.asarray(s_rel, dtype=float)
        if not self.rest_curvature_profile:
            return np.zeros_like(s_rel)
        k = np.array(self.rest_curvature_profile)
        return np.interp(s_rel, k[:, 0], k[:, 1])

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        for key in ("stiffness_profile", "rest_curvature_profile"):
            d[key] = [list(p) for p in d[key]]
        return d

    @classmethod
    def from_dict(cls, d: Any) -> Material:
        if isinstance(d, Material):
            return d
        if not isinstance(d, dict):
            raise TypeError(f"rod.material: expected a mapping, got {type(d).__name__}")
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = set(d) - known
        if unknown:
            raise KeyError(f"rod.material: unknown key(s) {sorted(unknown)}; known: {sorted(known)}")
        return cls(**d)


@njit(cache=True)
def _log_cosh(x):
    """ln cosh x, accurate near 0 (ln(1 + sinh^2) / 2) and without overflow for large |x|."""
    a = abs(x)
    if a < 20.0:
        sh = math.sinh(a)
        return 0.5 * math.log1p(sh * sh)
    return a + math.log1p(math.exp(-2.0 * a)) - math.log(2.0)


@njit(cache=True)
def bend_law(law, EI, dk, b):
    """Bending moment m, energy density W_b and tangent dm/d(dk) of the law (module docstring);
    ``law`` = ``Material.law_vector()``, b the cubic coefficient (``nonlinear_stiffness``)."""
    kind = law[0]
    if kind == 0.0:
        return EI * dk * (1.0 + b * dk * dk), EI * (0.5 * dk * dk + 0.25 * b * dk**4), \
            EI * (1.0 + 3.0 * b * dk * dk)
    cub_m = EI * b * dk * dk * dk
    cub_w = 0.25 * EI * b * dk**4
    cub_t = 3.0 * EI * b * dk * dk
    if kind == 1.0:
        beta = law[1]
        x = beta * dk
        sh = math.sinh(0.5 * x)
        return (EI * math.sinh(x) / beta + cub_m, 2.0 * EI * sh * sh / (beta * beta) + cub_w,
                EI * math.cosh(x) + cub_t)
    ms = law[1]
    x = EI * dk / ms
    th = math.tanh(x)
    return ms * th + cub_m, ms * ms / EI * _log_cosh(x) + cub_w, EI * (1.0 - th * th) + cub_t


@njit(cache=True)
def stretch_law(law, EA, e):
    """Axial force n_1, energy density W_s and tangent dn_1/de of the stretch law."""
    if law[2] == 0.0:
        return EA * e, 0.5 * EA * e**2, EA
    a = law[3]
    return EA * e * (1.0 + a * e * e), EA * (0.5 * e * e + 0.25 * a * e**4), EA * (1.0 + 3.0 * a * e * e)


@njit(cache=True)
def _bend_array(law, EI, dk, b, out):
    for i in range(dk.shape[0]):
        out[i] = bend_law(law, EI[i], dk[i], b)[0]


@njit(cache=True)
def _stretch_array(law, EA, e, out):
    for i in range(e.shape[0]):
        out[i] = stretch_law(law, EA, e[i])[0]


def bending_moment(law: np.ndarray, EI: np.ndarray, dk: np.ndarray, b: float) -> np.ndarray:
    """``bend_law``'s moment m for arrays dk (..., N) with EI (N,) broadcast [N m]."""
    dk = np.asarray(dk, dtype=float)
    EIb = np.broadcast_to(EI, dk.shape)
    out = np.empty(dk.size)
    _bend_array(law, np.ascontiguousarray(EIb).ravel(), np.ascontiguousarray(dk).ravel(), float(b), out)
    return out.reshape(dk.shape)


def axial_force(law: np.ndarray, EA: float, e: np.ndarray) -> np.ndarray:
    """``stretch_law``'s n_1 for an array of stretch strains e = nu1 - nu1^0 [N]."""
    e = np.asarray(e, dtype=float)
    out = np.empty(e.size)
    _stretch_array(law, float(EA), np.ascontiguousarray(e).ravel(), out)
    return out.reshape(e.shape)
