"""Posterior function samples of a method's gradient GPs, stored for the sampled rollouts
(paper Sec. III-B "Uncertainty Quantification via RFF Sampling").

For every SE / ARD-SE gradient GP of a method (``cr_gpr``: q_x, q_y, dH/dtheta; ``cr_gpr_objective``:
obj_n1, obj_n2, obj_m; both: dH/dp_x, dH/dp_y, dH/dp_theta) S joint posterior function samples
are drawn by ``crgpr.gp.sampling`` (sparse pathwise conditioning on the rollout's own DTC
inducing inputs, centred exactly on the rollout's mean model, plus an RFF sample of the prior
residual), basis coefficients included. The 1D momentum GPs are sampled exactly and tabulated
like their means (``TabulatedSamples``). Every sample set is a component of
``crgpr.learning.learned.LearnedRod`` with a leading sample axis: x (S, ..., d) -> (S, ...).
The sampling-approximation errors are measured against the exact GP posterior (diagnostics).
"""

from __future__ import annotations

import json
import logging
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg as sla

from crgpr.gp import GP
from crgpr.gp.evaluators import interp_uniform
from crgpr.gp.sampling import (
    CompressedSamples,
    SparsePosterior,
    exact_posterior,
    heldout_block_scale,
    inducing_indices,
    pathwise_samples,
    reduce_update_rank,
    scaled_spec,
    se_kernel,
    sparse_posterior,
    subset_spec,
)
from crgpr.gp.sampling import compress as compress_samples
from crgpr.io import load_npz, write_json, write_npz
from crgpr.learning.extrapolation import TangentContinuation
from crgpr.learning.gradient_models import ALL_MODELS
from crgpr.learning.nominal import NominalContinuation, SelectedInputs
from crgpr.learning.warp import BendingWarp
from crgpr.uq.settings import UQSettings

log = logging.getLogger(__name__)

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
        interp_uniform(flat, self.grid[0], self.grid[1] - self.grid[0], self.values, slope, out)
        return out.reshape(x.shape)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """Sample s at x[s]: x (S, ...) or (S, ..., 1) -> (S, ...); 0 (the prior mean) outside
        the grid, as the CR-GPR rollout's tables (crgpr.gp.Table1D)."""
        return self._eval(x, False)

    def slope(self, x: np.ndarray) -> np.ndarray:
        """Slope of each sample's interpolant at x[s] (0 outside), for the damping flow."""
        return self._eval(x, True)


SampleSet = CompressedSamples | TabulatedSamples


def samples_from_arrays(arr: dict[str, np.ndarray]) -> SampleSet:
    if "kind" in arr and str(arr["kind"]) == "tabulated":
        return TabulatedSamples(arr["grid"], arr["values"])
    return CompressedSamples.from_arrays(arr)


def uq_seed(seed: int, model: str) -> int:
    """Seed of the samples of one gradient model, from the global ``seed`` and the model's name
    (the same draws for a model shared by two methods, e.g. the momentum GPs)."""
    return int(np.random.SeedSequence([int(seed), 5, ALL_MODELS.index(model)]).generate_state(1)[0])


# components that see another through ``component``
WRAPPERS = (SelectedInputs, BendingWarp, TangentContinuation, NominalContinuation)


def unwrapped(component: Any) -> Any:
    """The component inside any ``WRAPPERS`` (input selection, record-fit warp, tangent continuation,
    nominal continuation)."""
    while isinstance(component, WRAPPERS):
        component = component.component
    return component


def is_sample_set(component: Any) -> bool:
    """Whether a learned-rod component carries a sample axis (a sample set, or one seen through
    ``WRAPPERS``); a deterministic component (a nominal law) is shared by every sample."""
    return isinstance(unwrapped(component), (CompressedSamples, TabulatedSamples))


def select_samples(smp: Any, keep: np.ndarray) -> Any:
    """The sample set restricted to the samples ``keep`` (indices along the sample axis); a
    component seen through ``WRAPPERS`` keeps its wrapping, a deterministic one is returned as
    it is."""
    keep = np.asarray(keep, dtype=int)
    if isinstance(smp, WRAPPERS):
        return smp.rewrap(select_samples(smp.component, keep))
    if not is_sample_set(smp):
        return smp
    if isinstance(smp, TabulatedSamples):
        return TabulatedSamples(smp.grid, smp.values[keep])
    arr = smp.to_arrays()
    for k in ("omega", "phase", "w", "a", "beta"):
        arr[k] = arr[k][keep]
    out = CompressedSamples.from_arrays(arr)
    return out.truncate(smp.kernel_tol) if smp.kernel_tol > 0 else out


