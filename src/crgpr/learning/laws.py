"""The rest state of a learned bending law, estimated from the data (paper Sec. II: unknown laws).

A rod with a symmetric cross-section has a bending moment odd about its rest curvature k_r,
m(2 k_r - k) = -m(k) (the discrete law behind the learned m of eq. (10)); mirroring training
samples about k_r lets a record that bends the rod mostly one way teach the law both ways.
Mirroring about the *nominal* kappa0 is wrong for a rod whose rest curvature differs from it,
and mirroring is wrong altogether for a law that is not odd about any curvature. So both the
rest curvature and the symmetry are decided from the samples (kappa_i, m_i) of the law:

* the rest curvature c: the odd law m = sum_{k odd <= D} a_k (kappa - c)^k (``degree`` D odd)
  by profile least squares (the coefficients a_k in closed form for each c; c on a grid over
  the samples' range widened by that range on both sides, then refined by a bounded scalar
  search);
* the symmetry: the odd law about that c with D + 1 odd terms (degree 2 D + 1) against the
  general polynomial of degree D in kappa (no symmetry), the same number of coefficients. At
  equal degree the general law has about twice the odd law's terms, and on a record that bends
  the rod mostly one way (where mirroring matters) it wins by flexibility, not by asymmetry: a
  saturating law, odd about 0, fitted to curvatures on one side, lost to the general cubic by
  a held-out log ratio of 1.6 +- 0.19 at D = 3 (and of 3.0 +- 0.8 at D = 7);
* decision by held-out time blocks: the samples (time-major rows, as ``training_data`` returns
  them) are cut into ``blocks`` contiguous blocks; each law is fitted without one block (the
  odd law about the c of that fit) and predicts it; the odd law is used (and the samples
  mirrored about its c) unless the general law predicts the held-out blocks consistently
  better: the mean over blocks of log(odd error / general error) above 1.96 standard errors
  (blocks as independent units): the symmetric law is kept where the data cannot tell the two
  apart. Contiguous blocks, not single samples: the
  samples of one trajectory are correlated in time, so a per-sample criterion (BIC) would take
  any small asymmetry of one record for a law.
* the degree D: the configured one, raised by 2 (up to a maximum) while the next odd law, about
  its own c, predicts the held-out blocks better (``select_degree``, ``pooled_gain``): a strongly
  stiffening law is far from its cubic at the record's largest curvatures, and the cubic's
  misfit there moves c;
* the band of c: the delete-a-block jackknife over the same blocks, c +- 1.96 se (95 %).
* the nominal rest curvature kappa0 (where given): the odd law about kappa0 against the odd law
  about each held-out fit's own c, on the same blocks and by the same rule. The jackknife band
  of c measures only how much c moves between blocks; from noise-free full-state moments it is
  a few 1e-3 /m wide and a small misfit of the polynomial law moves c by more (a graded rod,
  odd about 0: c = 0.0063 /m, band 0.0007-0.0119), so the band alone would refuse kappa0 where
  the data predict no better with c. kappa0 is used where either holds (``mirror_about``).

Noisy curvature inputs (camera data) attenuate the fitted slope (errors in variables), which
moves c away from the samples' mean curvature; the jackknife band does not include that bias.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass

import numpy as np

Z95 = 1.959963984540054  # two-sided 95 % normal quantile


@dataclass(frozen=True)
class RestState:
    """Estimated rest curvature of a bending law and the symmetry decision (JSON-able)."""

    kappa_rest: float  # c of the odd law fitted to all samples [1/m]
    band_lo: float  # c - 1.96 se (delete-a-block jackknife) [1/m]
    band_hi: float  # c + 1.96 se [1/m]
    se: float  # jackknife standard error of c [1/m]
    heldout_mse_odd: float  # held-out-block mean squared error of the odd law (degree 2 D + 1) [(N m)^2]
    heldout_mse_general: float  # ... of the general polynomial [(N m)^2]
    heldout_log_ratio: float  # mean over blocks of log(odd / general held-out squared error) [-]
    heldout_log_ratio_se: float  # its standard error over the blocks [-]
    symmetric: bool  # the odd law is used: samples mirrored about kappa_rest
    degree: int
    blocks: int
    kappa0_nominal: float | None = None  # the nominal rest curvature compared (None: not compared) [1/m]
    heldout_mse_nominal: float | None = None  # held-out-block mean squared error of the odd law about it
    heldout_log_ratio_nominal: float | None = None  # mean over blocks of log(about kappa0 / about c) [-]
    heldout_log_ratio_nominal_se: float | None = None  # its standard error over the blocks [-]
    nominal_rejected: bool | None = None  # the odd law about c predicts consistently better than about kappa0
    degree_steps: list | None = None  # the higher degrees tried (select_degree): degree, log ratio, se, taken

    def to_dict(self) -> dict:
        return asdict(self)

    def mirror_about(self, kappa0_nominal: float, estimate: bool = True) -> float | None:
        """The curvature the law's samples are mirrored about: none for a law that is not odd;
        the nominal kappa0 where the estimate's band contains it (the data cannot tell the two
        apart; the nominal one is exact for the declared rod) or where the held-out blocks
        predict no better about the estimate than about kappa0 (mean log ratio <= 0: the band
        is too narrow for the law's misfit); else the estimate, or none where ``estimate`` is
        False (a law along s, whose rest curvature may vary along s).

        The band is the test of c; the held-out blocks only veto it, by the sign of their mean
        and not by its significance: a rest curvature shifts the moment by EI (c - kappa0), small
        against the targets' noise in every block (the held-out test has little power) but a
        bend of the whole rod at rest."""
        if not self.symmetric:
            return None
        compared = self.kappa0_nominal is not None and self.kappa0_nominal == kappa0_nominal
        about_c_better = compared and self.heldout_log_ratio_nominal is not None \
            and self.heldout_log_ratio_nominal > 0.0
        if self.band_lo <= kappa0_nominal <= self.band_hi or (compared and not about_c_better):
            return kappa0_nominal
        return self.kappa_rest if estimate else None


def heldout_blocks(n: int, blocks: int) -> list[np.ndarray]:
    """Boolean masks of ``blocks`` contiguous blocks of n time-ordered rows: the held-out unit of
    every choice the data decide in ``learning`` (the samples of one trajectory are correlated in
    time, so blocks, not single samples, are the independent units)."""
    edges = np.linspace(0, n, blocks + 1).astype(int)
    out = []
    for b in range(blocks):
        test = np.zeros(n, dtype=bool)
        test[edges[b]:edges[b + 1]] = True
        out.append(test)
    return out


def log_error_ratio(e_simple: float, e_richer: float) -> float:
    """d_b = log(simpler law's / richer law's held-out squared error) of one block."""
    return math.log(max(e_simple, 1e-300) / max(e_richer, 1e-300))


def consistent_gain(d: np.ndarray) -> tuple[float, float, bool]:
    """(mean of d_b over the blocks, its standard error, whether the richer law predicts the
    held-out blocks consistently better: mean > 1.96 standard errors)."""
    d = np.asarray(d, dtype=float)
    se = float(np.std(d, ddof=1)) / math.sqrt(d.size)
    return float(d.mean()), se, bool(d.mean() > Z95 * se)


def pooled_gain(e_simple: np.ndarray, e_richer: np.ndarray) -> tuple[float, float, bool]:
    """(log of the simpler law's over the richer law's total held-out squared error, its
    delete-a-block jackknife standard error, whether it exceeds 1.96 of it), from the per-block
    errors. Unlike ``consistent_gain`` the blocks are weighted by their error: a law that differs
    from the simpler one only where the record reaches large strains (its first, large-amplitude
    blocks) counts there."""
    es, er = np.asarray(e_simple, dtype=float), np.asarray(e_richer, dtype=float)
    ratio = log_error_ratio(float(es.sum()), float(er.sum()))
    loo = np.array([log_error_ratio(float(es.sum() - es[b]), float(er.sum() - er[b]))
                    for b in range(es.size)])
    se = jackknife_se(loo)
    return ratio, se, bool(ratio > Z95 * se)

def jackknife_se(values: np.ndarray) -> float:
    """Delete-a-block jackknife standard error of an estimate from its leave-one-block-out values."""
    v = np.asarray(values, dtype=float)
    return math.sqrt((v.size - 1) / v.size * float(np.sum((v - v.mean()) ** 2)))


def _odd_design(u: np.ndarray, degree: int) -> np.ndarray:
    return np.stack([u**k for k in range(1, degree + 1, 2)], axis=-1)


def _lstsq(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, float]:
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ coef
    return coef, float(r @ r)


def _group_rows(groups: np.ndarray | None, n: int) -> list[np.ndarray]:
    """Row indices of each group (one group of all rows where ``groups`` is None)."""
    if groups is None:
        return [np.arange(n)]
    return [np.flatnonzero(groups == g) for g in np.unique(groups)]


def _odd_rss(kappa: np.ndarray, m: np.ndarray, rows: list[np.ndarray], c: float, degree: int,
             scale: float) -> float:
    return sum(_lstsq(_odd_design((kappa[r] - c) / scale, degree), m[r])[1] for r in rows if r.size)


def _zero_crossings(kappa: np.ndarray, m: np.ndarray, rows: list[np.ndarray]) -> np.ndarray:
    """The curvature where each group's least-squares line m = a + b kappa vanishes (groups with
    b > 0): where a group's samples straddle its zero moment, the rest curvature is close to it."""
    out = []
    for r in rows:
        if r.size < 3 or np.ptp(kappa[r]) <= 0.0:
            continue
        b, a = np.polyfit(kappa[r], m[r], 1)
        if b > 0.0 and np.isfinite(a / b):
            out.append(-a / b)
    return np.array(out, dtype=float)


