"""Grey-box CR-GPR: constitutive laws taken from the nominal rod instead of learned.

Camera positions resolve bending but not always stretch and shear: at 1 mm noise on 2 cm
segments the axial strain nu1 - 1 (~1e-3) and the shear nu2 (~5e-3) are far below the strain
noise of one segment, sqrt(2) sigma / ds (~0.07), so GPs of n1 and n2 learn noise and the
learned rod does not hold together. A grey-box model keeps the learned bending moment m and
takes the unresolvable laws from the nominal rod (the config's ``rod``, the constitutive law of
the simulator's eq. (4) discretisation, physics/rod.py):

    n1 = EA (nu1 - nu1_0),   n2 = GA (nu2 - nu2_0)

``NominalLaw`` is one more implementation of the component protocol of
``learning.learned.LearnedRod`` (a callable on the objective feature rows [nu1, nu2, kappa]),
so the learned rod, its rollouts and its energy are unchanged.

Which laws: a fixed list (config ``camera.learn.nominal_laws``: a subset of [n1, n2, m]) or
``auto``: a law is taken from the nominal rod when the data do not support learning it, i.e.

* (n1, n2) when its strain is not resolvable by the positions: the strain signal-to-noise
  ratio ``strain_snr`` is below ``camera.learn.snr_min`` (below); or
* (n1, n2, m and the momentum maps H_p(p)) when a learned law does not predict held-out
  contiguous time blocks of its own samples consistently better than the nominal law
  (``learning.law_choice.learned_or_nominal``: fitted on one trajectory, a law the record
  cannot tell from the nominal one only adds the record's systematic errors, and they mislead
  rollouts from other states; a learned momentum map is also tabulated over the record's
  momenta only, 0 beyond them, where rollouts from larger angles go).

The strain SNR:

    signal = rms(n_k) / (stiffness_k)           the strain the measured resultants n_k (from
                                                the force balance, eq. (13)) imply on the
                                                nominal rod (n1 / EA, n2 / GA; m / EI for kappa)
    noise  = sqrt(2) sigma / ds                 one segment's strain noise from positions with
                                                noise sigma (nu1, nu2); 2 sigma / ds^2 (kappa)

with sigma estimated from the raw positions (``position_noise_std``: fourth differences in time,
robust scale), so the decision does not depend on the prefilter.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from crgpr.gp.evaluators import KernelMean, interp_uniform, law_grid
from crgpr.physics.params import RodParams

NOMINAL_LAWS: dict[str, str] = {"n1": "obj_n1", "n2": "obj_n2", "m": "obj_m",  # law -> component
                                 "p_x": "dH_dp_x", "p_y": "dH_dp_y", "p_theta": "dH_dp_theta"}
MOMENTUM_LAWS = ("p_x", "p_y", "p_theta")  # H_p = p / (rho A), p / (rho I): the velocity maps


class NominalLaw:
    """Component ``obj_n1`` / ``obj_n2`` / ``obj_m`` of the nominal rod: n1 = EA (nu1 - nu1_0),
    n2 = GA (nu2 - nu2_0) at objective n feature rows X (..., 3) = [nu1, nu2, kappa], or
    m = EI (kappa - kappa0) at objective m feature rows (..., 5) = [kappa, ...] (eq. (10)); or a
    momentum map ``dH_dp_*`` of eq. (9): H_p = p / (rho A) (p_x, p_y), p / (rho I) (p_theta) at
    momenta per length (...), with its ``slope`` (the 1-D components' convention)."""

    def __init__(self, law: str, params: RodParams):
        if law not in NOMINAL_LAWS:
            raise ValueError(f"unknown nominal law {law!r}; expected one of {sorted(NOMINAL_LAWS)}")
        self.law = law
        self.name = NOMINAL_LAWS[law]
        if law == "n1":
            self.col, self.stiffness, self.ref = 0, float(params.EA), float(params.nu1_0)
        elif law == "n2":
            self.col, self.stiffness, self.ref = 1, float(params.GA), float(params.nu2_0)
        elif law == "m":
            self.col, self.stiffness, self.ref = 0, float(params.EI), float(params.kappa0)
        else:
            self.col, self.ref = None, 0.0
            self.stiffness = 1.0 / float(params.rhoI if law == "p_theta" else params.rhoA)
        self.meta: dict[str, Any] = {"name": self.name, "kind": "nominal", "law": law,
                                     "stiffness": self.stiffness, "reference_strain": self.ref}

    def __call__(self, X: np.ndarray) -> np.ndarray:
        if self.col is None:
            return self.stiffness * np.asarray(X, dtype=float)
        x = np.asarray(X)[..., self.col]
        return self.stiffness * (x - self.ref if self.ref else x)

    def slope(self, X: np.ndarray) -> np.ndarray:
        """dH_p/dp of a momentum map (constant)."""
        return np.full(np.shape(X), self.stiffness)


class SelectedInputs:
    """A component fitted on some columns of its feature rows (``feature_columns`` of the model's
    JSON): the grey-box bending law m(kappa) evaluated on the objective m features. One column:
    the 1-D components' convention (values (...), like the momentum maps H_p(p)); several:
    rows (..., k). ``arclength`` (N,): the segments' s, appended as the last input (a law that
    varies along the rod, ``arclength_input`` of the model's JSON); the rows are then (..., N, k).

    A law of (kappa, s) whose component is a posterior mean (``crgpr.gp.KernelMean``) is
    evaluated from one table per segment: m(kappa, s_j) on the grid of the 1-D laws
    (``law_grid``, linear interpolation), the kernel sum itself only where kappa leaves the
    grid. The rollout's s are fixed, so this is the 1-D laws' tabulation slice by slice; the
    posterior samples (UQ) are evaluated as they are."""

    def __init__(self, component: Any, columns: list[int], arclength: np.ndarray | None = None):
        self.component = component
        self.columns = list(columns)
        self.arclength = None if arclength is None else np.asarray(arclength, dtype=float)
        self.meta = getattr(component, "meta", {})
        self._tables = None
        if (self.arclength is not None and len(self.columns) == 1 and isinstance(component, KernelMean)
                and component.dim == 2):
            self._tables = SliceTables(component, self.arclength)

    def rewrap(self, component: Any) -> SelectedInputs:
        """The same input selection around another component (its posterior samples)."""
        return SelectedInputs(component, self.columns, self.arclength)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X)
        if self._tables is not None:
            return self._tables(X[..., self.columns[0]])
        if self.arclength is not None:
            s = np.broadcast_to(self.arclength[:, None], (*X.shape[:-1], 1))
            return self.component(np.concatenate([X[..., self.columns], s], axis=-1))
        if len(self.columns) == 1:
            return self.component(X[..., self.columns[0]])
        return self.component(X[..., self.columns])


