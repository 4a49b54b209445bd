"""Measured (camera) rod data: loading, validation, gross-outlier and geometry screening.

A measured file is a table, Parquet (``.parquet``) or CSV (``.csv``, e.g. a motion-capture
export; ``crgpr.io.read_table``), with one row per observation of one marker:
``t`` [s], the marker's place along the rod as either ``s`` [m] (arc length from the base,
markers anywhere) or ``node`` (an integer, s = node * ds on the model grid), and its position
``x``, ``y`` [m] in the model's frame (base at the origin unless a base marker s = 0 is given).
Any number >= 4 of markers; rows in any order. Following the paper's Remark in Sec. III-B,
positions are the measurement: angles and momenta are derived (``crgpr.measured.kinematics``).

Tolerated and reported (never silently):
* dropped frames and occlusions: missing rows or NaN/inf in x, y -> missing samples;
* gross outliers (a marker jumping for a frame, swapped markers): samples far from a
  running median of their own marker (``outlier_k`` robust standard deviations and at least
  ``outlier_min_m``), and samples that make the rod's geometry impossible (a chord between
  neighbouring markers longer than their arc-length distance by more than ``geometry_tol``,
  shorter than half of it, beyond ``outlier_k`` standard deviations of the chord's noise, or
  turning by more than 3 pi / 4) are excluded;
* a marker with fewer than ``min_samples`` usable samples is dropped.
Rejected with one line naming the file (``MeasuredDataError``): an empty or unreadable file, a
file that is neither ``.parquet`` nor ``.csv``, missing or non-numeric columns (naming the
column), non-finite t or s, s outside [0, L0], duplicate (t, marker) rows, times off a uniform
grid, a rate below ``min_rate_hz``, too few frames or markers, and a geometry that is
impossible in most frames (wrong s, units or base position).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.io import read_table

MARKER_COLUMNS: tuple[str, ...] = ("t", "x", "y")
PLACE_COLUMNS: tuple[str, ...] = ("s", "node")
MAX_TURN_RAD = 0.75 * math.pi  # turning between neighbouring chords beyond this: impossible
MIN_CHORD_RATIO = 0.5  # a chord shorter than half its arc length: impossible for this rod


class MeasuredDataError(ValueError):
    """The measured data file is unusable; the message names the file and the problem."""


@dataclass(frozen=True)
class ScreenSettings:
    """Validation and screening settings (config section ``discovery``; no defaults here)."""

    min_rate_hz: float
    min_samples: int
    outlier_k: float
    outlier_min_m: float
    geometry_tol: float

    @classmethod
    def config_keys(cls) -> tuple[str, ...]:
        """The keys of the ``discovery`` config section these settings read."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_config(cls, d: dict) -> ScreenSettings:
        return cls(float(d["min_rate_hz"]), int(d["min_samples"]), float(d["outlier_k"]),
                   float(d["outlier_min_m"]), float(d["geometry_tol"]))


@dataclass
class Measured:
    """Marker positions on a uniform time grid, NaN where missing or excluded.

    t (n_t,) [s]; s (n_m,) marker arc lengths [m], ascending; x, y (n_t, n_m) [m].
    ``missing_fraction`` (n_m,): share of frames without a finite sample (dropped rows, NaN);
    ``outliers`` (n_t, n_m): samples excluded by the screening; ``notes``: what was done.
    """

    t: np.ndarray
    s: np.ndarray
    x: np.ndarray
    y: np.ndarray
    source: str
    missing_fraction: np.ndarray
    outliers: np.ndarray
    notes: list[str] = field(default_factory=list)
    dropped_markers: list[float] = field(default_factory=list)

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.t)))

    @property
    def rate_hz(self) -> float:
        return 1.0 / self.dt

    @property
    def valid(self) -> np.ndarray:
        return np.isfinite(self.x) & np.isfinite(self.y)

    @property
    def has_base(self) -> bool:
        return bool(self.s[0] <= 1e-9)

    def summary(self) -> dict:
        """Report of the input: markers, missing and excluded samples per marker."""
        return {
            "n_frames": int(self.t.size), "n_markers": int(self.s.size),
            "t0_s": float(self.t[0]), "sample_rate_hz": self.rate_hz,
            "markers_s_m": [float(v) for v in self.s],
            "missing_fraction": [float(v) for v in self.missing_fraction],
            "outliers_excluded": [int(v) for v in self.outliers.sum(axis=0)],
            "outliers_total": int(self.outliers.sum()),
            "base_marker": self.has_base, "dropped_markers_s_m": list(self.dropped_markers),
            "notes": list(self.notes),
        }