def _odd_fit(kappa: np.ndarray, m: np.ndarray, degree: int, scale: float, rows: list[np.ndarray]) -> float:
    """c of the odd law (coefficients of its own in each group of ``rows``, one c) minimising the
    squared residual (profile least squares): the best point of a grid over the samples' range
    widened by it on both sides, refined by a bounded search between its neighbours. With
    groups whose curvatures span little (a rod's tip segments) the residual has a valley about
    the true c narrower than the grid's step, which the grid can miss altogether (a softening
    pre-curved rod's full state: c = 176 /m for a true 1.5); so each group's zero crossing
    (``_zero_crossings``) and their median are candidates too, each refined by a zoom (grids of
    21 points over +-1, +-0.1, +-0.01 grid steps) and a bounded search; the lowest residual wins."""
    from scipy.optimize import minimize_scalar  # here: most rules import this module, few fit a law

    lo, hi = float(kappa.min()), float(kappa.max())
    span = max(hi - lo, 1e-12)

    def rss(c: float) -> float:
        return _odd_rss(kappa, m, rows, c, degree, scale)

    grid = np.linspace(lo - span, hi + span, 301)
    vals = np.array([rss(c) for c in grid])
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    res = minimize_scalar(rss, bounds=(a, b), method="bounded", options={"xatol": 1e-10 * span})
    best, best_rss = float(grid[i]), float(vals[i])
    if res.fun <= best_rss:
        best, best_rss = float(res.x), float(res.fun)
    cross = _zero_crossings(kappa, m, rows)
    cross = cross[(cross >= grid[0]) & (cross <= grid[-1])]
    if cross.size == 0:
        return best
    step = grid[1] - grid[0]
    starts = np.r_[cross, np.median(cross)]
    c0 = float(starts[int(np.argmin([rss(c) for c in starts]))])
    for width in (step, step / 10.0, step / 100.0):
        zoom = c0 + np.linspace(-width, width, 21)
        c0 = float(zoom[int(np.argmin([rss(c) for c in zoom]))])
    w = step / 1000.0
    res = minimize_scalar(rss, bounds=(c0 - w, c0 + w), method="bounded", options={"xatol": 1e-10 * span})
    r0 = rss(c0)
    c1, r1 = (float(res.x), float(res.fun)) if res.fun <= r0 else (c0, r0)
    return c1 if r1 < best_rss else best