class SliceTables:
    """A 2-D mean f(x, s) at fixed slices s_j, tabulated along x (``law_grid`` of its training
    inputs' first column; linear interpolation): ``self(x)`` with x (..., J) gives
    f(x[..., j], s_j); rows off the grid are evaluated by the mean itself."""

    def __init__(self, mean: Any, slices: np.ndarray):
        self.mean, self.slices = mean, np.asarray(slices, dtype=float)
        x_train = mean.Z[:, 0] * mean.x_scale[0] + mean.x_mean[0]
        self.grid = law_grid(x_train, float(mean.ell[0] * mean.x_scale[0]))
        G, J = self.grid.size, self.slices.size
        rows = np.stack([np.broadcast_to(self.grid, (J, G)),
                         np.broadcast_to(self.slices[:, None], (J, G))], -1)
        self.values = np.ascontiguousarray(mean(rows))  # (J, G)
        self.h = float((self.grid[-1] - self.grid[0]) / (G - 1))

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        J = self.slices.size
        if x.shape[-1] != J:
            raise ValueError(f"expected values at the {J} slices along the last axis, got {x.shape}")
        rows = np.ascontiguousarray(x.reshape(-1, J).T)  # (J, rows): slice by slice
        out = np.empty_like(rows)
        interp_uniform(rows, self.grid[0], self.h, self.values, False, out)
        out = out.T.reshape(x.shape)
        if x.size and (x.min() < self.grid[0] or x.max() > self.grid[-1]):
            off = (x < self.grid[0]) | (x > self.grid[-1])
            s = np.broadcast_to(self.slices, x.shape)
            out[off] = self.mean(np.stack([x[off], s[off]], -1))
        return out


def position_noise_std(x: np.ndarray) -> float:
    """Noise std [m] of positions x (n_t, ...) sampled at a fixed rate: fourth differences in time
    (white noise: variance 70 sigma^2; a smooth motion adds h^4 x'''' only), robust scale
    (median absolute value / 0.6745)."""
    if x.shape[0] < 5:
        return math.nan
    d4 = x[4:] - 4 * x[3:-1] + 6 * x[2:-2] - 4 * x[1:-3] + x[:-4]
    d4 = d4[np.isfinite(d4)]
    if d4.size == 0:
        return math.nan
    return float(np.median(np.abs(d4)) / 0.6745 / math.sqrt(70.0))