# ----------------------------------------------------------------------------------------
# stage 1: samples of every gradient GP


def load_gp_spec(stem: str | Path, name: str, sampled: bool = True
                 ) -> tuple[GP, np.ndarray | None, np.ndarray | None]:
    """Read a ``crgpr.gp.GP.save`` model (stem.npz + stem.json) into a GP without the
    O(n^3) factorisation ``GP.load`` performs; also return the standardised inducing inputs
    ``dtc_Z`` of the rollout's DTC mean and the 1D table grid ``table_x`` (gradient_models.py)
    when the file has them. ``sampled``: the GP is to be RFF-sampled (an SE / ARD-SE kernel is
    then required)."""
    stem = Path(stem)
    npz, js = stem.with_suffix(".npz"), stem.with_suffix(".json")
    for p in (npz, js):
        if not p.exists():
            raise FileNotFoundError(f"{p}: gradient model file missing (run the gradient_models rule)")
    meta = json.loads(js.read_text())
    if sampled and meta.get("kernel") != "se":
        raise ValueError(f"{js}: kernel {meta.get('kernel')!r}; RFF sampling needs SE / ARD-SE")
    with np.load(npz, allow_pickle=False) as a:
        arr = {k: a[k] for k in a.files}
    X = np.asarray(arr["X"], dtype=float)
    X = X[:, None] if X.ndim == 1 else X
    Y = np.asarray(arr["Y"], dtype=float)
    if Y.ndim == 2 and Y.shape[1] != 1:
        raise ValueError(f"{npz}: {Y.shape[1]} output columns; expected a single-output GP")
    if "odd_about" in meta:
        X, Y = _interleave_reflections(X, Y.ravel(), float(meta["odd_about"]), npz)
    y_mean = float(np.ravel(arr["y_mean"])[0])
    y_scale = float(np.ravel(arr["y_scale"])[0])
    x_mean, x_scale = np.ravel(arr["x_mean"]), np.ravel(arr["x_scale"])
    spec = GP.from_standardised(
        (X - x_mean) / x_scale, (Y.ravel() - y_mean) / y_scale, float(meta["sigma_f_std"]),
        np.broadcast_to(np.ravel(arr["lengthscales"]), (X.shape[1],)), float(meta["sigma_n_std"]),
        str(meta["basis"]), x_mean, x_scale, y_mean, y_scale, name, kernel=str(meta["kernel"]))
    Z = arr.get("dtc_Z")
    Z = None if Z is None else np.atleast_2d(np.asarray(Z, dtype=float))
    grid = arr.get("table_x")
    spec.rollout_arrays = {k: arr[k] for k in ("dtc_Z", "dtc_w", "dtc_beta", "table_y") if k in arr}
    if "rollout_pivots" in arr:  # the rollout integrates the DTC mean on a subset of dtc_Z
        w = np.zeros_like(arr["dtc_w"])
        w[arr["rollout_pivots"]] = arr["rollout_w"]
        spec.rollout_arrays["dtc_w"] = w
    return spec, Z, (None if grid is None else np.ravel(grid).astype(float))


def _interleave_reflections(X: np.ndarray, y: np.ndarray, about: float, src: Path
                           ) -> tuple[np.ndarray, np.ndarray]:
    """Rows of an odd law (``gradient_models.train_model_arrays(odd_about=...)``: n/2 time-major
    samples, then their reflections (2 k0 - x, -y; an arclength input s unchanged)) reordered so
    that each sample is followed by its reflection: a contiguous block of rows
    (``uq.heldout_blocks``) is then a time block with its mirror image, not a time block whose
    reflection stays in the other blocks. The posterior does not depend on the order."""
    h = X.shape[0] // 2
    if 2 * h != X.shape[0] or not (
            np.allclose(X[h:, 0], 2.0 * about - X[:h, 0], rtol=0.0, atol=1e-12 * (1.0 + np.abs(X).max()))
            and np.array_equal(X[h:, 1:], X[:h, 1:])
            and np.allclose(y[h:], -y[:h], rtol=0.0, atol=1e-12 * (1.0 + np.abs(y).max()))):
        raise ValueError(f"{src}: odd_about = {about:g}, but its rows are not samples followed by "
                         "their reflections")
    order = np.arange(2 * h).reshape(2, h).T.ravel()
    return X[order], y[order]