def _numeric(df: pd.DataFrame, col: str, source: str) -> np.ndarray:
    raw = df[col]
    vals = pd.to_numeric(raw, errors="coerce")
    bad = vals.isna() & raw.notna()
    if bad.any():
        i = int(np.argmax(bad.to_numpy()))
        raise MeasuredDataError(f"{source}: column {col!r} has non-numeric value {raw.iloc[i]!r} at row {i}")
    try:
        return vals.to_numpy(dtype=float)
    except (TypeError, ValueError) as exc:
        raise MeasuredDataError(f"{source}: column {col!r} is not numeric") from exc


def validate_frame(df: pd.DataFrame, source: str, L0: float, ds: float, st: ScreenSettings
                   ) -> Measured:
    """Check a measured table, place it on a (t, marker) grid and screen it (module docstring)."""
    if not isinstance(df, pd.DataFrame) or len(df) == 0:
        raise MeasuredDataError(f"{source}: no rows")
    missing = [c for c in MARKER_COLUMNS if c not in df.columns]
    place = next((c for c in PLACE_COLUMNS if c in df.columns), None)
    if missing or place is None:
        need = missing + ([] if place else ["s or node"])
        raise MeasuredDataError(f"{source}: missing column(s) {need}; has {list(df.columns)}")
    t = _numeric(df, "t", source)
    loc = _numeric(df, place, source)
    x = _numeric(df, "x", source)
    y = _numeric(df, "y", source)
    for name, arr in (("t", t), (place, loc)):
        bad = ~np.isfinite(arr)
        if bad.any():
            raise MeasuredDataError(f"{source}: column {name!r} has {int(bad.sum())} NaN/non-finite "
                                    f"value(s) (first at row {int(np.argmax(bad))})")
    if place == "node":
        if np.any(loc != np.round(loc)) or loc.min() < 0:
            raise MeasuredDataError(f"{source}: column 'node' must hold non-negative integers")
        s = loc * ds
    else:
        s = loc
    if s.min() < -1e-9 or s.max() > L0 * (1.0 + 1e-6) + 1e-9:
        k = int(np.argmax((s < -1e-9) | (s > L0 * (1.0 + 1e-6) + 1e-9)))
        raise MeasuredDataError(f"{source}: column {place!r} puts a marker at s = {s[k]:.6g} m, "
                                f"outside the rod [0, {L0:g}] m (row {k})")
    s = np.clip(np.round(s, 9), 0.0, L0)
    marks, m_idx = np.unique(s, return_inverse=True)
    if marks.size < 4:
        raise MeasuredDataError(f"{source}: need at least 4 markers, got {marks.size} (s = {marks.tolist()})")
    times = np.unique(t)
    if times.size < 2:
        raise MeasuredDataError(f"{source}: only {times.size} distinct time(s)")
    dt = float(np.median(np.diff(times)))
    k_t = np.rint((t - times[0]) / dt)
    off = np.abs(t - times[0] - k_t * dt)
    if np.any(off > 0.1 * dt) or k_t.max() > 10 * times.size + 10:
        k = int(np.argmax(off))
        raise MeasuredDataError(f"{source}: uneven time sampling: t = {t[k]:.6g} s is off the uniform "
                                f"grid of step {dt:.6g} s (frames may be missing, not shifted)")
    if 1.0 / dt < st.min_rate_hz * (1.0 - 1e-9):
        raise MeasuredDataError(f"{source}: sampling rate {1.0 / dt:.4g} Hz is below the minimum "
                                f"{st.min_rate_hz:g} Hz")
    k_t = k_t.astype(int)
    n_t = int(k_t.max()) + 1
    key = k_t * marks.size + m_idx
    uniq, first, counts = np.unique(key, return_index=True, return_counts=True)
    if np.any(counts > 1):
        r = int(first[np.argmax(counts > 1)])
        raise MeasuredDataError(f"{source}: duplicate rows for t = {t[r]:.6g} s, {place} = {loc[r]:g} "
                                f"({int(counts.max())} rows)")
    X = np.full((n_t, marks.size), np.nan)
    Y = np.full((n_t, marks.size), np.nan)
    X[k_t, m_idx] = x
    Y[k_t, m_idx] = y
    bad = ~(np.isfinite(X) & np.isfinite(Y))
    X[bad] = np.nan
    Y[bad] = np.nan
    grid = times[0] + np.arange(n_t) * dt
    frames = int(np.sum(~bad.all(axis=1)))
    if frames < st.min_samples:
        raise MeasuredDataError(f"{source}: only {frames} frames with data; need at least {st.min_samples}")
    meas = Measured(grid, marks, X, Y, source, bad.mean(axis=0), np.zeros_like(bad))
    if bad.any():
        worst = int(np.argmax(meas.missing_fraction))
        meas.notes.append(f"{int(bad.sum())} missing samples (dropped frames or NaN); worst marker "
                          f"s = {marks[worst]:.3g} m misses {meas.missing_fraction[worst]:.1%}")
    screen(meas, st)
    return meas


