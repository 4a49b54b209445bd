"""The materials study (docs/materials.md, "The materials study"): rules ``material_data``,
``material_learn`` and ``material_score`` (config ``materials_study``;
workflow/rules/materials.smk; the table and figures: ``commands.material_report``).

Each case is a true rod: the config's ``rod`` with the case's ``rod.material`` (over the linear
defaults; ``config.material_case_rod``). ``material_data`` records it released at rest from
``theta0_deg`` (the full state, and every node's positions at ``camera_rate_hz`` with
``camera_noise_m`` Gaussian noise) and at every ``test_deg`` over ``rollout_t_end_s``;
``material_learn`` runs ``crgpr learn`` (objective features) on the full state or the camera
record; ``material_score`` rolls the learned rod and the nominal rod (the config's ``rod``
as it is, the simulator) out at the test angles against the true rod (``report.metrics.accuracy``)
and scores the learned bending law against the true one (``report.metrics.law_accuracy``).
"""

from __future__ import annotations

import copy
import logging
import math
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import capped_config, learn, load_learned, read_manifest
from crgpr.config import material_case_rod, rod_params
from crgpr.io import read_parquet, write_parquet
from crgpr.learning.law_choice import nominal_choice
from crgpr.learning.law_tables import bending_law_at_segments
from crgpr.learning.learned import frozen_after_divergence, rollout_members
from crgpr.learning.warp import manifest_warp, manifest_warp_cov, manifest_warp_truncation
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import segment_moment_law, straight_rod, strains
from crgpr.physics.simulate import Trajectory, simulate, trajectory_frame, trajectory_from_frame
from crgpr.report.metrics import accuracy, law_accuracy

log = logging.getLogger(__name__)

INPUTS: tuple[str, ...] = ("full_state", "camera")  # the study's inputs, learned under its run-time caps
LEARN_DEFAULTS = "camera_defaults"  # the camera record learned with crgpr learn's own settings (no caps)
SOURCES: tuple[str, ...] = (*INPUTS, LEARN_DEFAULTS)
COLUMNS: tuple[str, ...] = ("case", "input", "theta0_deg", "rmse_theta", "tip_rmse_over_L",
                            "nominal_rmse_theta", "ratio_to_nominal", "law_rmse", "law_band_coverage")
TIP_COLUMNS: tuple[str, ...] = ("model", "theta0_deg", "t", "tip_x", "tip_y")


def study_settings(cfg: dict[str, Any], t_end: float) -> SimSettings:
    """The config's step and record interval, the study's scheme, over ``t_end`` [s]."""
    sim = cfg["simulation"]
    return SimSettings(dt=float(sim["dt_s"]), t_end=float(t_end), record_every=int(sim["record_every"]),
                       scheme=str(cfg["materials_study"]["scheme"]))


def camera_seed(seed: int, case: str) -> np.random.Generator:
    """The camera noise generator of one case (seeded by the config's ``seed`` and the case name)."""
    return np.random.default_rng([int(seed), zlib.crc32(f"materials:{case}".encode())])


def material_data(cfg: dict[str, Any], case: str, train_out: str, camera_out: str, test_out: str) -> None:
    """Rule ``material_data``: the true rod's training record at ``theta0_deg`` (full state,
    ``crgpr learn``'s full-state format), its camera positions, and its records at ``test_deg``."""
    ms = cfg["materials_study"]
    truth = material_case_rod(cfg, case)
    meta = {"kind": "material_record", "case": case, "rod": truth.to_dict()}
    tr = simulate(float(ms["theta0_deg"]), truth, study_settings(cfg, float(ms["t_end_s"])))
    every = int(round(1.0 / (float(ms["camera_rate_hz"]) * float(np.median(np.diff(tr.t))))))
    write_parquet(camera_frame(tr.t[::every], tr.q[::every], float(ms["camera_noise_m"]),
                               camera_seed(int(cfg["seed"]), case)), camera_out,
                  {**meta, "kind": "measured", "noise_std_m": float(ms["camera_noise_m"]),
                   "rate_hz": float(ms["camera_rate_hz"])})
    write_parquet(trajectory_frame(tr).drop(columns=["theta0_deg", "s"]), train_out, meta)
    st = study_settings(cfg, float(ms["rollout_t_end_s"]))
    frames = [trajectory_frame(simulate(float(a), truth, st)) for a in ms["test_deg"]]
    write_parquet(pd.concat(frames, ignore_index=True), test_out, meta)


def learn_config(cfg: dict[str, Any], source: str) -> dict[str, Any]:
    """The config ``crgpr learn`` sees in the study for one source (``SOURCES``): for an input of
    ``INPUTS``, ``commands.learn.capped_config`` with the study's ``n_train_max`` and
    ``n_hyper_max`` of that input and ``camera_n_t_out`` (the run-time budget of ``all``); for
    ``LEARN_DEFAULTS``, the config as it is: what ``crgpr learn`` does with it (target ``sweeps``)."""
    if source not in SOURCES:
        raise ValueError(f"input {source!r}: expected one of {SOURCES}")
    if source == LEARN_DEFAULTS:
        return copy.deepcopy(cfg)
    ms = cfg["materials_study"]
    return capped_config(cfg, ms["n_train_max"][source], ms["n_hyper_max"][source], ms["camera_n_t_out"])

