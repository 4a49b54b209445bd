"""Trajectory-level uncertainty of CR-GPR (paper Sec. III "Uncertainty Quantification via RFF
Sampling" and Sec. V "Uncertainty Quantification Results", Fig. combined_shapes right).

Stages (rules in workflow/rules/uq.smk):

``uq_samples``   For every SE / ARD-SE gradient GP of the UQ method (paper Table II: q_x, q_y,
                 dH/dtheta, dH/dp_x, dH/dp_y, dH/dp_theta) draw S joint posterior function
                 samples (``crgpr.gp.sampling``: sparse pathwise conditioning on M inducing inputs, or
                 exact pathwise conditioning compressed onto them), basis coefficients
                 included, and write them as plain arrays to
                 ``results/uq/samples/{model}.npz``; the sampling-approximation errors are
                 measured against the exact GP posterior and written to
                 ``results/uq/samples/diagnostics.json``.
``uq_rollout``   Per test angle, the S sampled H_z are integrated through the same Stormer-
                 Verlet rollout as the CR-GPR mean model (dt = simulation.dt_s), all S samples
                 as one batch (the state carries a sample axis; the sampled functions are
                 evaluated for all samples in one compiled call per model and step). Writes
                 ``results/uq/{angle}.parquet``: one row per (sample, t, node), the state columns
                 of the ground truth plus ``sample``.
``uq_coverage``  Per angle: the 2.5-97.5 % percentile band over the S samples at every (t, node)
                 and the fraction of ground-truth theta values inside it (``theta_coverage``;
                 the clamped base node and t = 0, identical in every run, are excluded), the
                 tip-position coverage (x and y of the tip both inside their bands,
                 ``tip_coverage``), band widths and RMSE of the band centre.
                 ``results/uq/coverage.parquet`` and ``results/tables/uq_coverage.csv``.
``uq_calibration`` Function-level check of each gradient GP at the ground-truth states of the
                 test angles: z = (analytic target - rollout mean) / posterior sd and the
                 fraction with |z| < 1.96 (``results/tables/uq_function_calibration.csv``).
                 A trajectory band can only cover the truth if the functions' bands do.
``uq_figure``    Rod configurations at four time instants with the 95 % band shaded and the
                 ground truth dashed (``results/figures/uq_band_{angle}.png``).

A note on S = 10 (the paper's value). The 2.5 / 97.5 % percentiles of 10 samples (linear
interpolation) lie just inside the sample minimum and maximum. If the ground truth were an
eleventh draw from the same distribution, it would fall inside the sample range with
probability 9 / 11 = 0.82, so even a perfectly calibrated model cannot reach 0.95 coverage with
S = 10 (0.79 with the interpolated 2.5 / 97.5 % percentiles); ``expected_coverage_calibrated``
gives this reference for the band and S used. We report
this reference next to the measured coverage instead of widening the band.
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numba import njit

from crgpr.gp import GP
from crgpr.gp.sampling import (
    CompressedSamples,
    exact_posterior,
    inducing_indices,
    pathwise_samples,
    sparse_posterior,
)
from crgpr.gp.sampling import compress as compress_samples
from crgpr.io import read_parquet, write_csv, write_json, write_npz, write_parquet
from crgpr.learning import features as ft
from crgpr.physics.rod import free_mask, node_weights, straight_rod
from crgpr.physics.simulate import TRAJECTORY_COLUMNS

log = logging.getLogger(__name__)

SAMPLERS = ("sparse_pathwise", "exact_pathwise")
UQ_COLUMNS: tuple[str, ...] = ("sample", *TRAJECTORY_COLUMNS)
COVERAGE_COLUMNS: tuple[str, ...] = (
    "theta0_deg", "n_samples", "n_diverged", "band_lo_pct", "band_hi_pct",
    "theta_coverage", "tip_coverage", "tip_x_coverage", "tip_y_coverage",
    "expected_coverage_calibrated", "theta_band_width_mean", "tip_band_width_mean",
    "theta_rmse_median", "theta_rmse_mean_model", "theta_abs_err_over_halfwidth_median",
)


@dataclass(frozen=True)
class UQSettings:
    """Section ``uq`` of config.yaml (see its schema for units and ranges)."""

    method: str
    sampler: str
    n_samples: int
    n_features: int
    inducing: int
    band_pct: tuple[float, float]
    angles_deg: tuple[int, ...]
    figure_angle_deg: int
    figure_time_fractions: tuple[float, ...]
    exact_check_max_n: int
    check_points: int

    @classmethod
    def from_config(cls, cfg: dict[str, Any]) -> UQSettings:
        u = cfg["uq"]
        s = cls(method=u["method"], sampler=u["sampler"], n_samples=int(u["n_samples"]),
                n_features=int(u["n_features"]), inducing=int(u["inducing"]),
                band_pct=(float(u["band_percentiles"][0]), float(u["band_percentiles"][1])),
                angles_deg=tuple(int(a) for a in u["angles_deg"]),
                figure_angle_deg=int(u["figure_angle_deg"]),
                figure_time_fractions=tuple(float(f) for f in u["figure_time_fractions"]),
                exact_check_max_n=int(u["exact_check_max_n"]), check_points=int(u["check_points"]))
        if s.sampler not in SAMPLERS:
            raise ValueError(f"config key uq.sampler: {s.sampler!r} is not one of {SAMPLERS}")
        if not s.band_pct[0] < s.band_pct[1]:
            raise ValueError("config key uq.band_percentiles: need lower < upper")
        return s


@dataclass
class TabulatedSamples:
    """S samples of a 1D GP tabulated on a grid (linear interpolation, constant beyond the
    ends), the same representation the CR-GPR rollout uses for the momentum models' mean
    (gradient_models.py): ``grid`` (G,), ``values`` (S, G) in output units."""

    grid: np.ndarray
    values: np.ndarray

    @property
    def n_samples(self) -> int:
        return self.values.shape[0]

    def to_arrays(self) -> dict[str, np.ndarray]:
        return {"kind": np.array("tabulated"), "grid": self.grid, "values": self.values}

    def __post_init__(self) -> None:
        self.grid = np.ascontiguousarray(self.grid, dtype=float)
        self.values = np.ascontiguousarray(self.values, dtype=float)
        dg = np.diff(self.grid)
        if not np.allclose(dg, dg[0], rtol=1e-9, atol=0.0) or dg[0] <= 0:
            raise ValueError("TabulatedSamples: the grid must be uniform and increasing")

    def _eval(self, x: np.ndarray, slope: bool) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        x = x[..., 0] if (x.ndim >= 3 and x.shape[-1] == 1) else x
        if x.shape[0] != self.n_samples:
            raise ValueError(f"expected inputs with S = {self.n_samples} rows first, got {x.shape}")
        flat = np.ascontiguousarray(x.reshape(self.n_samples, -1))
        out = np.empty_like(flat)
        _interp_uniform(flat, self.grid[0], self.grid[1] - self.grid[0], self.values, slope, out)
        return out.reshape(x.shape)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Sample s at x[s]: x (S, ...) or (S, ..., 1) -> (S, ...); 0 (the prior mean) outside
        the grid, as the CR-GPR rollout's tables (crgpr.gp.Table1D)."""
        return self._eval(x, False)

    def slope(self, x: np.ndarray) -> np.ndarray:
        """Slope of each sample's interpolant at x[s] (0 outside), for the damping flow."""
        return self._eval(x, True)


