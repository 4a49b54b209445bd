"""Describe what the effect library lacks: a learned bending-stiffness profile EI(s) f(s).

When no named effect closes the gap, the part of the constitutive law the data point at is
learned instead of named: the bending stiffness of eq. (5) becomes EI(s) f(s), with
f = exp(u) piecewise linear between ``describe_knots`` equally spaced knots in s / L0 (the
simulator's ``rod.material.stiffness_profile``). The log-factors u get a Gaussian-process
prior (squared-exponential kernel of ``crgpr.gp``, std ``describe_prior_std``, length scale
``describe_length_scale`` in s / L0, mean 0: the nominal law) and are fitted jointly with the
initial-state corrections to theta at the markers over the whole record by damped
Gauss-Newton (the maximum a posteriori estimate; theta errors at the floor's level, the
sample deflated by the residuals' autocorrelation time). The band is that of the Laplace
posterior of u.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.trajectory import TrajectoryFit, TrajectoryFitter
from crgpr.gp import kernel_matrix
from crgpr.physics.params import RodParams


def knot_positions(n_knots: int) -> np.ndarray:
    """Knots of the learned profile in s / L0 (0 to 1, equally spaced)."""
    return np.linspace(0.0, 1.0, n_knots)


def profile_params(params: RodParams, logf: np.ndarray) -> RodParams:
    """``params`` with EI(s) multiplied by f(s), f piecewise linear through exp(logf) at the knots
    (any profile of ``params`` is taken at the knots and multiplied; its defect is kept)."""
    knots = knot_positions(len(logf))
    prof = params.material.stiffness_profile
    f0 = np.interp(knots, *np.array(prof).T) if prof else np.ones(len(knots))
    f = f0 * np.exp(np.asarray(logf, float))
    knots_f = tuple((float(s), float(v)) for s, v in zip(knots, f, strict=True))
    mat = dataclasses.replace(params.material, stiffness_profile=knots_f)
    return params.replace(material=mat)


@dataclass
class ProfileFit:
    """A learned EI(s) factor: log-factors at the knots, their posterior covariance, the fit."""

    knots: np.ndarray  # s / L0
    logf: np.ndarray
    cov: np.ndarray  # posterior covariance of logf
    init: np.ndarray  # initial-state corrections
    q: np.ndarray  # (n_t, N+1, 3) of the fitted model
    rss: float
    n: int
    iterations: int

    @property
    def rmse(self) -> float:
        return math.sqrt(self.rss / self.n)

    def band(self, s_rel: np.ndarray, z: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(f, lower, upper) at s / L0: the factor and its pointwise band of z std in log f."""
        sd = np.sqrt(np.maximum(np.diag(self.cov), 0.0))
        f = np.interp(s_rel, self.knots, np.exp(self.logf))
        lo = np.interp(s_rel, self.knots, np.exp(self.logf - z * sd))
        hi = np.interp(s_rel, self.knots, np.exp(self.logf + z * sd))
        return f, lo, hi


def _simulate(fitter: TrajectoryFitter, base: TrajectoryFit, logf: np.ndarray, c: np.ndarray,
              tangent: bool) -> tuple[np.ndarray, np.ndarray | None] | None:
    """Theta residual at the markers of the model ``base`` with profile ``logf`` from
    corrections ``c``, and (``tangent``) its exact Jacobian in c; None if it diverges."""
    g = fitter.on_grid(profile_params(fitter.params, logf), fitter.theta, fitter.omega, fitter.dt_max)
    if tangent:
        return g._init_jacobian(base.names, base.coef, c, fitter.n)
    r = g._resid(base.names, base.coef, c, fitter.n)
    return (r, None) if np.all(np.abs(r) < 10.0) else None