def strain_snr(resultants: dict[str, np.ndarray], params: RodParams, sigma_m: float) -> dict[str, dict]:
    """Signal-to-noise of each strain (see module docstring); ``resultants``: the training
    targets n1, n2, m (any shape)."""
    ds = params.ds
    noise = {"n1": math.sqrt(2.0) * sigma_m / ds, "n2": math.sqrt(2.0) * sigma_m / ds,
             "m": 2.0 * sigma_m / ds**2}
    stiff = {"n1": params.EA, "n2": params.GA, "m": params.EI}
    out = {}
    for k, v in resultants.items():
        sig = float(np.sqrt(np.mean(np.square(v)))) / float(stiff[k])
        out[k] = {"strain": {"n1": "nu1 - nu1_0", "n2": "nu2 - nu2_0", "m": "kappa"}[k],
                  "signal_rms": sig, "noise_rms": noise[k],
                  "snr": math.inf if noise[k] == 0 else sig / noise[k]}
    return out


def segment_curvature_snr(m: np.ndarray, EI: float, kappa_noise: np.ndarray) -> np.ndarray:
    """Curvature signal-to-noise of each segment (N,): rms over frames of the bending targets m
    (n_t, N) (from the force balance, eq. (13), so independent of the curvature reconstruction)
    over EI, divided by that segment's reconstructed-curvature noise sd
    (``measured.kinematics.clamped_angle_fit``; NaN = unknown, kept). Below
    ``camera.learn.snr_min`` a segment's curvature input is mostly noise: kept in a regression
    of m on it, it would flatten the learned law where the data crowd (errors in variables:
    E[kappa | kappa_est] shrinks)."""
    sig = np.sqrt(np.mean(np.square(m), axis=0)) / float(EI)
    noise = np.asarray(kappa_noise, dtype=float)
    known = np.isfinite(noise) & (noise > 0)  # an unknown (NaN) or zero noise: the segment is kept
    return np.where(known, sig / np.where(known, noise, 1.0), np.inf)


def choose_nominal(setting: str | list[str], snr: dict[str, dict], snr_min: float,
                   heldout: dict[str, dict] | None = None) -> list[str]:
    """Laws taken from the nominal rod: the configured list, or with ``auto`` those of n1, n2
    whose strain SNR is below ``snr_min``, and those of n1, n2, m whose learned stand-in does not
    predict held-out time blocks consistently better than the nominal law (``heldout``: law ->
    ``law_choice.HeldoutChoice.to_dict()``, key ``richer``; a law absent from it is learned
    where its SNR allows; m and the momentum maps are never dropped for an SNR)."""
    if setting == "auto":
        heldout = heldout or {}
        low = {k for k in ("n1", "n2") if not snr[k]["snr"] >= snr_min}
        return [k for k in NOMINAL_LAWS if k in low or (k in heldout and not heldout[k]["richer"])]
    bad = [k for k in setting if k not in NOMINAL_LAWS]
    if bad:
        raise ValueError(f"camera.learn.nominal_laws: unknown law(s) {bad}; expected 'auto' or a "
                         f"subset of {sorted(NOMINAL_LAWS)}")
    return [k for k in NOMINAL_LAWS if k in setting]


class NominalContinuation:
    """A learned stretch or shear law (component ``obj_n1`` / ``obj_n2``, rows (..., 3) =
    [nu1, nu2, kappa]) continued by the nominal law beyond the inputs its record covered:

        n(x) = n_learned(clip(x)) + nominal(x) - nominal(clip(x)),

    clip(x) the nearest point of the covered box [lo_j, hi_j] (the manifest's
    ``law_inputs_covered``). Inside the box the learned law is unchanged; beyond it the law
    keeps its value at the edge and takes the nominal stiffness EA (GA) for the rest, and
    nothing of the GP's reversion to its basis trend, which one record fitted over its own
    strains. A law fitted on one trajectory falls back towards the nominal one where the data
    did not reach (a release from a larger angle stretches the rod further than the record
    did). A wrapper like ``extrapolation.TangentContinuation`` (``rewrap``)."""

    def __init__(self, component: Any, law: str, params: RodParams, lo: np.ndarray, hi: np.ndarray):
        if law not in ("n1", "n2"):
            raise ValueError(f"nominal continuation of {law!r}: only n1, n2")
        self.component, self.law, self.params = component, law, params
        self.nominal = NominalLaw(law, params)
        self.lo, self.hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
        self.meta = getattr(component, "meta", {})

    def rewrap(self, component: Any) -> NominalContinuation:
        """The same continuation of another component (e.g. the law's posterior samples)."""
        return NominalContinuation(component, self.law, self.params, self.lo, self.hi)

    def __call__(self, X: np.ndarray) -> np.ndarray:
        X = np.asarray(X, dtype=float)
        inside = (X >= self.lo) & (X <= self.hi)
        if inside.all():
            return self.component(X)  # inside the covered box (every step of a record-like rollout)
        Xc = np.clip(X, self.lo, self.hi)
        return self.component(Xc) + self.nominal(X) - self.nominal(Xc)