_subset = subset_spec


_SCALE_SOURCES = {
    "rms": "held-out contiguous blocks of the training rows, rms of the held-out z (latent predictive)",
    "median": "held-out contiguous blocks of the training rows, median of the held-out z (latent predictive)",
    "split": "held-out contiguous blocks of the training rows, maximum likelihood of r ~ N(0, c^2 v_latent "
             "+ s^2), s the targets' own error (not sampled)",
    "jackknife": "delete-a-block jackknife over contiguous blocks of the training rows: c^2 = median over "
                 "training inputs of the jackknife variance of the posterior mean / the posterior variance",
}
_COVARIANCE_SOURCE = ("delete-a-block jackknife covariance of the DTC coefficients (beta, v) over "
                      "contiguous blocks of the training rows plus the prior part P^-1 Lambda P^-1 of the "
                      "kernel weights (cluster-robust; SparsePosterior.sample(jackknife=...)); no scale")
_COVARIANCE_SOURCE_1D = ("1D model sampled exactly and tabulated: its sigma_f, sigma_n scaled by the "
                         "delete-a-block jackknife scale (heldout_jackknife); the jackknife covariance needs "
                         "the sparse sampler")


def posterior_scale(spec: GP, settings: UQSettings, Z: np.ndarray | None,
                    full: SparsePosterior | None = None
                    ) -> tuple[float, dict[str, Any], np.ndarray | None]:
    """The factor c of the sampled posterior's sd (``uq.posterior_scale``): 1 for 'none'; for
    'heldout_split' / 'heldout_median' / 'heldout_rms' / 'heldout_jackknife' c from
    ``crgpr.gp.sampling.heldout_block_scale`` with ``uq.heldout_blocks`` contiguous (time)
    blocks, on the inducing inputs ``Z`` when the sampler is sparse (``full``: the unscaled
    full-data posterior there, if already built). 'jackknife_covariance': for the sparse sampler
    c = 1 and the leave-one-block-out coefficient vectors (B, p + M) are returned third, for
    ``SparsePosterior.sample(..., jackknife=...)``; for a 1D tabulated model (``Z`` None) the
    scalar jackknife scale. Returns (c, diagnostics, coefficients or None)."""
    if settings.posterior_scale == "none":
        return 1.0, {"posterior_scale": 1.0, "posterior_scale_source": "none (fitted posterior)"}, None
    t0 = time.perf_counter()
    covariance = settings.posterior_scale == "jackknife_covariance"
    stat = "jackknife" if covariance else settings.posterior_scale.removeprefix("heldout_")
    sparse = settings.sampler == "sparse_pathwise" and Z is not None
    coeffs: list[np.ndarray] | None = [] if covariance and sparse else None
    c, info = heldout_block_scale(spec, settings.heldout_blocks, Z if sparse else None, stat,
                                  settings.check_points, full if sparse else None, coeffs)
    info["posterior_scale_source"] = _SCALE_SOURCES[stat]
    jk = None
    if coeffs is not None:
        jk = np.asarray(coeffs)
        c = 1.0
        info["posterior_scale"] = 1.0
        info["posterior_covariance"] = _COVARIANCE_SOURCE
        info["posterior_scale_source"] = "none (the jackknife covariance replaces the posterior's data part)"
    elif covariance:
        info["posterior_covariance"] = _COVARIANCE_SOURCE_1D
    info["posterior_scale_seconds"] = time.perf_counter() - t0
    return c, info, jk