def material_learn(cfg: dict[str, Any], source: str, measured: str, out_dir: str) -> None:
    """Rule ``material_learn``: ``crgpr learn`` (objective features) on the full-state record
    (prefilter ``materials_study.prefilter``) or the camera record (``camera_prefilter``), with
    the config of ``learn_config``."""
    ms = cfg["materials_study"]
    learn(measured, out_dir, learn_config(cfg, source), "objective",
          str(ms["prefilter"] if source == "full_state" else ms["camera_prefilter"]))


def law_scores(model_dir: str | Path, truth: RodParams, train: Trajectory, law_table: dict[str, Any],
               seed: int) -> dict[str, float]:
    """``report.metrics.law_accuracy`` of a model directory's bending law (learned, or the nominal
    one where the data chose it, times its record-fit warp where kept;
    ``learning.law_tables.bending_law_at_segments``, each segment at
    its own s where the law takes s) against the true law of every segment at its own s
    (``rod.segment_moment_law``), each segment compared where its curvature went in the training
    record ``train`` (``law_table``: the config's ``camera.learn.law_table``, its sd settings)."""
    man = read_manifest(model_dir)
    kappa = strains(train.q, truth)["kappa"]  # (n_t, N)
    x = np.linspace(float(kappa.min()), float(kappa.max()), int(law_table["n_grid"]))
    where = (x[:, None] >= kappa.min(axis=0)[None, :]) & (x[:, None] <= kappa.max(axis=0)[None, :])
    mean, sd = bending_law_at_segments(model_dir, list(man["models"]), RodParams.from_dict(man["rod"]), x,
                                       int(law_table["max_points"]), seed, int(law_table["band_blocks"]),
                                       manifest_warp(man.get("record_fit")),
                                       manifest_warp_cov(man.get("record_fit")),
                                       manifest_warp_truncation(man.get("record_fit")), nominal_choice(man))
    return law_accuracy(mean, sd, segment_moment_law(truth, x), where)


def _tips(model: str, angle: float, tr: Trajectory) -> pd.DataFrame:
    return pd.DataFrame({"model": model, "theta0_deg": float(angle), "t": tr.t, "tip_x": tr.q[:, -1, 0],
                         "tip_y": tr.q[:, -1, 1]})


def material_score(cfg: dict[str, Any], case: str, source: str, model_dir: str, train: str, test: str,
                   out: str, tips_out: str) -> None:
    """Rule ``material_score``: one row per test angle (``COLUMNS``) for one case and input, and
    the tip paths of the learned rod, the nominal rod and the true rod (``TIP_COLUMNS``).

    The learned rod is rolled out at every angle as one batch (``learning.learned.rollout_members``);
    a rollout that leaves the physical range is scored by the project's one divergence policy
    (``frozen_after_divergence``), so its row holds its error."""
    ms = cfg["materials_study"]
    angles = [float(a) for a in ms["test_deg"]]
    st = study_settings(cfg, float(ms["rollout_t_end_s"]))
    model, _ = load_learned(model_dir)
    truth = material_case_rod(cfg, case)
    nominal = rod_params(cfg)
    q0 = np.stack([straight_rod(math.radians(a), model.params) for a in angles])
    runs = rollout_members(lambda keys: model, q0, np.arange(len(angles)), model.params, st,
                           f"materials study: {case}, {source} model")
    gt_all = read_parquet(test)
    laws = law_scores(model_dir, truth, trajectory_from_frame(read_parquet(train).assign(theta0_deg=math.nan),
                                                              truth),
                      cfg["camera"]["learn"]["law_table"], int(cfg["seed"]))
    rows, tips = [], []
    for a, run in zip(angles, runs, strict=True):
        traj = Trajectory(a, run.t, run.q, run.p, model.params)
        if run.diverged is not None:
            log.warning("%s, %s: the learned rollout at %g deg left the physical range at t = %.3g s", case,
                        source, a, run.diverged["t_s"])
            traj = frozen_after_divergence(traj, st)
        gt = gt_all[np.isclose(gt_all["theta0_deg"], a)]
        nom = simulate(a, nominal, st)
        acc = accuracy(gt, trajectory_frame(traj), truth.L0, test, f"{case} {source} rollout at {a:g} deg")
        acc_n = accuracy(gt, trajectory_frame(nom), truth.L0, test, f"nominal rollout at {a:g} deg")
        ratio = acc["rmse_theta"] / acc_n["rmse_theta"] if acc_n["rmse_theta"] > 0 else math.nan
        rows.append({"case": case, "input": source, "theta0_deg": a, "rmse_theta": acc["rmse_theta"],
                     "tip_rmse_over_L": acc["tip_rmse_over_L"], "nominal_rmse_theta": acc_n["rmse_theta"],
                     "ratio_to_nominal": ratio, **laws})
        tips += [_tips("learned", a, traj), _tips("nominal", a, nom),
                 _tips("truth", a, trajectory_from_frame(gt, truth))]
        log.info("%s, %s at %g deg: RMSE(theta) %.4g rad (nominal %.4g)", case, source, a, acc["rmse_theta"],
                 acc_n["rmse_theta"])
    meta = {"kind": "material_score", "case": case, "input": source, "model_dir": str(model_dir),
            "diverged_deg": [a for a, r in zip(angles, runs, strict=True) if r.diverged is not None]}
    write_parquet(pd.DataFrame(rows, columns=list(COLUMNS)), out, meta)
    write_parquet(pd.concat(tips, ignore_index=True)[list(TIP_COLUMNS)], tips_out, meta)