def _mad(r: np.ndarray) -> np.ndarray:
    """Robust standard deviation per column (1.4826 MAD), 0 where a column has no data."""
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        mad = np.nanmedian(np.abs(r - np.nanmedian(r, axis=0)), axis=0) * 1.4826
    return np.nan_to_num(mad, nan=0.0)


def _cubic_prediction(a: np.ndarray) -> np.ndarray:
    """Standardised residual of each sample from the cubic through its four nearest
    neighbours in time (two each side inside the record, one-sided at its ends): for the
    neighbour offsets o and Lagrange weights w, (a_k - sum_i w_i a_{k+o_i}) / sqrt(1 + |w|^2),
    which has the camera noise's standard deviation; NaN where a neighbour is missing."""
    n = a.shape[0]
    r = np.full_like(a, np.nan)
    if n < 5:
        return r
    for k in range(n):
        lo = min(max(k - 2, 0), n - 5)
        offs = [o for o in range(lo - k, lo - k + 5) if o != 0]
        w = [math.prod((0.0 - oj) / (oi - oj) for oj in offs if oj != oi) for oi in offs]
        pred = sum(wi * a[k + oi] for wi, oi in zip(w, offs, strict=True))
        r[k] = (a[k] - pred) / math.sqrt(1.0 + sum(wi * wi for wi in w))
    return r


def _running_median(a: np.ndarray, half: int = 2) -> np.ndarray:
    """Median of the ``half`` neighbours on each side in time, the sample itself left out."""
    n = a.shape[0]
    pad = np.full((half,) + a.shape[1:], np.nan)
    ap = np.concatenate([pad, a, pad])
    shifts = [ap[half + k: half + k + n] for k in range(-half, half + 1) if k != 0]
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(np.stack(shifts), axis=0)


def screen(meas: Measured, st: ScreenSettings) -> None:
    """Exclude gross outliers and impossible geometry in place; drop starved markers."""
    X, Y = meas.x, meas.y
    out = np.zeros(X.shape, dtype=bool)
    sig = []
    for A in (X, Y):
        # a gross outlier departs both from the median of its neighbours (robust to a bad
        # neighbour) and from their cubic prediction (exact for smooth fast motion)
        r_med = A - _running_median(A)
        r_cub = _cubic_prediction(A)
        mad_med = _mad(r_med)
        mad_cub = _mad(r_cub)
        sig.append(float(np.median(mad_cub)))
        thr_med = np.maximum(st.outlier_k * mad_med, st.outlier_min_m)
        thr_cub = np.maximum(st.outlier_k * mad_cub, st.outlier_min_m / math.sqrt(2.0))
        far_med = np.abs(np.nan_to_num(r_med, nan=0.0)) > thr_med[None, :]
        far_cub = ~(np.abs(r_cub) <= thr_cub[None, :])  # NaN (a neighbour missing): median decides
        out |= far_med & far_cub
    X[out] = np.nan
    Y[out] = np.nan
    n_marker = int(out.sum())
    # chord lengths carry the noise of two markers: allow outlier_k of their std on top
    slack = st.outlier_k * math.sqrt(2.0) * max(sig)
    geo, frac_bad = _geometry_screen(meas, st.geometry_tol, slack)
    if frac_bad > 0.2:
        raise MeasuredDataError(f"{meas.source}: impossible geometry in {frac_bad:.0%} of the frames "
                                f"(median chord / arc length between neighbouring markers "
                                f"{_median_ratio(meas):.3g}); check the s/node column, the units (m) "
                                f"and that the base is at the origin when there is no s = 0 marker")
    X[geo] = np.nan
    Y[geo] = np.nan
    meas.outliers = out | geo
    if meas.outliers.any():
        meas.notes.append(f"{int(meas.outliers.sum())} outlier samples excluded ({n_marker} far from their "
                          f"marker's running median, {int(geo.sum())} with impossible geometry)")
    n_valid = np.sum(np.isfinite(X), axis=0)
    keep = n_valid >= st.min_samples
    if not keep.all():
        gone = meas.s[~keep]
        meas.dropped_markers = [float(v) for v in gone]
        meas.notes.append(f"markers at s = {[round(float(v), 4) for v in gone]} m dropped: fewer than "
                          f"{st.min_samples} usable samples")
        if keep.sum() < 4:
            raise MeasuredDataError(f"{meas.source}: fewer than 4 markers with {st.min_samples} usable "
                                    f"samples each")
        meas.s, meas.x, meas.y = meas.s[keep], X[:, keep], Y[:, keep]
        meas.missing_fraction, meas.outliers = meas.missing_fraction[keep], meas.outliers[:, keep]
    if np.sum(np.isfinite(meas.x).any(axis=1)) < st.min_samples:
        raise MeasuredDataError(f"{meas.source}: fewer than {st.min_samples} frames left after screening")