def _heldout_error(kappa: np.ndarray, m: np.ndarray, train: np.ndarray, test: np.ndarray,
                   design: Callable[[np.ndarray], np.ndarray], rows: list[np.ndarray]) -> float:
    """Squared error on the ``test`` rows of a law fitted (per group) on the ``train`` rows."""
    err = 0.0
    for r in rows:
        tr, te = r[train[r]], r[test[r]]
        if te.size == 0:
            continue
        coef = _lstsq(design(kappa[tr]), m[tr])[0] if tr.size else np.zeros(design(kappa[te]).shape[1])
        err += float(np.sum((m[te] - design(kappa[te]) @ coef) ** 2))
    return err


def _general_design(kappa: np.ndarray, center: float, scale: float, degree: int) -> np.ndarray:
    u = (kappa - center) / scale
    return np.stack([u**k for k in range(degree + 1)], axis=-1)


def _fits_blocks(n: int, rows: list[np.ndarray], degree: int, blocks: int) -> bool:
    """Enough samples for every held-out fit of the odd law (2 D + 2 coefficients) in every group."""
    return blocks >= 2 and n >= blocks * (2 * degree + 3) and min(r.size for r in rows) >= 4 * (degree + 1)


def select_degree(kappa: np.ndarray, m: np.ndarray, degree: int, max_degree: int, blocks: int,
                  rows: list[np.ndarray], scale: float) -> tuple[int, float, list[dict[str, float]]]:
    """The odd degree D of the law c is fitted with: ``degree``, raised by 2 while the odd law of
    the next degree (about its own c) predicts the held-out blocks better by ``pooled_gain`` (a
    strongly nonlinear law differs from its cubic stand-in where the record reaches large
    curvatures, and there the cubic's misfit moves c), up to ``max_degree``. Returns D, the c of
    the odd law of degree D fitted to all samples, and the steps tried (degree, log ratio, se,
    taken)."""
    masks = heldout_blocks(kappa.size, blocks)

    def fit(d: int) -> tuple[float, np.ndarray]:
        c = _odd_fit(kappa, m, d, scale, rows)
        return c, np.array([_heldout_error(kappa, m, ~t, t, lambda k: _odd_design((k - c) / scale, d), rows)
                            for t in masks])
    steps: list[dict[str, float]] = []
    c, e = fit(degree)
    while degree + 2 <= max_degree and _fits_blocks(kappa.size, rows, degree + 2, blocks):
        c_next, e_next = fit(degree + 2)
        ratio, se, better = pooled_gain(e, e_next)
        steps.append({"degree": degree + 2, "heldout_log_ratio": ratio, "heldout_log_ratio_se": se,
                      "taken": bool(better)})
        if not better:
            break
        degree, c, e = degree + 2, c_next, e_next
    return degree, c, steps