def fit_profile(fitter: TrajectoryFitter, base: TrajectoryFit, sigma: float, n_knots: int,
                prior_std: float, length_scale: float, iterations: int, probe: float = 1e-3) -> ProfileFit:
    """MAP fit of the log-factors of EI(s) (and the initial-state corrections) to the record.

    ``base`` is the model the profile multiplies (its effects fixed, its corrections the start);
    ``sigma`` [rad] the std of a theta error (with the autocorrelation deflation applied)."""
    knots = knot_positions(n_knots)
    K = kernel_matrix("se", knots[:, None], knots[:, None], prior_std, np.array([length_scale]))
    P = np.linalg.inv(K + 1e-8 * prior_std**2 * np.eye(n_knots))  # prior precision
    x = np.concatenate([np.zeros(n_knots), base.init])
    w = 1.0 / sigma**2

    def objective(r: np.ndarray, u: np.ndarray) -> float:
        return float(w * (r @ r) + u @ P @ u)

    out = _simulate(fitter, base, x[:n_knots], x[n_knots:], True)
    if out is None:
        raise ValueError("the nominal model diverges")
    r, Jc = out
    phi = objective(r, x[:n_knots])
    mu = 1e-3
    done = 0
    for it in range(1, iterations + 1):
        done = it
        Jk = np.empty((r.size, n_knots))
        for i in range(n_knots):
            u = x[:n_knots].copy()
            u[i] += probe
            ri = _simulate(fitter, base, u, x[n_knots:], False)
            Jk[:, i] = 0.0 if ri is None else (ri[0] - r) / probe
        J = np.concatenate([Jk, Jc], axis=1)
        Pf = np.zeros((x.size, x.size))
        Pf[:n_knots, :n_knots] = P
        H = w * (J.T @ J) + Pf
        g = w * (J.T @ r) + Pf @ x
        improved = False
        while mu < 1e6:
            step = -np.linalg.solve(H + mu * np.diag(np.diag(H) + 1e-12), g)
            x_new = x + step
            x_new[:n_knots] = np.clip(x_new[:n_knots], -3.0, 3.0)
            trial = _simulate(fitter, base, x_new[:n_knots], x_new[n_knots:], True)
            if trial is not None and objective(trial[0], x_new[:n_knots]) < phi:
                x, (r, Jc) = x_new, trial
                phi_old, phi = phi, objective(r, x[:n_knots])
                mu = max(mu / 3.0, 1e-6)
                improved = True
                break
            mu *= 10.0
        if not improved or phi_old - phi < 1e-6 * phi_old:
            break
    cov = np.linalg.pinv(H)[:n_knots, :n_knots]
    g = fitter.on_grid(profile_params(fitter.params, x[:n_knots]), fitter.theta, fitter.omega, fitter.dt_max)
    q = g.simulate(base.names, base.coef, x[n_knots:])
    return ProfileFit(knots, x[:n_knots].copy(), cov, x[n_knots:].copy(), q, float(r @ r), r.size, done)


def describe_region(pf: ProfileFit, L0: float, z: float, n_eval: int = 201) -> dict[str, Any] | None:
    """Where the band of f excludes 1, the contiguous region with the largest |log f|: its ends
    [m], the factor at its extreme and the band there, and its extra compliance
    int (1/f - 1) ds [m] with the band's; None if the band contains 1 everywhere."""
    s = np.linspace(0.0, 1.0, n_eval)
    f, lo, hi = pf.band(s, z)
    off = (hi < 1.0) | (lo > 1.0)
    if not off.any():
        return None
    best = None
    i = 0
    while i < n_eval:
        if not off[i]:
            i += 1
            continue
        j = i
        while j + 1 < n_eval and off[j + 1] and (hi[j + 1] < 1.0) == (hi[i] < 1.0):
            j += 1
        k = i + int(np.argmax(np.abs(np.log(f[i:j + 1]))))
        if best is None or abs(math.log(f[k])) > abs(math.log(f[best[2]])):
            best = (i, j, k)
        i = j + 1
    i, j, k = best
    # the extra compliance of the region, int (1/f - 1) ds [m]: what a narrow change of EI does
    # to the rod's bending (its depth and width trade off; their product is what the data fix)
    seg = slice(i, j + 1)
    comp = [float(np.trapezoid(1.0 / v[seg] - 1.0, s[seg] * L0)) if j > i else 0.0 for v in (f, hi, lo)]
    return {"quantity": "bending stiffness EI(s)", "direction": "softer" if f[k] < 1.0 else "stiffer",
            "s_from_m": float(s[i] * L0), "s_to_m": float(s[j] * L0), "s_extreme_m": float(s[k] * L0),
            "factor": float(f[k]), "band": [float(lo[k]), float(hi[k])],
            "extra_compliance_m": comp[0], "extra_compliance_band_m": comp[1:]}