def _points(meas: Measured) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Marker positions with the base (origin when no s = 0 marker) prepended."""
    if meas.has_base:
        return meas.s, meas.x, meas.y
    z = np.zeros((meas.t.size, 1))
    return np.r_[0.0, meas.s], np.c_[z, meas.x], np.c_[z, meas.y]


def _median_ratio(meas: Measured) -> float:
    s, X, Y = _points(meas)
    ratio = np.hypot(np.diff(X, axis=1), np.diff(Y, axis=1)) / np.diff(s)[None, :]
    return float(np.nanmedian(ratio)) if np.isfinite(ratio).any() else float("nan")


def _frame_violations(s: np.ndarray, x: np.ndarray, y: np.ndarray, tol: float, slack: float
                      ) -> np.ndarray:
    """Per point of one frame, how many impossible chords/turns it takes part in."""
    n = s.size
    hits = np.zeros(n, dtype=int)
    dx, dy = np.diff(x), np.diff(y)
    arc = np.diff(s)
    chord = np.hypot(dx, dy)
    badc = (chord > arc * (1.0 + tol) + slack) | (chord < arc * MIN_CHORD_RATIO - slack)
    hits[:-1] += badc
    hits[1:] += badc
    ang = np.arctan2(dy, dx)
    turn = np.abs((np.diff(ang) + math.pi) % (2.0 * math.pi) - math.pi)
    badt = turn > MAX_TURN_RAD
    hits[:-2] += badt
    hits[1:-1] += badt
    hits[2:] += badt
    return hits


def _geometry_screen(meas: Measured, tol: float, slack: float) -> tuple[np.ndarray, float]:
    """Samples whose removal makes each frame's marker chain possible; share of bad frames."""
    s_all, X, Y = _points(meas)
    off = 0 if meas.has_base else 1
    excl = np.zeros(meas.x.shape, dtype=bool)
    n_bad = 0
    n_frames = 0
    for k in range(meas.t.size):
        ok = np.isfinite(X[k]) & np.isfinite(Y[k])
        if ok.sum() < 3:
            continue
        n_frames += 1
        idx = np.nonzero(ok)[0]
        hits = _frame_violations(s_all[idx], X[k, idx], Y[k, idx], tol, slack)
        if not hits.any():
            continue
        n_bad += 1
        while hits.any() and idx.size >= 3:
            cand = idx[hits == hits.max()]
            cand = cand[cand >= off] if (cand >= off).any() else cand  # never blame the virtual base
            j = int(cand[-1]) if cand.size else int(idx[-1])
            if j < off:
                break
            excl[k, j - off] = True
            idx = idx[idx != j]
            hits = _frame_violations(s_all[idx], X[k, idx], Y[k, idx], tol, slack)
        if hits.any():
            excl[k, :] = True
    return excl, n_bad / max(n_frames, 1)


def read_measured(path: str | Path) -> pd.DataFrame:
    """The table of a measured file (``.parquet`` or ``.csv``), unvalidated; ``MeasuredDataError``
    (one line naming the file) if it is missing, of another kind or unreadable."""
    try:
        return read_table(path)
    except (OSError, ValueError) as exc:
        raise MeasuredDataError(" ".join(str(exc).split())) from exc


def load_measured(path: str | Path, L0: float, ds: float, st: ScreenSettings) -> Measured:
    """Read, validate and screen a measured file (see module docstring)."""
    return validate_frame(read_measured(path), str(path), L0, ds, st)
