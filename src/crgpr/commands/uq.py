"""Rule functions of the trajectory-UQ stage (workflow/rules/uq.smk); rule name = script name =
function name. Each takes the config values its rule passes as ``params``.

uq_samples      S posterior samples of one gradient GP of one method
uq_samples_learned   the same for every learned GP of a ``crgpr learn`` model directory
uq_rollout      the S sampled models of one method through the rollout at every angle (one batch)
uq_rollout_learned   the same for a ``crgpr learn`` model directory (grey-box laws kept as they are)
uq_coverage     coverage at every level, method and angle (+ the paper's S = 10 rows)
uq_calibration  function-level calibration of the gradient GPs on the test trajectories
uq_figure       rod shapes with the band (one method, one angle)
uq_reliability  reliability diagram from the coverage table
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.io import read_metadata, read_parquet, write_csv, write_json, write_parquet
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.simulate import TRAJECTORY_COLUMNS, trajectory_from_frame
from crgpr.uq.coverage import COVERAGE_COLUMNS, coverage_rows, sample_arrays, summary_rows, truth_arrays
from crgpr.uq.rollout import UQ_COLUMNS, rollout_samples_angles, uq_frame
from crgpr.uq.samples import load_samples, sample_model
from crgpr.uq.settings import UQSettings

log = logging.getLogger(__name__)


def _sim(simulation: Mapping[str, Any]) -> SimSettings:
    return SimSettings(dt=float(simulation["dt_s"]), t_end=float(simulation["t_end_s"]),
                       record_every=int(simulation["record_every"]), scheme=str(simulation["scheme"]))


def theta_center(model_jsons: Sequence[str | Path], features: str) -> float | None:
    """The angle window of the paper features (q_x and dH_dtheta must agree); None otherwise."""
    if features != "paper":
        return None
    metas = {Path(m).stem: json.loads(Path(m).read_text()) for m in model_jsons}
    centers = {metas[m].get("theta_center") for m in ("q_x", "q_y", "dH_dtheta") if m in metas}
    if len(centers) != 1:
        raise ValueError(f"q_x, q_y, dH_dtheta have different theta windows {centers}")
    return centers.pop()


def uq_samples(model_npz: str, uq: Mapping[str, Any], seed: int, out: str, diagnostics: str) -> None:
    """Rule ``uq_samples``: S samples of the gradient model ``model_npz`` (stem.npz + .json)."""
    settings = UQSettings.from_section(dict(uq))
    stem = Path(model_npz).with_suffix("")
    sample_model(stem, stem.name, settings, int(seed), out, diagnostics)


def uq_samples_learned(model_dir: str, uq: Mapping[str, Any], seed: int, out_dir: str) -> None:
    """Rule ``uq_samples_learned``: ``uq_samples`` for every learned GP of a ``crgpr learn`` model
    directory (its manifest's ``models``; the nominal laws are not sampled) into ``out_dir``
    (name.npz + name.json each, then the directory's manifest, written last: a complete set)."""
    from crgpr.commands.learn import MANIFEST, learned_models, read_manifest

    settings = UQSettings.from_section(dict(uq))
    man = read_manifest(model_dir)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    (out / MANIFEST).unlink(missing_ok=True)
    for m in learned_models(man):
        sample_model(Path(model_dir) / m, m, settings, int(seed), out / f"{m}.npz", out / f"{m}.json")
    write_json({**man, "samples_of": str(model_dir)}, out / MANIFEST)


def uq_rollout(samples: Sequence[str], models: Sequence[str], method: str, method_cfg: Mapping[str, str],
               angles: Sequence[int], rod: Mapping[str, Any], simulation: Mapping[str, Any],
               uq: Mapping[str, Any], outs: Sequence[str]) -> None:
    """Rule ``uq_rollout``: the S sampled models of ``method`` at every angle (one batch of S x A
    rods, ``rollout_samples_angles``); writes, per angle, every ``uq.store_every``-th record of
    every sample (``UQ_COLUMNS``, float32 states) to the matching file of ``outs``."""
    settings = UQSettings.from_section(dict(uq))
    smp = load_samples({Path(p).stem: p for p in samples}, settings.kernel_tol)
    _rollout_and_write(smp, method_cfg["features"], RodParams.from_dict(dict(rod)),
                       theta_center(models, method_cfg["features"]), method, angles, _sim(simulation),
                       settings, int(uq["store_every"]), outs)


def uq_rollout_learned(samples_dir: str, model_dir: str, method: str, angles: Sequence[int],
                       simulation: Mapping[str, Any], uq: Mapping[str, Any], outs: Sequence[str]) -> None:
    """Rule ``uq_rollout_learned``: ``uq_rollout`` for a ``crgpr learn`` model directory: its
    learned GPs replaced by their samples (``samples_dir``, from ``uq_samples_learned``), its
    nominal laws kept (``commands.learn.learned_components``: the assembly of the mean model), on
    the rod of its manifest, with the config's integrator settings."""
    from crgpr.commands.learn import learned_components, learned_damping, learned_models, read_manifest
    from crgpr.commands.rollout import rollout_settings

    settings = UQSettings.from_section(dict(uq))
    man = read_manifest(model_dir)
    params = RodParams.from_dict(man["rod"])
    smp = load_samples({m: Path(samples_dir) / f"{m}.npz" for m in learned_models(man)}, settings.kernel_tol)
    comps, center = learned_components(model_dir, man, smp.__getitem__)
    sim = rollout_settings({"simulation": dict(simulation)}, params, None)
    _rollout_and_write(comps, man["features"], params, center, method, angles, sim, settings,
                       int(uq["store_every"]), outs, {"model_dir": str(model_dir),
                                                      "nominal_laws": man.get("nominal_laws", [])},
                       learned_damping(man))


def _rollout_and_write(smp: Mapping[str, Any], features: str, params: RodParams, center: float | None,
                       method: str, angles: Sequence[int], sim: SimSettings, settings: UQSettings,
                       k: int, outs: Sequence[str], extra: Mapping[str, Any] | None = None,
                       damping: float = 0.0) -> None:
    if len(outs) != len(angles):
        raise ValueError(f"uq_rollout: {len(angles)} angles but {len(outs)} output files")
    bounds = {m: s.truncation_bound for m, s in smp.items() if hasattr(s, "truncation_bound")}
    log.info("kernel sums truncated below %g sigma_f^2: |change| <= %s (output units)",
             settings.kernel_tol, bounds)
    t0 = time.perf_counter()
    res = rollout_samples_angles(smp, features, params, center, [float(a) for a in angles], sim, damping)
    secs = time.perf_counter() - t0
    for angle, out in zip(angles, outs, strict=True):
        t, q, p, keep, diverged = res[float(angle)]
        log.info("%s at %d deg: %d samples kept (%d diverged)", method, angle, len(keep), len(diverged))
        df = uq_frame(float(angle), t[::k], q[:, ::k], p[:, ::k], keep, params.ds)
        df = df.astype({c: np.float32 for c in ("x", "y", "theta", "p_x", "p_y", "p_theta")})
        meta = {"kind": "uq_rollout", "method": method, "theta0_deg": angle, **(extra or {}),
                "features": features, "n_samples": settings.n_samples,
                "n_diverged": len(diverged), "diverged": diverged,
                "kernel_truncation_bound": bounds, "batch_angles": list(angles),
                "seconds_rollout": secs / len(angles), "seconds_rollout_batch": secs, "store_every": k,
                "settings": settings.to_dict(), "rod": params.to_dict(), "simulation": sim.to_dict()}
        write_parquet(df, out, meta)
    log.info("%s: %d angles x %d samples integrated in %.1f s", method, len(angles), settings.n_samples, secs)


def _method_angle(path: str) -> tuple[str, int]:
    p = Path(path)
    return p.parent.name, int(p.stem)


def uq_coverage(uq_paths: Sequence[str], ground_truth: Sequence[str], mean_models: Sequence[str],
                uq: Mapping[str, Any], out: str, table: str) -> None:
    """Rule ``uq_coverage``: rows per (method, angle, S, level) plus the mean over the angles.

    ``mean_models``: results/rollouts/{method}/{angle}.parquet of the same methods and angles."""
    settings = UQSettings.from_section(dict(uq))
    gts = {int(Path(p).stem): p for p in ground_truth}
    means = {_method_angle(p): p for p in mean_models}
    cols = ("x", "y", "theta")
    rows = []
    loos: dict[tuple[str, int, float], list[dict[int, float]]] = {}
    for path in uq_paths:
        method, angle = _method_angle(path)
        df = read_parquet(path, required=UQ_COLUMNS)
        arr = sample_arrays(df, cols)
        t = np.sort(df["t"].unique())
        g = truth_arrays(read_parquet(gts[angle], required=TRAJECTORY_COLUMNS), t, cols)
        mm = None
        if (method, angle) in means:
            mm = truth_arrays(read_parquet(means[(method, angle)], required=TRAJECTORY_COLUMNS), t, cols)
        n_div = int(read_metadata(path).get("n_diverged", 0))
        sizes = sorted({settings.paper_n_samples, arr.shape[0]})
        ids = np.sort(df["sample"].unique())
        for r in coverage_rows(arr, g, settings.levels, sizes, mm):
            loo = r.pop("loo")
            loos.setdefault((method, r["n_samples"], r["level"]), []).append(dict(zip(ids.tolist(), loo,
                                                                                    strict=False)))
            rows.append({"method": method, "theta0_deg": float(angle), "n_diverged": n_div, **r})
    df = pd.DataFrame(rows)[list(COVERAGE_COLUMNS)]
    df = pd.concat([df, summary_rows(df, loos)], ignore_index=True)
    meta = {"kind": "uq_coverage", "settings": settings.to_dict(),
            "definition": "fraction of ground-truth samples inside the central band of the given level "
                          "(percentiles over the first n_samples sampled trajectories); theta over t > 0 "
                          "and nodes 1..N; tip: x and y both inside; expected_coverage: the value a "
                          "calibrated model reaches with n_samples; calibrated_coverage_sd / "
                          "calibrated_fraction_at_least: spread of the coverage of ONE truth that is a "
                          "draw of the sampled law (leave-one-sample-out) and the fraction of those >= "
                          "the observed coverage; rows with theta0_deg empty: mean over the angles"}
    write_parquet(df, out, meta)
    write_csv(df.round(5), table)
    log.info("coverage (means over angles):\n%s",
             df[df["theta0_deg"].isna()][["method", "n_samples", "level", "theta_coverage",
                                           "expected_coverage", "mc_se", "calibrated_coverage_sd",
                                           "calibrated_fraction_at_least"]].to_string())


def uq_calibration(models: Sequence[str], ground_truth: Sequence[str], rod: Mapping[str, Any],
                   out: str) -> None:
    """Rule ``uq_calibration``: function-level calibration of the models ``models`` (.npz of
    results/models/{prefilter}/) at the ground-truth states of the test angles."""
    from crgpr.uq.calibration import function_calibration

    params = RodParams.from_dict(dict(rod))
    by_prefilter: dict[str, dict[str, str]] = {}
    for m in models:
        p = Path(m)
        by_prefilter.setdefault(p.parent.name, {})[p.stem] = str(p.with_suffix(""))
    trajs = {}
    for path in ground_truth:
        tr = trajectory_from_frame(read_parquet(path, required=TRAJECTORY_COLUMNS), params)
        trajs[int(Path(path).stem)] = (tr.q, tr.p)
    frames = []
    for prefilter, stems in sorted(by_prefilter.items()):
        jsons = [str(Path(s).with_suffix(".json")) for s in stems.values()]
        center = theta_center(jsons, "paper") if "q_x" in stems else None
        df = function_calibration(stems, trajs, params, center)
        df.insert(0, "prefilter", prefilter)
        frames.append(df)
    write_csv(pd.concat(frames, ignore_index=True).round(6), out)


def uq_figure(uq_path: str, ground_truth: str, mean_model: str, uq: Mapping[str, Any], out: str) -> None:
    """Rule ``uq_figure``: rod shapes with the ``uq.figure_level`` band for one method and angle."""
    from crgpr.report.uq import band_figure

    settings = UQSettings.from_section(dict(uq))
    method, angle = _method_angle(uq_path)
    df = read_parquet(uq_path, required=UQ_COLUMNS)
    arr = sample_arrays(df, ("x", "y"))
    t = np.sort(df["t"].unique())
    g = truth_arrays(read_parquet(ground_truth, required=TRAJECTORY_COLUMNS), t, ("x", "y"))
    mm = truth_arrays(read_parquet(mean_model, required=TRAJECTORY_COLUMNS), t, ("x", "y"))
    band_figure(arr, t, g, settings.figure_level, settings.figure_time_fractions, out, method, angle, mm)


def uq_reliability(coverage: str, out: str) -> None:
    """Rule ``uq_reliability``: the reliability diagram of ``results/uq/coverage.parquet``."""
    from crgpr.report.uq import reliability_diagram

    reliability_diagram(read_parquet(coverage, required=COVERAGE_COLUMNS), out)