@njit(cache=True)
def _interp_uniform(x, g0, dg, values, slope, out):
    S, m = x.shape
    G = values.shape[1]
    for s in range(S):
        for i in range(m):
            r = (x[s, i] - g0) / dg
            if not (r >= 0.0 and r <= G - 1):
                out[s, i] = 0.0
                continue
            j = min(int(r), G - 2)
            f = r - j
            if slope:
                out[s, i] = (values[s, j + 1] - values[s, j]) / dg
            else:
                out[s, i] = values[s, j] + f * (values[s, j + 1] - values[s, j])


def samples_from_arrays(arr: dict[str, np.ndarray]) -> CompressedSamples | TabulatedSamples:
    if "kind" in arr and str(arr["kind"]) == "tabulated":
        return TabulatedSamples(arr["grid"], arr["values"])
    return CompressedSamples.from_arrays(arr)


def uq_seed(cfg: dict[str, Any], model_index: int) -> int:
    """Seed of the samples of one gradient model, derived from the global ``seed``."""
    return int(np.random.SeedSequence([int(cfg["seed"]), 5, model_index]).generate_state(1)[0])


# ----------------------------------------------------------------------------------------
# stage 1: samples of every gradient GP


def load_gp_spec(stem: str | Path, name: str) -> tuple[GP, np.ndarray | None, np.ndarray | None]:
    """Read a ``crgpr.gp.GP.save`` model (stem.npz + stem.json) into a GP without the
    O(n^3) factorisation ``GP.load`` performs; also return the standardised inducing inputs
    ``dtc_Z`` of the rollout's DTC mean and the 1D table grid ``table_x`` (gradient_models.py)
    when the file has them."""
    stem = Path(stem)
    npz, js = stem.with_suffix(".npz"), stem.with_suffix(".json")
    for p in (npz, js):
        if not p.exists():
            raise FileNotFoundError(f"{p}: gradient model file missing (run the gradient_models rule)")
    meta = json.loads(js.read_text())
    if meta.get("kernel") != "se":
        raise ValueError(f"{js}: kernel {meta.get('kernel')!r}; RFF sampling needs SE / ARD-SE")
    with np.load(npz, allow_pickle=False) as a:
        arr = {k: a[k] for k in a.files}
    X = np.asarray(arr["X"], dtype=float)
    X = X[:, None] if X.ndim == 1 else X
    Y = np.asarray(arr["Y"], dtype=float)
    if Y.ndim == 2 and Y.shape[1] != 1:
        raise ValueError(f"{npz}: {Y.shape[1]} output columns; expected a single-output GP")
    y_mean = float(np.ravel(arr["y_mean"])[0])
    y_scale = float(np.ravel(arr["y_scale"])[0])
    x_mean, x_scale = np.ravel(arr["x_mean"]), np.ravel(arr["x_scale"])
    spec = GP.from_standardised(
        (X - x_mean) / x_scale, (Y.ravel() - y_mean) / y_scale, float(meta["sigma_f_std"]),
        np.broadcast_to(np.ravel(arr["lengthscales"]), (X.shape[1],)), float(meta["sigma_n_std"]),
        str(meta["basis"]), x_mean, x_scale, y_mean, y_scale, name)
    Z = arr.get("dtc_Z")
    Z = None if Z is None else np.atleast_2d(np.asarray(Z, dtype=float))
    grid = arr.get("table_x")
    spec.rollout_arrays = {k: arr[k] for k in ("dtc_Z", "dtc_w", "dtc_beta") if k in arr}
    return spec, Z, (None if grid is None else np.ravel(grid).astype(float))


def _subset(spec: GP, idx: np.ndarray) -> GP:
    return GP.from_standardised(spec.Xs[idx], spec.y[idx], spec.sigma_f, spec.ell, spec.sigma_n, spec.basis,
                                spec.x_mean, spec.x_std, spec.out_mean, spec.out_scale, spec.name)


