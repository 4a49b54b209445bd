"""The learned constitutive laws as tables: input grid, posterior mean and sd, the covered range.

For each learned objective law (``obj_m``, and ``obj_n1`` / ``obj_n2`` where learned, eq. (10):
the local resultants n1, n2, m as functions of the strains nu1, nu2, kappa) and each of its
inputs x_j, one table row per grid point of x_j over the covered range [lo_j, hi_j] (the
training inputs' min and max, mirrored samples included) widened by ``pad`` x (hi_j - lo_j) on
both sides, the other inputs at their training medians:

* ``mean``: the posterior mean the rollout integrates (the model's saved rollout evaluator);
* ``sd``: the latent posterior sd of the same GP (its hyperparameters and basis) conditioned on
  a seeded subset of at most ``max_points`` of its training points (an exact sd over all n
  points would cost O(n^3); conditioning on fewer points can only widen the sd, so the band is
  conservative inside the covered range and exact in its growth beyond it, where the basis
  coefficients' uncertainty and the prior variance take over), multiplied by ``sd_scale`` =
  max(1, c), c the delete-a-block jackknife scale over ``band_blocks`` contiguous time blocks
  of those points (``crgpr.gp.sampling.heldout_block_scale``, the UQ path's ``heldout_jackknife``):
  the targets' errors are correlated along the trajectory, so where the mean moves more when
  one block is left out than the latent band allows (a law learned from exact full-state
  moments: sigma_n ~ 1e-5 of the law, its finite-difference targets' systematic error not in
  it) the band widens by that factor; it is never narrowed (the jackknife of a local estimator
  does not see extrapolation, the latent band does). The scale c is a median over the record,
  so where the mean moves more than elsewhere (a law along s whose errors run along the
  trajectory at a few segments only) the band also takes the jackknife variance V_jk(x) of the
  mean at x itself (``gp.sampling.jackknife_variance``): var = max(c^2 v(x), V_jk(x)), the
  larger of two estimates of the same variance; and never below ``sd_floor`` =
  sigma_n / sqrt(band_blocks) (sigma_n: the law GP's noise sd), added in quadrature: with
  errors correlated along the trajectory the record holds about ``band_blocks`` independent
  samples of them, not n (the held-out rules' unit, ``learning.law_choice``), and a bias common
  to every block (a finite-difference or discretisation error of the targets, the same in each
  block) moves no jackknife estimate; the floor is uniform in the inputs, so it says nothing of
  where the data end, and the bending law's reach (``learning.extrapolation``) is taken on the
  band without it and without V_jk (``floor`` False: a leave-one-block-out mean moves most
  where one block alone holds the data, the reach is the latent band's). ``band_blocks`` 0:
  the latent band;
* ``nominal``: the nominal rod's law at the same inputs (n1 = EA (nu1 - nu1_0), n2 = GA (nu2 -
  nu2_0), m = EI (kappa - kappa0));
* ``covered``: whether x_j lies inside [lo_j, hi_j];
* ``at_s``: for a law with the arclength s as an input (a bending law varying along the rod,
  ``law_choice``), the grid of every other input is repeated at ``s_points`` values of s evenly
  over its covered range (so EI(s) can be read off); for a bending law without s whose warp
  shifts its rest curvature along the rod (``warp.rest_shift``), at ``s_points`` values of s
  from the first segment's mid-point to the last's; NaN otherwise and for the s grid itself.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.gp import GP, Table1D, load_evaluator
from crgpr.gp.sampling import (
    ExactPosterior,
    heldout_block_scale,
    jackknife_variance,
    scaled_spec,
    subset_spec,
)
from crgpr.learning.law_choice import standin_departure
from crgpr.learning.warp import Warp, has_rest_shift, law_factor, segment_positions, shifted_kappa, warp_sd
from crgpr.physics.params import RodParams

LAW_MODELS: tuple[str, ...] = ("obj_m", "obj_n1", "obj_n2")


def covered_ranges(stem: str | Path, features: list[str]) -> dict[str, list[float]]:
    """[min, max] of each training input of a saved model (its ``X``)."""
    with np.load(Path(stem).with_suffix(".npz"), allow_pickle=False) as f:
        X = np.asarray(f["X"], dtype=float)
    return {name: [float(X[:, j].min()), float(X[:, j].max())] for j, name in enumerate(features)}


def nominal_law(name: str, features: list[str], X: np.ndarray, params: RodParams) -> np.ndarray:
    """The nominal rod's resultant of law ``name`` at rows X over ``features`` (NaN if an input is absent)."""
    col = {"obj_n1": ("nu1", params.EA, params.nu1_0), "obj_n2": ("nu2", params.GA, params.nu2_0),
           "obj_m": ("kappa", params.EI, params.kappa0)}[name]
    if col[0] not in features:
        return np.full(X.shape[0], np.nan)
    return col[1] * (X[:, features.index(col[0])] - col[2])