def describe(fitter: TrajectoryFitter, base: TrajectoryFit, floor: float, tau: float, gap_before: float,
             excess: float, st: DiscoverySettings, rivals: tuple[tuple[list[str], float], ...] = ()
             ) -> dict[str, Any]:
    """The learned EI(s) law of a record no named effect explains, and whether it describes the
    gap (``accepted``): its trajectory BIC gain >= ``bic_min_improvement`` (sample deflated by
    ``tau``, one parameter per knot) over the nominal model and over every library model tried
    (``rivals``: effect names and theta RMSE of their trajectory fits; a library effect that
    fits nearly as well with fewer parameters was rejected for its own reasons, and the learned
    law must not stand in for it: a 9-knot stiffness profile can mimic a tip mass), its band
    excludes the nominal law somewhere, it closes at least ``min_explained`` of the excess over
    the floor and leaves at most ``max(min_gap_rad, max_remaining * excess)`` (these but the
    library test: ``closes_the_gap``)."""
    sigma = max(floor, 1e-6) * math.sqrt(max(tau, 1.0))
    pf = fit_profile(fitter, base, sigma, st.describe_knots, st.describe_prior_std, st.describe_length_scale,
                     st.describe_iterations)
    L0 = fitter.params.L0
    region = describe_region(pf, L0, st.describe_band_z)
    n_eff = pf.n / max(tau, 1.0)
    dbic = n_eff * math.log(max(base.rss, 1e-300) / max(pf.rss, 1e-300)) - len(pf.logf) * math.log(n_eff)
    k = len(pf.logf)
    rival_bic = [{"effects": list(names), "rmse": rmse,
                  "delta_bic": n_eff * math.log(max(rmse**2, 1e-300) / max(pf.rss / pf.n, 1e-300))
                  - (k - len(names)) * math.log(n_eff)} for names, rmse in rivals]
    closest = min(rival_bic, key=lambda r: r["delta_bic"]) if rival_bic else None
    remaining = math.sqrt(max(pf.rmse**2 - floor**2, 0.0))
    closed = 1.0 - remaining / excess if excess > 0 else 0.0
    beats_library = closest is None or closest["delta_bic"] >= st.bic_min_improvement
    fits = bool(region is not None and dbic >= st.bic_min_improvement and closed >= st.min_explained
                and remaining <= max(st.min_gap_rad, st.max_remaining * excess))
    accepted = fits and beats_library
    s = np.linspace(0.0, 1.0, 101)
    f, lo, hi = pf.band(s, st.describe_band_z)
    sentence = None
    if region is not None:
        sentence = (f"the bending stiffness is {region['factor']:.2g}x nominal between s = "
                    f"{region['s_from_m']:.2f} and {region['s_to_m']:.2f} m (extreme at "
                    f"{region['s_extreme_m']:.2f} m; {st.describe_band_z:g}-std band "
                    f"{region['band'][0]:.2g}-{region['band'][1]:.2g}x); gap {gap_before:.4f} -> "
                    f"{pf.rmse:.4f} rad (floor {floor:.4f})")
    return {"accepted": accepted, "closes_the_gap": fits, "law": "EI(s) f(s), f piecewise linear in s / L0",
            "knots_s_m": (pf.knots * L0).tolist(), "factor_at_knots": np.exp(pf.logf).tolist(),
            "log_factor_std": np.sqrt(np.maximum(np.diag(pf.cov), 0.0)).tolist(),
            "band_z": st.describe_band_z, "curve": {"s_m": (s * L0).tolist(), "factor": f.tolist(),
                                                    "lower": lo.tolist(), "upper": hi.tolist()},
            "region": region, "summary": sentence, "gap_after": pf.rmse, "remaining_excess": remaining,
            "explained_excess_fraction": closed, "trajectory_delta_bic": dbic,
            "closest_library_model": closest, "beats_library": beats_library,
            "iterations": pf.iterations, "_q": pf.q}