def draw_model_samples(spec: GP, settings: UQSettings, seed: int, Z: np.ndarray | None = None,
                       grid: np.ndarray | None = None
                       ) -> tuple[CompressedSamples | TabulatedSamples, dict[str, Any]]:
    """S compressed joint samples of one GP plus diagnostics.

    Inducing inputs: ``Z`` (standardised) if given, i.e. the rollout's own DTC inducing set, so
    that the samples are centred on exactly the mean model the CR-GPR rollout integrates; else
    M = uq.inducing by crgpr.gp.select_inducing. Diagnostics: the sampler's mean and sd against the
    exact GP posterior at ``check_points`` training inputs; for n > exact_check_max_n both are
    conditioned on a random subset of exact_check_max_n points (as gradient_models.py does).

    1D models (the momentum GPs, n ~ 1000) with a ``grid``: exact pathwise samples tabulated on
    the grid (the rollout's own representation of their mean); the diagnostics then measure
    the interpolation error of the tabulated samples against the exact samples.
    """
    if spec.dim == 1 and grid is not None:
        return _tabulated_samples(spec, settings, seed, grid)
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    n = spec.Xs.shape[0]
    if Z is None:
        idx = inducing_indices(spec, settings.inducing, seed)
        Z, z_src = spec.Xs[idx], "farthest points (crgpr.gp.select_inducing)"
    else:
        idx, z_src = None, "the rollout model's DTC inducing inputs (dtc_Z)"
    info: dict[str, Any] = {"model": spec.name, "n": int(n), "dim": spec.dim, "basis": spec.basis,
                            "inducing": int(Z.shape[0]), "inducing_source": z_src,
                            "sampler": settings.sampler, "n_features": settings.n_features,
                            "n_samples": settings.n_samples, "seed": seed}
    ra = getattr(spec, "rollout_arrays", {})
    if settings.sampler == "sparse_pathwise":
        sp = sparse_posterior(spec, Z)
        comp = sp.sample(settings.n_samples, settings.n_features, rng)
        if "dtc_w" in ra:
            # centre the samples exactly on the rollout's mean model: its DTC coefficients plus
            # the zero-mean posterior deviations (the two DTC solutions agree near the data but
            # differ far from it, where K_ZZ's ill-conditioned directions and the basis
            # extrapolation dominate; see diagnostics centre_vs_rollout_*)
            beta_bar, a_bar = sp.mean_coefficients()
            comp.a = comp.a - a_bar + np.ravel(ra["dtc_w"])
            comp.beta = comp.beta - beta_bar + np.ravel(ra["dtc_beta"])
            comp.__post_init__()
            info["centred_on"] = "the rollout's DTC mean (dtc_w, dtc_beta)"
    else:
        if idx is None:  # compression needs training-point indices: match Z to rows of X
            idx = np.array([int(np.argmin(((spec.Xs - z) ** 2).sum(1))) for z in Z])
        smp = pathwise_samples(exact_posterior(spec), settings.n_samples, settings.n_features, rng)
        comp = compress_samples(smp, idx)
    info["sampling_s"] = time.perf_counter() - t0
    if settings.sampler == "sparse_pathwise" and "dtc_w" in ra:
        # our DTC posterior mean against the mean model the CR-GPR rollout integrates
        from crgpr.gp.sampling import se_kernel

        xc = spec.Xs[np.random.default_rng(seed + 2).choice(n, size=min(settings.check_points, n),
                                                             replace=False)]
        m_roll = spec.to_output(se_kernel(xc, Z, spec.sigma_f, spec.ell) @ np.ravel(ra["dtc_w"])
                                + spec.basis_fn(xc) @ np.ravel(ra["dtc_beta"]))
        m_ours, v_ours = sp.mean_var(xc * spec.x_std + spec.x_mean)
        info["sparse_mean_vs_rollout_mean_max_over_sd"] = float(
            np.max(np.abs(m_ours - m_roll) / np.sqrt(v_ours)))
        info["sparse_mean_vs_rollout_mean_max_abs"] = float(np.max(np.abs(m_ours - m_roll)))
    # diagnostics against the exact posterior
    crng = np.random.default_rng(seed + 1)
    limit = settings.exact_check_max_n
    if limit > 0:
        sub = np.arange(n) if n <= limit else np.sort(crng.choice(n, size=limit, replace=False))
        cspec = spec if n <= limit else _subset(spec, sub)
        info["exact_check"] = ("all n points" if n <= limit else
                               f"exact and sparse both conditioned on a random subset of {limit} points")
        post = exact_posterior(cspec)
        chk = crng.choice(cspec.Xs.shape[0], size=min(settings.check_points, cspec.Xs.shape[0]),
                          replace=False)
        xr = cspec.Xs[chk] * spec.x_std + spec.x_mean
        m_ex, v_ex = post.mean_var(xr)
        sd_ex = np.sqrt(np.maximum(v_ex, 1e-300))
        if settings.sampler == "sparse_pathwise":
            m_ap, v_ap = sparse_posterior(cspec, Z).mean_var(xr)
            sd_ap = np.sqrt(np.maximum(v_ap, 0.0))
            info["mean_err_max_over_sd"] = float(np.max(np.abs(m_ap - m_ex) / sd_ex))
            info["mean_err_rms_over_sd"] = float(np.sqrt(np.mean(((m_ap - m_ex) / sd_ex) ** 2)))
            info["sd_ratio_median"] = float(np.median(sd_ap / sd_ex))
            info["sd_ratio_min"] = float(np.min(sd_ap / sd_ex))
            info["sd_ratio_max"] = float(np.max(sd_ap / sd_ex))
        else:
            exact_f = smp(xr)
            approx_f = comp(np.broadcast_to(xr, (comp.n_samples, *xr.shape)))
            err = (approx_f - exact_f) / sd_ex
            info["compression_err_max_over_sd"] = float(np.abs(err).max())
            info["compression_err_rms_over_sd"] = float(np.sqrt(np.mean(err**2)))
        info["exact_sd_median"] = float(np.median(sd_ex))
        info["sigma_n"] = spec.sigma_n * spec.out_scale
    else:
        info["exact_check"] = "skipped (uq.exact_check_max_n = 0)"
    info["seconds"] = time.perf_counter() - t0
    log.info("%s: %s", spec.name, {k: v for k, v in info.items() if k != "model"})
    return comp, info