def _mean(stem: Path, X: np.ndarray) -> np.ndarray:
    ev = load_evaluator(stem)
    return np.asarray(ev(X[:, 0]) if isinstance(ev, Table1D) else ev(X), dtype=float).ravel()


@dataclass
class _Band:
    """A law's band (module docstring, ``sd``): its GP (scaled by ``c``), ``floor`` and the
    leave-one-block-out posteriors of its pointwise jackknife (empty: none)."""

    gp: GP
    c: float
    floor: float
    blocks: list[ExactPosterior]

    def sd(self, X: np.ndarray) -> np.ndarray:
        """sqrt(max(c^2 var, V_jk) + floor^2) at rows X (module docstring)."""
        var = np.asarray(self.gp.predict(X, return_var=True)[1], dtype=float).ravel()
        if self.blocks:
            var = np.maximum(var, jackknife_variance(self.blocks, X))
        return np.sqrt(var + self.floor**2)


def _sd_model(stem: Path, max_points: int, seed: int, band_blocks: int, systematic: bool) -> _Band:
    """The band of a law (module docstring, ``sd``): ``systematic`` False, its latent band widened
    by the global jackknife scale alone (no floor, no pointwise jackknife)."""
    from crgpr.uq.samples import load_gp_spec  # rows time-major, an odd law's reflections interleaved

    spec, _, _ = load_gp_spec(stem, stem.name, sampled=False)
    idx = np.arange(spec.Xs.shape[0])
    if idx.size > max_points:
        idx = np.sort(np.random.default_rng(seed).choice(idx.size, size=max_points, replace=False))
    gp = subset_spec(spec, idx)
    c, posts = 1.0, []
    if band_blocks and idx.size >= 2 * band_blocks:
        c = max(1.0, float(heldout_block_scale(gp, band_blocks, None, "jackknife", max_points,
                                               posteriors=posts if systematic else None)[0]))
    floor = 0.0
    if band_blocks and systematic:
        floor = float(json.loads(stem.with_suffix(".json").read_text())["sigma_n"]) / np.sqrt(band_blocks)
    return _Band(scaled_spec(gp, c) if c > 1.0 else gp, c, floor, posts)


def law_table(stem: str | Path, name: str, features: list[str], params: RodParams, n_grid: int, pad: float,
              max_points: int, seed: int, s_points: int, band_blocks: int, floor: bool,
              warp: Warp | None = None, warp_cov: np.ndarray | None = None,
              truncation: np.ndarray | None = None) -> pd.DataFrame:
    """One law's table (see module docstring): columns law, input, x, mean, sd, nominal, covered,
    covered_lo, covered_hi, sd_points, sd_scale, sd_floor, at_s (``floor`` False: the band without
    its floor and its pointwise jackknife, ``sd_floor`` 0). ``warp``: the bending law's record-fit warp
    (``learning.record_fit``: center, kappa scale, coefficients), which scales mean and sd;
    ``warp_cov``: its coefficients' covariance, whose sd of the warp adds to the band:
    sd^2 = (w sd_law)^2 + (m_law sd_w)^2 (``truncation``: with the warp's truncation estimate,
    ``warp.warp_sd``)."""
    stem = Path(stem)
    with np.load(stem.with_suffix(".npz"), allow_pickle=False) as f:
        Xt = np.asarray(f["X"], dtype=float)
    band = _sd_model(stem, max_points, seed, band_blocks, floor)
    med = np.median(Xt, axis=0)
    js = features.index("s") if "s" in features else None
    L = params.N * params.ds
    if js is not None:
        s_at = np.linspace(Xt[:, js].min(), Xt[:, js].max(), s_points)
    elif has_rest_shift(warp):  # a law without s, evaluated along the rod at its warp's rest shift
        s_at = L * np.linspace(*segment_positions(params.N)[[0, -1]], s_points)
    else:
        s_at = [np.nan]
    rows = []
    for j, feat in enumerate(features):
        lo, hi = float(Xt[:, j].min()), float(Xt[:, j].max())
        w = pad * max(hi - lo, 1e-12)
        g = np.linspace(lo - w, hi + w, n_grid)
        for sv in ([np.nan] if j == js else s_at):
            X = np.tile(med, (n_grid, 1))
            if np.isfinite(sv):
                X[:, js] = sv
            X[:, j] = g
            s_rel = X[:, js] / L if js is not None else (np.full(n_grid, sv / L) if np.isfinite(sv) else None)
            for i in _curvature_columns(features):  # the warp's rest shift moves the law's curvature inputs
                X[:, i] = shifted_kappa(X[:, i], s_rel, warp)
            mean, sd = _warped(_mean(stem, X), band.sd(X),
                               None if warp is None else X[:, features.index("kappa")], warp, warp_cov, s_rel,
                               truncation)
            rows.append(pd.DataFrame({"law": name, "input": feat, "x": g, "mean": mean, "sd": sd,
                                      "nominal": nominal_law(name, features, X, params),
                                      "covered": (g >= lo) & (g <= hi), "covered_lo": lo, "covered_hi": hi,
                                      "sd_points": int(band.gp.Xs.shape[0]), "sd_scale": band.c,
                                      "sd_floor": band.floor, "at_s": float(sv)}))
    return pd.concat(rows, ignore_index=True)