def centre_on_rollout(comp: CompressedSamples, sp: SparsePosterior, ra: dict[str, np.ndarray],
                      c: float) -> None:
    """Centre the samples ``comp`` of the (scaled by ``c``) DTC posterior ``sp`` exactly on the
    rollout's mean model ``ra`` (dtc_w, dtc_beta): its DTC coefficients plus the zero-mean
    posterior deviations (the two DTC solutions agree near the data but differ far from it,
    where K_ZZ's ill-conditioned directions and the basis extrapolation dominate). In place."""
    beta_bar, a_bar = sp.mean_coefficients()
    # (dtc_w weights k(u, Z) of the unscaled kernel; the samples' kernel is c^2 k)
    comp.a = comp.a - a_bar + np.ravel(ra["dtc_w"]) / c**2
    comp.beta = comp.beta - beta_bar + np.ravel(ra["dtc_beta"])
    comp.__post_init__()


def draw_model_samples(spec: GP, settings: UQSettings, seed: int, Z: np.ndarray | None = None,
                       grid: np.ndarray | None = None
                       ) -> tuple[CompressedSamples | TabulatedSamples, dict[str, Any]]:
    """S compressed joint samples of one GP plus diagnostics.

    Inducing inputs: ``Z`` (standardised) if given, i.e. the rollout's own DTC inducing set, so
    that the samples are centred on exactly the mean model the CR-GPR rollout integrates; else
    M = uq.inducing by pivoted Cholesky. Diagnostics: the sampler's mean and sd against the
    exact GP posterior at ``check_points`` training inputs; for n > exact_check_max_n both are
    conditioned on a random subset of exact_check_max_n points (as gradient_models.py does).

    1D models (the momentum GPs, n ~ 1000) with a ``grid``: exact pathwise samples tabulated on
    the grid (the rollout's own representation of their mean); the diagnostics then measure
    the interpolation error of the tabulated samples against the exact samples.
    """
    if spec.dim == 1 and grid is not None and spec.Xs.shape[0] <= settings.tabulated_exact_max_n:
        c, cinfo, _ = posterior_scale(spec, settings, None)
        tab, info = _tabulated_samples(scaled_spec(spec, c) if c != 1.0 else spec, settings, seed, grid)
        return tab, {**info, **cinfo}
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    n = spec.Xs.shape[0]
    if Z is None:
        idx = inducing_indices(spec, settings.inducing, seed)
        Z, z_src = spec.Xs[idx], "farthest points (crgpr.gp.select_inducing)"
    else:
        idx, z_src = None, "the rollout model's DTC inducing inputs (dtc_Z)"
    sp0 = sparse_posterior(spec, Z) if settings.sampler == "sparse_pathwise" else None
    c, cinfo, jk = posterior_scale(spec, settings, Z, sp0)
    sspec = scaled_spec(spec, c) if c != 1.0 else spec
    info: dict[str, Any] = {"model": spec.name, "n": int(n), "dim": spec.dim, "basis": spec.basis,
                            "inducing": int(Z.shape[0]), "inducing_source": z_src,
                            "sampler": settings.sampler, "n_features": settings.n_features,
                            "n_samples": settings.n_samples, "seed": seed}
    ra = getattr(spec, "rollout_arrays", {})
    info.update(cinfo)
    if settings.sampler == "sparse_pathwise":
        sp = sp0.scaled(c) if c != 1.0 else sp0  # = sparse_posterior(sspec, Z), one factorisation
        comp = sp.sample(settings.n_samples, settings.n_features, rng, jk)
        if jk is not None:
            _jackknife_diagnostics(sp, jk, spec, settings, info, np.random.default_rng(seed + 4))
        if "dtc_w" in ra:
            centre_on_rollout(comp, sp, ra, c)
            info["centred_on"] = "the rollout's DTC mean (dtc_w, dtc_beta)"
    else:
        if idx is None:  # compression needs training-point indices: match Z to rows of X
            idx = np.array([int(np.argmin(((spec.Xs - z) ** 2).sum(1))) for z in Z])
        smp = pathwise_samples(exact_posterior(sspec), settings.n_samples, settings.n_features, rng)
        comp = compress_samples(smp, idx)
    comp, rinfo = _reduced(comp, spec, settings, c, np.random.default_rng(seed + 3),
                           sp if settings.sampler == "sparse_pathwise" else None, jk)
    info.update(rinfo)
    info["sampling_s"] = time.perf_counter() - t0
    if settings.sampler == "sparse_pathwise" and "dtc_w" in ra:
        # our DTC posterior mean against the mean model the CR-GPR rollout integrates
        xc = spec.Xs[np.random.default_rng(seed + 2).choice(n, size=min(settings.check_points, n),
                                                             replace=False)]
        m_roll = spec.to_output(se_kernel(xc, Z, spec.sigma_f, spec.ell) @ np.ravel(ra["dtc_w"])
                                + spec.basis_fn(xc) @ np.ravel(ra["dtc_beta"]))
        m_ours, v_ours = sp.mean_var(xc * spec.x_std + spec.x_mean)
        v_ours = v_ours / c**2  # the unscaled posterior's variance
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
            err = (approx_f - exact_f) / (c * sd_ex)
            info["compression_err_max_over_sd"] = float(np.abs(err).max())
            info["compression_err_rms_over_sd"] = float(np.sqrt(np.mean(err**2)))
        info["exact_sd_median"] = float(np.median(sd_ex))
        info["sigma_n"] = spec.sigma_n * spec.out_scale
    else:
        info["exact_check"] = "skipped (uq.exact_check_max_n = 0)"
    if spec.dim == 1 and grid is not None:
        comp = _tabulate_sparse(comp, sp if settings.sampler == "sparse_pathwise" else None, spec, grid, info)
    info["seconds"] = time.perf_counter() - t0
    log.info("%s: %s", spec.name, {k: v for k, v in info.items() if k != "model"})
    return comp, info