def _tabulated_samples(spec: GP, settings: UQSettings, seed: int, grid: np.ndarray
                       ) -> tuple[TabulatedSamples, dict[str, Any]]:
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    post = exact_posterior(spec)
    smp = pathwise_samples(post, settings.n_samples, settings.n_features, rng)
    grid = np.asarray(grid, dtype=float).ravel()
    tab = TabulatedSamples(grid, np.hstack([smp(grid[i:i + 2048, None]) for i in range(0, grid.size, 2048)]))
    crng = np.random.default_rng(seed + 1)
    xc = crng.uniform(grid[0], grid[-1], settings.check_points)[:, None]
    _, var = post.mean_var(xc)
    err = (tab(np.broadcast_to(xc, (tab.n_samples, *xc.shape))) - smp(xc)) / np.sqrt(np.maximum(var, 1e-300))
    info = {"model": spec.name, "n": int(spec.Xs.shape[0]), "dim": 1, "basis": spec.basis,
            "sampler": "exact_pathwise, tabulated", "grid_points": int(grid.size),
            "n_features": settings.n_features, "n_samples": settings.n_samples, "seed": seed,
            "exact_check": "interpolation error of the tabulated samples vs the exact samples",
            "interp_err_max_over_sd": float(np.abs(err).max()),
            "interp_err_rms_over_sd": float(np.sqrt(np.mean(err**2))),
            "exact_sd_median": float(np.median(np.sqrt(var))), "sigma_n": spec.sigma_n * spec.out_scale,
            "seconds": time.perf_counter() - t0}
    log.info("%s: %s", spec.name, {k: v for k, v in info.items() if k != "model"})
    return tab, info


def sample_models(model_stems: dict[str, str], settings: UQSettings, cfg: dict[str, Any],
                  out_dir: str | Path, diagnostics_out: str | Path
                  ) -> dict[str, CompressedSamples | TabulatedSamples]:
    """Stage ``uq_samples``: samples of every model, one npz each, plus diagnostics JSON."""
    out_dir = Path(out_dir)
    diags = {}
    result = {}
    for i, (name, stem) in enumerate(model_stems.items()):
        spec, Z, grid = load_gp_spec(stem, name)
        comp, info = draw_model_samples(spec, settings, uq_seed(cfg, i), Z, grid)
        write_npz(out_dir / f"{name}.npz", **comp.to_arrays())
        diags[name] = info
        result[name] = comp
    write_json({"settings": settings.__dict__, "models": diags}, diagnostics_out)
    return result


def load_samples(paths: dict[str, str | Path]) -> dict[str, CompressedSamples | TabulatedSamples]:
    from crgpr.io import load_npz

    return {name: samples_from_arrays(load_npz(p)) for name, p in paths.items()}


# ----------------------------------------------------------------------------------------
# stage 2: the sampled H_z through the rollout, all samples as one batch

MOMENTUM = ("dH_dp_x", "dH_dp_y", "dH_dp_theta")


class SampledRod:
    """S sampled H_z of the paper's six GPs, evaluated for a batch of S rods (sample s on rod s).

    Same assembly as the CR-GPR mean model (learned.LearnedRod, features 'paper'): nodal
    forces -dH/dx_i = (q_x,i - q_x,i-1) / (w_i ds) from the segment GPs q_x, q_y, -dH/dtheta_i
    from GPR 3 at nodes 1..N, dq/dt = H_p(p) from GPR 4-6, gravity as the input G u. States
    carry a leading sample axis: q, p (S, N+1, 3).
    """

    def __init__(self, samples: dict[str, Any], params: Any, theta_center: float | None):
        missing = [m for m in ("q_x", "q_y", "dH_dtheta", *MOMENTUM) if m not in samples]
        if missing:
            raise ValueError(f"UQ samples missing for model(s) {missing}")
        sizes = {m: samples[m].n_samples for m in samples}
        if len(set(sizes.values())) != 1:
            raise ValueError(f"UQ samples have different S per model: {sizes}")
        self.S = next(iter(sizes.values()))
        self.smp = samples
        self.params = params
        self.center = theta_center
        self.gu = np.array([0.0, -params.rhoA * params.g, 0.0])
        self.active = np.arange(self.S)  # samples still integrated (divergence drops some)
        self.last_q: np.ndarray | None = None
        self.last_p: np.ndarray | None = None

    def select(self, keep: np.ndarray) -> None:
        """Integrate only the samples ``keep`` (indices into the original S) from now on."""
        self.active = np.asarray(keep, dtype=int)

    def _call(self, name: str, X: np.ndarray, slope: bool = False) -> np.ndarray:
        smp = self.smp[name]
        full = np.zeros((self.S, *X.shape[1:]))
        full[self.active] = X
        out = smp.slope(full) if slope else smp(full)
        return out[self.active]

    def force(self, q: np.ndarray) -> np.ndarray:
        """-H_q + G u per unit length (S', N+1, 3)."""
        self.last_q = q
        P = self.params
        x, y, th = q[..., 0], q[..., 1], q[..., 2]
        out = np.zeros(q.shape)
        Xq = ft.paper_q_features(x, y, th, P.ds, self.center)
        out[..., 0] = ft.forces_from_q(self._call("q_x", Xq), P)
        out[..., 1] = ft.forces_from_q(self._call("q_y", Xq), P)
        out[..., 1:, 2] = -self._call("dH_dtheta", ft.paper_theta_features(x, y, th, P.ds, self.center))
        return out + self.gu

    def velocity(self, p: np.ndarray) -> np.ndarray:
        self.last_p = p
        return np.stack([self._call(m, p[..., k]) for k, m in enumerate(MOMENTUM)], axis=-1)

    def velocity_slope(self, p: np.ndarray) -> np.ndarray:
        return np.stack([self._call(m, p[..., k], slope=True) for k, m in enumerate(MOMENTUM)], axis=-1)