def rest_state(kappa: np.ndarray, m: np.ndarray, degree: int, blocks: int,
               groups: np.ndarray | None = None, kappa0: float | None = None,
               max_degree: int | None = None) -> RestState:
    """Rest curvature, its 95 % band and the symmetry decision from law samples (see module doc).

    ``kappa``, ``m``: (n,) curvature inputs and bending-moment targets, rows in time order;
    ``degree``: D, the odd degree of the law c is fitted with and the degree of the general law
    (the odd law it is compared with has degree 2 D + 1), raised up to ``max_degree`` where
    held-out blocks support it (``select_degree``; None: D as given); ``blocks``: contiguous
    held-out blocks (>= 2); ``groups``: (n,) labels of samples that share a law (the segments of
    a law that varies along the rod): each group has coefficients of its own, all share one rest
    curvature c; ``kappa0``: the nominal rest curvature, compared on the held-out blocks with c
    (module doc).
    """
    kappa = np.asarray(kappa, dtype=float).ravel()
    m = np.asarray(m, dtype=float).ravel()
    bad_max = max_degree is not None and (max_degree < degree or max_degree % 2 == 0)
    if degree < 1 or degree % 2 == 0 or bad_max:
        raise ValueError(f"rest_state: degree {degree} (max {max_degree}) must be odd and >= 1")
    rows = _group_rows(None if groups is None else np.asarray(groups).ravel(), kappa.size)
    # enough samples for every held-out fit of the odd law (2 D + 2 coefficients) in every group
    if not _fits_blocks(kappa.size, rows, degree, blocks):
        raise ValueError(f"rest_state: {kappa.size} samples cannot fill {blocks} blocks of a degree-{degree} "
                         "law" + ("" if groups is None else f" in each of {len(rows)} groups"))
    center = float(kappa.mean())
    scale = float(kappa.std()) or 1.0
    steps: list[dict[str, float]] = []
    if max_degree is not None:
        degree, c, steps = select_degree(kappa, m, degree, max_degree, blocks, rows, scale)
    else:
        c = _odd_fit(kappa, m, degree, scale, rows)
    cs, diff, d_nom, e_odd, e_gen, e_nom = [], [], [], 0.0, 0.0, 0.0
    for test in heldout_blocks(kappa.size, blocks):
        cb = _odd_fit(kappa[~test], m[~test], degree, scale, _subset_rows(rows, ~test))
        cs.append(cb)
        eo = _heldout_error(kappa, m, ~test, test,
                            lambda k, cb=cb: _odd_design((k - cb) / scale, 2 * degree + 1), rows)
        eg = _heldout_error(kappa, m, ~test, test, lambda k: _general_design(k, center, scale, degree), rows)
        e_odd, e_gen = e_odd + eo, e_gen + eg
        diff.append(log_error_ratio(eo, eg))
        if kappa0 is not None:
            en = _heldout_error(kappa, m, ~test, test,
                                lambda k: _odd_design((k - kappa0) / scale, 2 * degree + 1), rows)
            e_nom += en
            d_nom.append(log_error_ratio(en, eo))
    se = jackknife_se(np.array(cs))
    mse_odd, mse_gen = e_odd / kappa.size, e_gen / kappa.size
    # the general law only where it predicts the held-out blocks consistently better: the mean
    # over blocks of log(odd error / general error) above 1.96 of its standard error (blocks as
    # independent units; the log ratio is scale-free, so blocks of larger curvature do not dominate)
    mean, ratio_se, general = consistent_gain(np.array(diff))
    nominal = {}
    if kappa0 is not None:
        n_mean, n_se, rejected = consistent_gain(np.array(d_nom))
        nominal = {"kappa0_nominal": float(kappa0), "heldout_mse_nominal": e_nom / kappa.size,
                   "heldout_log_ratio_nominal": n_mean, "heldout_log_ratio_nominal_se": n_se,
                   "nominal_rejected": rejected}
    return RestState(kappa_rest=c, band_lo=c - Z95 * se, band_hi=c + Z95 * se, se=se,
                     heldout_mse_odd=mse_odd, heldout_mse_general=mse_gen,
                     heldout_log_ratio=mean, heldout_log_ratio_se=ratio_se,
                     symmetric=not general, degree=int(degree), blocks=int(blocks), degree_steps=steps,
                     **nominal)


def _subset_rows(rows: list[np.ndarray], keep: np.ndarray) -> list[np.ndarray]:
    """Group rows re-indexed into the rows where ``keep`` holds."""
    pos = np.cumsum(keep) - 1
    return [pos[r[keep[r]]] for r in rows]