def _curvature_columns(features: list[str]) -> list[int]:
    """The columns of a bending law's inputs that are curvatures (kappa and its neighbours')."""
    return [i for i, f in enumerate(features) if f.startswith("kappa")]


def _warped(mean: np.ndarray, sd: np.ndarray, kappa: np.ndarray | None, warp: Warp | None,
            warp_cov: np.ndarray | None, s_rel: np.ndarray | None = None,
            truncation: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Mean and sd of a law m (mean, sd at the curvatures ``kappa`` and relative arclengths
    ``s_rel`` = s/L, None for a law without s) times its record-fit ``warp`` w(kappa) v(s): m w v
    and |w v| sd, or sqrt((w v sd)^2 + (m sd_wv)^2) with the warp's coefficient covariance (and
    its ``truncation`` estimate, ``warp.warp_sd``); unchanged without a warp."""
    if warp is None:
        return mean, sd
    w = law_factor(kappa, s_rel, warp)
    if warp_cov is None:
        return mean * w, np.abs(w) * sd
    return mean * w, np.sqrt((w * sd) ** 2 + (mean * warp_sd(kappa, s_rel, warp, warp_cov, truncation)) ** 2)


def warped_nominal_table(params: RodParams, warp: Warp, warp_cov: np.ndarray | None, n_grid: int, pad: float,
                         truncation: np.ndarray | None = None, choice: dict[str, Any] | None = None
                         ) -> pd.DataFrame:
    """The table of a nominal bending law EI (kappa - kappa0) that the record fit warped
    (``law_table``'s columns; input kappa, covered range the warp's [c - kappa_s, c + kappa_s]):
    mean m w, sd from the warp (0 without the warp's covariance) and, where the data chose the
    nominal law (``choice``: its ``law_choice`` entry), the departure of the law's richer
    stand-in (``law_choice.standin_departure``) times |w|; sd_points 0, sd_scale 1, sd_floor 0."""
    c, ks = float(warp[0]), float(warp[1])
    lo, hi = c - ks, c + ks
    g = np.linspace(lo - pad * (hi - lo), hi + pad * (hi - lo), n_grid)
    m = params.EI * (g - params.kappa0)
    mean, sd = _warped(m, standin_departure(g, choice), g, warp, warp_cov, None, truncation)
    return pd.DataFrame({"law": "obj_m", "input": "kappa", "x": g, "mean": mean, "sd": sd, "nominal": m,
                         "covered": (g >= lo) & (g <= hi), "covered_lo": lo, "covered_hi": hi,
                         "sd_points": 0, "sd_scale": 1.0, "sd_floor": 0.0, "at_s": np.nan})


def law_tables(model_dir: str | Path, trained: list[str], params: RodParams, settings: dict[str, Any],
               seed: int, floor: bool, warp: Warp | None = None, warp_cov: np.ndarray | None = None,
               truncation: np.ndarray | None = None, choice: dict[str, Any] | None = None) -> pd.DataFrame:
    """The tables of every learned law of a ``crgpr learn`` directory (``settings``: the config's
    ``camera.learn.law_table``: n_grid, pad, max_points, s_points, band_blocks; ``floor``: the
    band with its ``sd_floor``, ``law_table``; ``warp``,
    ``warp_cov``, ``truncation``: the bending law's record-fit warp, its coefficient covariance and
    truncation estimate, ``law_table``; ``choice``: the bending law's ``law_choice`` entry, the
    band of a nominal law the data chose, ``warped_nominal_table``;
    a bending law left nominal but warped is tabulated by ``warped_nominal_table``)."""
    out = []
    if warp is not None and "obj_m" not in trained:
        out.append(warped_nominal_table(params, warp, warp_cov, int(settings["n_grid"]),
                                        float(settings["pad"]), truncation, choice))
    for name in (m for m in LAW_MODELS if m in trained):
        stem = Path(model_dir) / name
        meta = json.loads(stem.with_suffix(".json").read_text())
        out.append(law_table(stem, name, list(meta["features"]), params, int(settings["n_grid"]),
                             float(settings["pad"]), int(settings["max_points"]), seed,
                             int(settings["s_points"]), int(settings["band_blocks"]), floor,
                             *((warp, warp_cov, truncation) if name == "obj_m" else (None, None, None))))
    return pd.concat(out, ignore_index=True) if out else pd.DataFrame()


def bending_law_at_segments(model_dir: str | Path, trained: list[str], params: RodParams, kappa: np.ndarray,
                            max_points: int, seed: int, band_blocks: int, warp: Warp | None = None,
                            warp_cov: np.ndarray | None = None, truncation: np.ndarray | None = None,
                            choice: dict[str, Any] | None = None, with_sd: bool = True
                            ) -> tuple[np.ndarray, np.ndarray]:
    """The bending law m of a ``crgpr learn`` directory at the curvatures ``kappa`` (n,) for every
    segment j at its own arclength s_j (``features.segment_arclength``): posterior mean and sd,
    each (n, N) (``with_sd`` False: the mean alone, sd 0). A learned ``obj_m``: its rollout
    evaluator's mean and the sd of ``law_table`` with its floor (inputs other than kappa and s at
    their training medians); a nominal one (not in
    ``trained``): EI (kappa - kappa0) of ``params`` with the sd of its richer stand-in's departure
    where the data chose it (``choice``: its ``law_choice`` entry; else 0). Either times the
    record-fit ``warp`` where the model has one (``learning.record_fit``)."""
    from crgpr.learning.features import segment_arclength

    kappa = np.asarray(kappa, dtype=float).ravel()
    N = params.N
    if "obj_m" not in trained:
        m = np.repeat((params.EI * (kappa - params.kappa0))[:, None], N, axis=1)
        sd = np.repeat(standin_departure(kappa, choice)[:, None], N, axis=1)
        return _warped(m, sd, kappa[:, None], warp, warp_cov, None, truncation)
    stem = Path(model_dir) / "obj_m"
    features = list(json.loads(stem.with_suffix(".json").read_text())["features"])
    with np.load(stem.with_suffix(".npz"), allow_pickle=False) as f:
        med = np.median(np.asarray(f["X"], dtype=float), axis=0)
    band = _sd_model(stem, max_points, seed, band_blocks, True) if with_sd else None
    s, s_rel = segment_arclength(N, params.ds), segment_positions(N)
    mean, sd = np.empty((kappa.size, N)), np.empty((kappa.size, N))
    at = np.empty((kappa.size, N))  # the curvature each segment's law is evaluated at (the warp's rest shift)
    along = "s" in features or has_rest_shift(warp)  # a law of its own at each segment
    for j in range(N):
        X = np.tile(med, (kappa.size, 1))
        X[:, features.index("kappa")] = kappa
        if "s" in features:
            X[:, features.index("s")] = s[j]
        if along:
            for i in _curvature_columns(features):
                X[:, i] = shifted_kappa(X[:, i], s_rel[j:j + 1], warp)
        at[:, j] = X[:, features.index("kappa")]
        mean[:, j] = _mean(stem, X)
        sd[:, j] = 0.0 if band is None else band.sd(X)
        if not along:  # the same law for every segment
            mean[:, j:], sd[:, j:], at[:, j:] = mean[:, [j]], sd[:, [j]], at[:, [j]]
            break
    return _warped(mean, sd, at, warp, warp_cov, s_rel, truncation)


def bending_tangent(model_dir: str | Path, trained: list[str], params: RodParams, lo: float, hi: float,
                    n_grid: int, warp: Warp | None = None) -> dict[str, Any]:
    """The least tangent stiffness dm/dkappa of a ``crgpr learn`` directory's bending law as its
    rollouts integrate it inside [lo, hi] (learned or nominal, times its record-fit ``warp``; every
    segment at its own s, ``bending_law_at_segments``), by differences on ``n_grid`` points:
    ``min_over_EI`` (in units of the nominal EI), ``at_kappa`` [1/m] and ``segment`` where it is,
    ``kappa_range``. A passive elastic rod's stored energy is convex in its curvature (eq. (10)),
    its tangent stiffness positive; a negative one lets a segment snap between two curvatures
    under one moment."""
    g = np.linspace(float(lo), float(hi), int(n_grid))
    m = bending_law_at_segments(model_dir, trained, params, g, 0, 0, 0, warp, with_sd=False)[0]
    d = np.diff(m, axis=0) / np.diff(g)[:, None]
    i, j = np.unravel_index(int(np.argmin(d)), d.shape)
    return {"min_over_EI": float(d[i, j] / params.EI), "at_kappa": float(0.5 * (g[i] + g[i + 1])),
            "segment": int(j), "kappa_range": [float(lo), float(hi)]}