def rollout_samples(rod: SampledRod, theta0_deg: float, settings: Any, max_restarts: int = 3
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """Integrate all S sampled models at once with ``integrator.run_hamiltonian`` (the CR-GPR
    rollout's scheme, dt and boundary conditions). A sample that diverges is recorded and
    dropped, and the remaining batch is integrated again from t = 0 (never silently kept).
    Returns t (n_t,), q and p (S', n_t, N+1, 3) of the surviving samples, their indices, and
    the divergence records."""
    from crgpr.physics.integrator import REACH, SimulationDiverged, diverged_nodes, run_hamiltonian

    P = rod.params
    q0 = straight_rod(np.radians(theta0_deg), P)
    free = free_mask(P)
    wds = node_weights(P.N) * P.ds
    keep = np.arange(rod.S)
    diverged: list[dict[str, Any]] = []
    n_nodes = P.N + 1
    for _ in range(max_restarts + 1):
        rod.select(keep)
        S = len(keep)
        shape = (S, n_nodes, 3)

        # run_hamiltonian integrates one (n, 3) state: the S rods are stacked along its node axis
        # (S (N+1) rows), and the model sees them with the sample axis restored.
        def force(qf: np.ndarray, shape=shape) -> np.ndarray:
            return rod.force(qf.reshape(shape)).reshape(-1, 3)

        def velocity(pf: np.ndarray, shape=shape) -> np.ndarray:
            return rod.velocity(pf.reshape(shape)).reshape(-1, 3)

        def velocity_slope(pf: np.ndarray, shape=shape) -> np.ndarray:
            return rod.velocity_slope(pf.reshape(shape)).reshape(-1, 3)

        qb = np.tile(q0, (S, 1))
        try:
            out = run_hamiltonian(qb, np.zeros_like(qb), force, velocity, np.tile(free, (S, 1)), P.zeta,
                                  settings.dt, settings.n_steps, settings.record_every, np.tile(wds, S),
                                  what=f"UQ rollout at theta0 = {theta0_deg:g} deg",
                                  velocity_slope=velocity_slope, length=P.L0)
        except SimulationDiverged as exc:
            q, p = rod.last_q, rod.last_p
            v = rod.velocity(p) if p is not None else np.full_like(q, np.nan)
            bad = diverged_nodes(q, v, q0[0, :2], REACH * P.L0).any(axis=1)  # the integrator's policy
            if not bad.any():
                raise
            for j in np.nonzero(bad)[0]:
                diverged.append({"sample": int(keep[j]), "t_s": exc.t, "step": exc.step})
                log.warning("sample %d diverged at t = %.4g s; dropped, batch restarted", keep[j], exc.t)
            keep = keep[~bad]
            if len(keep) < 2:
                raise SimulationDiverged(f"UQ rollout at {theta0_deg:g} deg: fewer than 2 samples left "
                                         f"({diverged})", exc.step, exc.t, exc.node) from exc
            continue
        n_t = out.t.size
        q = np.moveaxis(out.q.reshape(n_t, S, n_nodes, 3), 1, 0)  # (S, n_t, N+1, 3)
        p = np.moveaxis(out.v.reshape(n_t, S, n_nodes, 3), 1, 0)
        return out.t, q, p, keep, diverged
    raise RuntimeError(f"UQ rollout at {theta0_deg:g} deg: too many divergence restarts ({diverged})")


def uq_frame(theta0_deg: float, t: np.ndarray, q: np.ndarray, p: np.ndarray, samples: np.ndarray,
             ds: float) -> pd.DataFrame:
    """Tidy table, one row per (sample, t, node), columns ``UQ_COLUMNS``."""
    S, n_t, n_nodes, _ = q.shape
    n = S * n_t * n_nodes
    return pd.DataFrame({
        "sample": np.repeat(samples.astype(np.int32), n_t * n_nodes),
        "theta0_deg": np.full(n, float(theta0_deg)),
        "t": np.tile(np.repeat(t, n_nodes), S),
        "node": np.tile(np.arange(n_nodes, dtype=np.int32), S * n_t),
        "s": np.tile(np.arange(n_nodes) * ds, S * n_t),
        "x": q[..., 0].ravel(), "y": q[..., 1].ravel(), "theta": q[..., 2].ravel(),
        "p_x": p[..., 0].ravel(), "p_y": p[..., 1].ravel(), "p_theta": p[..., 2].ravel(),
    })


# ----------------------------------------------------------------------------------------
# stage 3: bands and coverage


def expected_coverage_calibrated(n_samples: int, lo_pct: float, hi_pct: float,
                                 n_mc: int | None = None) -> float:
    """Coverage a perfectly calibrated model reaches with S samples: P(an (S+1)-th draw from the
    same distribution lies inside the [lo, hi] percentile band (numpy linear interpolation) of
    S draws), by Monte Carlo with Gaussian draws (fixed seed). 0.79 for S = 10 and 2.5 / 97.5 %
    (the sample range alone gives 9 / 11 = 0.82); -> (hi - lo) / 100 as S grows."""
    rng = np.random.default_rng(0)
    n_mc = n_mc or max(20_000, min(200_000, 4_000_000 // (n_samples + 1)))
    x = rng.standard_normal((n_mc, n_samples + 1))
    q = np.percentile(x[:, :n_samples], [lo_pct, hi_pct], axis=1)
    return float(np.mean((x[:, -1] >= q[0]) & (x[:, -1] <= q[1])))


def band_arrays(df: pd.DataFrame, cols: tuple[str, ...], lo: float, hi: float
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Per-sample arrays (S, n_t, n_nodes, len(cols)) and their lo / median / hi percentiles and
    mean over the samples. Rows must cover the full (sample, t, node) grid."""
    df = df.sort_values(["sample", "t", "node"])
    S = df["sample"].nunique()
    n_t = df["t"].nunique()
    n_nodes = df["node"].nunique()
    if len(df) != S * n_t * n_nodes:
        raise ValueError(f"UQ table has {len(df)} rows, expected S x n_t x n_nodes = "
                         f"{S} x {n_t} x {n_nodes}")
    arr = df[list(cols)].to_numpy().reshape(S, n_t, n_nodes, len(cols))
    q = np.percentile(arr, [lo, 50.0, hi], axis=0)
    return arr, q[0], q[1], q[2], arr.mean(0)


def coverage_row(uq: pd.DataFrame, gt: pd.DataFrame, lo: float, hi: float, n_diverged: int = 0
                 ) -> dict[str, Any]:
    """Coverage of the ground truth by the [lo, hi] percentile band for one angle."""
    gt = gt.sort_values(["t", "node"])
    t_uq = np.sort(uq["t"].unique())
    t_gt = np.sort(gt["t"].unique())
    if len(t_uq) != len(t_gt) or not np.allclose(t_uq, t_gt, atol=1e-9):
        raise ValueError(f"UQ and ground-truth time grids differ ({len(t_uq)} vs {len(t_gt)} samples)")
    cols = ("x", "y", "theta")
    arr, qlo, qmed, qhi, mean = band_arrays(uq, cols, lo, hi)
    S, n_t, n_nodes, _ = arr.shape
    g = gt[list(cols)].to_numpy().reshape(n_t, n_nodes, len(cols))
    inside = (g >= qlo) & (g <= qhi)
    th_in = inside[1:, 1:, 2]  # no t = 0 and no clamped base node
    tip_x, tip_y = inside[1:, -1, 0], inside[1:, -1, 1]
    err_med = qmed[..., 2] - g[..., 2]
    half = 0.5 * (qhi[..., 2] - qlo[..., 2])
    return {
        "theta0_deg": float(gt["theta0_deg"].iloc[0]), "n_samples": int(S), "n_diverged": int(n_diverged),
        "band_lo_pct": lo, "band_hi_pct": hi,
        "theta_coverage": float(th_in.mean()),
        "tip_coverage": float((tip_x & tip_y).mean()),
        "tip_x_coverage": float(tip_x.mean()), "tip_y_coverage": float(tip_y.mean()),
        "expected_coverage_calibrated": expected_coverage_calibrated(S, lo, hi),
        "theta_band_width_mean": float((qhi[1:, 1:, 2] - qlo[1:, 1:, 2]).mean()),
        "tip_band_width_mean": float(np.hypot(qhi[1:, -1, 0] - qlo[1:, -1, 0],
                                              qhi[1:, -1, 1] - qlo[1:, -1, 1]).mean()),
        "theta_rmse_median": float(np.sqrt(np.mean(err_med[:, 1:] ** 2))),
        "theta_rmse_mean_model": float(np.sqrt(np.mean((mean[..., 2] - g[..., 2])[:, 1:] ** 2))),
        "theta_abs_err_over_halfwidth_median": float(np.median(
            np.abs(err_med[1:, 1:]) / np.maximum(half[1:, 1:], 1e-12))),
    }


def coverage_table(uq_paths: dict[int, str], gt_paths: dict[int, str], settings: UQSettings,
                   out_parquet: str | Path, out_csv: str | Path) -> pd.DataFrame:
    """Stage ``uq_coverage``: one row per angle (``COVERAGE_COLUMNS``) plus a mean row in the CSV."""
    from crgpr.io import read_metadata

    rows = []
    for angle in sorted(uq_paths):
        uq = read_parquet(uq_paths[angle], required=UQ_COLUMNS)
        gt = read_parquet(gt_paths[angle], required=TRAJECTORY_COLUMNS)
        n_div = int(read_metadata(uq_paths[angle]).get("n_diverged", 0))
        rows.append(coverage_row(uq, gt, *settings.band_pct, n_diverged=n_div))
    df = pd.DataFrame(rows, columns=list(COVERAGE_COLUMNS))
    meta = {"kind": "uq_coverage", "settings": settings.__dict__,
            "definition": "fraction of ground-truth samples inside the [lo, hi] percentile band of "
                          "the S sampled trajectories; theta over all t > 0 and nodes 1..N; tip: "
                          "x and y both inside; expected_coverage_calibrated = the value a calibrated "
                          "model reaches with this S"}
    write_parquet(df, out_parquet, meta)
    table = df.copy()
    mean = table.drop(columns=["theta0_deg"]).mean(numeric_only=True)
    table["angle"] = table["theta0_deg"].map(lambda a: f"{a:g}")
    mean_row = {**mean.to_dict(), "angle": "mean", "theta0_deg": np.nan}
    table = pd.concat([table, pd.DataFrame([mean_row])], ignore_index=True)
    table = table[["angle", *[c for c in COVERAGE_COLUMNS if c != "theta0_deg"]]]
    write_csv(table.round(4), out_csv)
    return df


# ----------------------------------------------------------------------------------------
# figure


def band_figure(uq: pd.DataFrame, gt: pd.DataFrame, settings: UQSettings, out: str | Path,
                mean_traj: pd.DataFrame | None = None) -> None:
    """Rod configurations at four time instants: 95 % band (normal offsets of the sampled
    shapes from the median shape, lo-hi percentiles) shaded, thin sampled shapes, the CR-GPR
    mean-model rollout solid red (the sample median if not given), ground truth dashed blue
    (paper Fig. combined_shapes, right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from crgpr.io import atomic_path

    lo, hi = settings.band_pct
    arr, qlo, qmed, qhi, _ = band_arrays(uq, ("x", "y"), lo, hi)
    t = np.sort(uq["t"].unique())
    gt = gt.sort_values(["t", "node"])
    n_nodes = arr.shape[2]
    g = gt[["x", "y"]].to_numpy().reshape(len(t), n_nodes, 2)
    mm = None
    if mean_traj is not None:
        mean_traj = mean_traj.sort_values(["t", "node"])
        if mean_traj["t"].nunique() != len(t):
            raise ValueError("mean-model rollout and UQ samples have different time grids")
        mm = mean_traj[["x", "y"]].to_numpy().reshape(len(t), n_nodes, 2)
    idx = [int(round(f * (len(t) - 1))) for f in settings.figure_time_fractions]
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    colors = plt.cm.viridis(np.linspace(0.0, 0.85, len(idx)))
    for c, k in zip(colors, idx, strict=True):
        med = qmed[k]  # (n_nodes, 2) median shape
        tan = np.gradient(med, axis=0)
        tan /= np.maximum(np.linalg.norm(tan, axis=1, keepdims=True), 1e-12)
        nrm = np.stack([-tan[:, 1], tan[:, 0]], axis=1)
        off = np.einsum("snk,nk->sn", arr[:, k] - med, nrm)  # (S, n_nodes) normal offsets
        o_lo, o_hi = np.percentile(off, [lo, hi], axis=0)
        # tip: extend the band along the tangent by the tangential spread of the tip samples
        tang = np.einsum("sk,k->s", arr[:, k, -1] - med[-1], tan[-1])
        t_hi = max(float(np.percentile(tang, hi)), 0.0)
        upper = med + o_hi[:, None] * nrm
        lower = med + o_lo[:, None] * nrm
        poly = np.vstack([upper, med[-1] + t_hi * tan[-1], lower[::-1]])
        ax.fill(poly[:, 0], poly[:, 1], color=c, alpha=0.3, lw=0)
        for smp in arr[:, k]:
            ax.plot(smp[:, 0], smp[:, 1], "-", color=c, lw=0.4, alpha=0.6)
        centre = med if mm is None else mm[k]
        ax.plot(centre[:, 0], centre[:, 1], "-", color="tab:red", lw=1.6)
        ax.plot(g[k, :, 0], g[k, :, 1], "--", color="tab:blue", lw=1.6)
        ax.annotate(f"t = {t[k]:.2f} s", med[-1], textcoords="offset points", xytext=(4, 4),
                    fontsize=8, color=c)
    ax.plot([], [], "-", color="tab:red",
            label="CR-GPR (mean model)" if mm is not None else f"CR-GPR median of S = {arr.shape[0]} samples")
    ax.plot([], [], "-", color="gray", lw=0.4, label=f"S = {arr.shape[0]} RFF posterior samples")
    ax.plot([], [], "--", color="tab:blue", label="ground truth")
    ax.fill([], [], color="gray", alpha=0.3, label=f"{hi - lo:g} % band ({lo:g}-{hi:g} percentiles)")
    ax.plot(0, 0, "ks", ms=5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(f"theta0 = {uq['theta0_deg'].iloc[0]:g} deg: rod shapes with 95 % CI (RFF samples)")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_path(out, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=150)
    plt.close(fig)


# ----------------------------------------------------------------------------------------
# Snakemake entry points


def samples_rule(cfg: dict[str, Any], models: list[str], samples: list[str], diagnostics: str) -> None:
    """Rule ``uq_samples``: ``models`` are the .npz files of results/models/{prefilter}/."""
    settings = UQSettings.from_config(cfg)
    stems = {Path(m).stem: str(Path(m).with_suffix("")) for m in models}
    out_dir = Path(samples[0]).parent
    expected = {Path(s).stem for s in samples}
    if set(stems) != expected:
        raise ValueError(f"uq_samples: models {sorted(stems)} do not match outputs {sorted(expected)}")
    sample_models(stems, settings, cfg, out_dir, diagnostics)


def coverage_rule(cfg: dict[str, Any], uq_paths: list[str], gt_paths: list[str], out: str,
                  table: str) -> None:
    """Rule ``uq_coverage``."""
    settings = UQSettings.from_config(cfg)
    uq_map = {int(Path(p).stem): p for p in uq_paths}
    gt_map = {int(Path(p).stem): p for p in gt_paths}
    df = coverage_table(uq_map, gt_map, settings, out, table)
    log.info("coverage:\n%s", df.to_string())


def figure_rule(cfg: dict[str, Any], uq_path: str, gt_path: str, out: str,
                mean_path: str | None = None) -> None:
    """Rule ``uq_figure``; ``mean_path``: the CR-GPR mean-model rollout at the same angle."""
    settings = UQSettings.from_config(cfg)
    uq = read_parquet(uq_path, required=UQ_COLUMNS)
    gt = read_parquet(gt_path, required=TRAJECTORY_COLUMNS)
    mean = read_parquet(mean_path, required=TRAJECTORY_COLUMNS) if mean_path else None
    band_figure(uq, gt, settings, out, mean)


def rollout_rule(cfg: dict[str, Any], angle: int, samples: list[str], models: list[str], out: str) -> None:
    """Rule ``uq_rollout``: S sampled models through the rollout at one angle."""
    from crgpr.config import rod_params, sim_settings

    settings = UQSettings.from_config(cfg)
    params, sim = rod_params(cfg), sim_settings(cfg)
    smp = load_samples({Path(p).stem: p for p in samples})
    metas = {Path(m).stem: json.loads(Path(m).read_text()) for m in models}
    centers = {metas[m].get("theta_center") for m in ("q_x", "q_y", "dH_dtheta") if m in metas}
    if len(centers) != 1:
        raise ValueError(f"uq_rollout: q_x, q_y, dH_dtheta have different theta windows {centers}")
    if metas.get("q_x", {}).get("features") is not None and list(metas["q_x"]["features"]) != list(
            ft.PAPER_Q_FEATURES):
        raise ValueError("uq_rollout: the sampled models do not use the paper's features")
    rod = SampledRod(smp, params, centers.pop())
    t0 = time.perf_counter()
    t, q, p, keep, diverged = rollout_samples(rod, float(angle), sim)
    secs = time.perf_counter() - t0
    log.info("theta0 = %d deg: %d samples integrated in %.1f s (%d diverged)", angle, len(keep), secs,
             len(diverged))
    meta = {"kind": "uq_rollout", "theta0_deg": angle, "method": settings.method,
            "n_samples": settings.n_samples, "n_diverged": len(diverged), "diverged": diverged,
            "seconds_rollout": secs, "settings": settings.__dict__, "rod": params.to_dict(),
            "simulation": sim.to_dict(), "seed": cfg["seed"]}
    write_parquet(uq_frame(float(angle), t, q, p, keep, params.ds), out, meta)


# ----------------------------------------------------------------------------------------
# function-level calibration on the test trajectories (diagnostic of the band's coverage)


def true_targets(q: np.ndarray, p: np.ndarray, params: Any) -> dict[str, np.ndarray]:
    """The analytic rod's values of the six gradient-GP targets at states q, p (n_t, N+1, 3):
    q_x, q_y (segments: the rod's own stress resultants, features.q_from_hz of its H_x, H_y),
    dH_dtheta at nodes 1..N (-F_theta / (w ds)), dH_dp_* = p / (rho A), p_theta / (rho I)."""
    from crgpr.physics.rod import internal_forces, strains

    st = strains(q, params)
    wds = node_weights(params.N) * params.ds
    F = np.array([internal_forces(qq, params, float(q[0, 0, 2]))[0] for qq in q])
    return {"q_x": st["q_x"], "q_y": st["q_y"], "dH_dtheta": -F[:, 1:, 2] / wds[1:],
            "dH_dp_x": p[:, 1:, 0] / params.rhoA, "dH_dp_y": p[:, 1:, 1] / params.rhoA,
            "dH_dp_theta": p[:, 1:, 2] / params.rhoI}


def function_calibration(cfg: dict[str, Any], model_stems: dict[str, str], gt_paths: dict[int, str],
                         out_csv: str | Path, n_times: int = 200) -> pd.DataFrame:
    """Is each gradient GP's posterior calibrated where the test rollouts go? At ``n_times``
    ground-truth states per test angle: z = (true target - rollout mean) / posterior sd (the
    sampler's predictive sd: DTC for the multi-input GPs, exact for the 1D ones), and the
    fraction with |z| < 1.96 (0.95 if calibrated). Poor function-level coverage means the
    trajectory band cannot cover the truth, whatever S and D."""
    from crgpr.config import rod_params
    from crgpr.physics.simulate import trajectory_from_frame

    params = rod_params(cfg)
    specs = {m: load_gp_spec(s, m) for m, s in model_stems.items()}
    metas = {m: json.loads(Path(s).with_suffix(".json").read_text()) for m, s in model_stems.items()}
    center = metas["q_x"].get("theta_center")
    preds = {}
    for m, (spec, Z, _) in specs.items():
        if Z is not None:
            preds[m] = ("dtc", sparse_posterior(spec, Z), spec)
        else:
            preds[m] = ("exact", exact_posterior(spec), spec)
    rows = []
    for angle, path in sorted(gt_paths.items()):
        traj = trajectory_from_frame(read_parquet(path, required=TRAJECTORY_COLUMNS), params)
        k = np.unique(np.linspace(1, len(traj.t) - 1, n_times).round().astype(int))
        q, p = traj.q[k], traj.p[k]
        x, y, th = q[..., 0], q[..., 1], q[..., 2]
        feats = {"q_x": ft.paper_q_features(x, y, th, params.ds, center),
                 "dH_dtheta": ft.paper_theta_features(x, y, th, params.ds, center)}
        feats["q_y"] = feats["q_x"]
        for j, m in enumerate(MOMENTUM):
            feats[m] = p[:, 1:, j:j + 1]
        truth = true_targets(q, p, params)
        for m, (kind, post, spec) in preds.items():
            X = feats[m].reshape(-1, feats[m].shape[-1])
            mean, var = post.mean_var(X)
            ra = getattr(spec, "rollout_arrays", {})
            if kind == "dtc" and "dtc_w" in ra:  # centre = the rollout's mean model
                from crgpr.gp.sampling import se_kernel

                xs = spec.standardise(X)
                mean = spec.to_output(se_kernel(xs, ra["dtc_Z"], spec.sigma_f, spec.ell)
                                      @ np.ravel(ra["dtc_w"]) + spec.basis_fn(xs) @ np.ravel(ra["dtc_beta"]))
            sd = np.sqrt(np.maximum(var, 1e-300))
            z = (truth[m].reshape(-1) - mean) / sd
            rows.append({"theta0_deg": angle, "model": m, "n_points": int(z.size),
                         "coverage_95": float(np.mean(np.abs(z) < 1.959964)),
                         "median_abs_z": float(np.median(np.abs(z))),
                         "rmse": float(np.sqrt(np.mean((truth[m].reshape(-1) - mean) ** 2))),
                         "median_sd": float(np.median(sd)),
                         "target_std": float(np.std(truth[m]))})
    df = pd.DataFrame(rows)
    write_csv(df.round(6), out_csv)
    log.info("function-level calibration:\n%s", df.to_string())
    return df


def calibration_rule(cfg: dict[str, Any], models: list[str], gt_paths: list[str], out: str) -> None:
    """Rule ``uq_calibration``."""
    stems = {Path(m).stem: str(Path(m).with_suffix("")) for m in models}
    function_calibration(cfg, stems, {int(Path(p).stem): p for p in gt_paths}, out)