def _jackknife_diagnostics(sp: SparsePosterior, jk: np.ndarray, spec: GP, settings: UQSettings,
                           info: dict[str, Any], rng: np.random.Generator) -> None:
    """The jackknife covariance against the fitted posterior: sd of the basis coefficients
    (standardised units) and the ratio of the samples' sd to the posterior sd at training inputs."""
    p = sp.n_basis
    C = sp.jackknife_covariance(jk)
    Pi = sla.solve_triangular(sp.RP, sla.solve_triangular(sp.RP, np.eye(sp.mu.shape[0]), trans="T"))
    info["jackknife_blocks"] = int(jk.shape[0])
    info["basis_coef_sd_jackknife"] = [float(v) for v in np.sqrt(np.diag(C)[:p])]
    info["basis_coef_sd_posterior"] = [float(v) for v in np.sqrt(np.diag(Pi)[:p])]
    n = spec.Xs.shape[0]
    xr = spec.Xs[rng.choice(n, size=min(settings.check_points, n), replace=False)] * spec.x_std + spec.x_mean
    _, v_post = sp.mean_var(xr)
    _, v_jk = sp.mean_var(xr, jk)
    r = np.sqrt(np.maximum(v_jk, 0.0) / np.maximum(v_post, 1e-300))
    info["jackknife_over_posterior_sd"] = {"median": float(np.median(r)), "min": float(r.min()),
                                           "max": float(r.max())}


def _reduced(comp: CompressedSamples, spec: GP, settings: UQSettings, c: float, rng: np.random.Generator,
             posterior: SparsePosterior | None = None, jackknife: np.ndarray | None = None
             ) -> tuple[CompressedSamples, dict[str, Any]]:
    """The samples on a low-rank subset of their inducing inputs (``reduce_update_rank`` with
    ``uq.update_rank_tol``) if that changes no sample by more than ``uq.update_rank_max_error``
    posterior sd at ``check_points`` random training inputs and is at most half the terms;
    else unchanged. Same function draws, fewer kernel terms a rollout step. ``posterior``: the
    sampler's own (scaled) DTC posterior on the samples' inducing inputs, whose sd is the one
    measured against (built here when not given, e.g. for compressed exact samples);
    ``jackknife``: the samples' jackknife covariance (their sd is then that of
    ``posterior.mean_var(x, jackknife)``)."""
    M = comp.Z.shape[0]
    info: dict[str, Any] = {"update_terms": int(M)}
    if settings.update_rank_tol <= 0:
        info["update_rank"] = "not reduced (uq.update_rank_tol = 0)"
        return comp, info
    red = reduce_update_rank(comp, settings.update_rank_tol)
    r = red.Z.shape[0]
    n = spec.Xs.shape[0]
    xs = spec.Xs[rng.choice(n, size=min(settings.check_points, n), replace=False)]
    xr = xs * spec.x_std + spec.x_mean
    X = np.broadcast_to(xr, (comp.n_samples, *xr.shape))
    # the samples' posterior sd there (scaled posterior: c x the fitted one), from the ensemble's
    # own kernel: DTC variance of the sampled GP
    if posterior is None or not np.array_equal(posterior.Z, comp.Z):
        posterior = sparse_posterior(scaled_spec(spec, c) if c != 1.0 else spec, comp.Z)
    _, var = posterior.mean_var(xr, jackknife)
    sd = np.sqrt(np.maximum(var, 1e-300))
    err = float(np.max(np.abs(red(X) - comp(X)) / sd))
    info["update_rank_pivots"] = int(r)
    info["update_rank_err_max_over_sd"] = err
    if r <= M // 2 and err <= settings.update_rank_max_error:
        info["update_terms"] = int(r)
        info["update_rank"] = (f"reduced {M} -> {r} inducing inputs (pivoted Cholesky, residual < "
                               f"{settings.update_rank_tol:g} sigma_f^2; max change {err:.1e} sd)")
        return red, info
    info["update_rank"] = (f"not reduced: {r} of {M} pivots, max change {err:.1e} sd "
                           f"(uq.update_rank_max_error {settings.update_rank_max_error:g})")
    return comp, info


def _tabulate_sparse(comp: CompressedSamples, sp: SparsePosterior | None, spec: GP, grid: np.ndarray,
                     info: dict[str, Any]) -> TabulatedSamples:
    """Samples of a 1D GP with more than ``uq.tabulated_exact_max_n`` points (a learned bending
    law m(kappa) on every frame): drawn by the sparse sampler, then tabulated on the rollout's
    grid like the mean, each sample's deviation from the sampler's mean added to the rollout's
    table (``table_y``: the exact posterior mean), so zero variance gives the mean model exactly."""
    g = np.asarray(grid, dtype=float).ravel()
    vals = np.hstack([comp(np.broadcast_to(g[i:i + 2048, None], (comp.n_samples, min(2048, g.size - i), 1)))
                      for i in range(0, g.size, 2048)])
    if sp is None:  # exact pathwise samples: their mean is the exact posterior mean
        centre = exact_posterior(spec).mean_var(g[:, None])[0]
    else:
        centre, var = sp.mean_var(g[:, None])
        table = spec.rollout_arrays.get("table_y")
        if table is not None:
            info["sparse_mean_vs_rollout_table_max_over_sd"] = float(
                np.max(np.abs(centre - np.ravel(table)) / np.sqrt(np.maximum(var, 1e-300))))
    table = spec.rollout_arrays.get("table_y")
    base = np.ravel(table) if table is not None else centre
    info["tabulated"] = (f"sparse samples tabulated on the rollout's {g.size}-point grid, centred on "
                         + ("its table (the exact mean)" if table is not None else "the sampler's mean"))
    return TabulatedSamples(g, vals - centre + base)


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


def sample_model(stem: str | Path, name: str, settings: UQSettings, seed: int, out_npz: str | Path,
                 diagnostics_out: str | Path) -> SampleSet:
    """S samples of one saved gradient model (``stem``.npz/.json) -> ``out_npz`` plus its
    diagnostics JSON; the seed is ``uq_seed(seed, name)``."""
    spec, Z, grid = load_gp_spec(stem, name)
    comp, info = draw_model_samples(spec, settings, uq_seed(seed, name), Z, grid)
    write_npz(out_npz, **comp.to_arrays())
    write_json({"settings": settings.to_dict(), "model": info}, diagnostics_out)
    return comp


def load_samples(paths: dict[str, str | Path], kernel_tol: float = 0.0) -> dict[str, SampleSet]:
    """Sample sets by model name from their .npz files; all must have the same S.
    ``kernel_tol`` > 0: kernel sums truncated below kernel_tol sigma_f^2 (CompressedSamples)."""
    out = {name: samples_from_arrays(load_npz(p)) for name, p in paths.items()}
    if kernel_tol > 0:
        out = {n: (s.truncate(kernel_tol) if isinstance(s, CompressedSamples) else s) for n, s in out.items()}
    sizes = {m: s.n_samples for m, s in out.items()}
    if len(set(sizes.values())) > 1:
        raise ValueError(f"UQ samples have different S per model: {sizes}")
    return out
