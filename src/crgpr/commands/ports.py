"""The actuated study (docs/ports.md): rules ``actuated_data``, ``actuated_camera``,
``actuated_learn`` and ``actuated_accuracy`` (config ``ports``; workflow/rules/ports.smk).

Records of the rod driven by the named input sequences of ``ports.signals`` (released straight
at rest at ``ports.study.theta0_deg``); the models learn from the training sequence's record
with its inputs (``crgpr learn --inputs``): ``objective`` from the full state, ``camera`` from
camera positions; ``actuated_accuracy`` rolls every model out under every sequence (the learned
rollout with the simulator's G, ``learning.learned.rollout``) and scores it against the record,
next to the nominal physics prior with E off by ``ports.study.prior_E_factor``.
"""

from __future__ import annotations

import copy
import logging
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import learn, load_learned
from crgpr.config import rod_params
from crgpr.io import read_parquet, write_csv, write_parquet
from crgpr.learning.learned import learned_energy, rollout
from crgpr.physics.params import SimSettings
from crgpr.physics.ports import ports_from_config
from crgpr.physics.signals import SignalInputs, inputs_frame, read_inputs
from crgpr.physics.simulate import energy_frame, simulate, trajectory_frame, trajectory_from_frame
from crgpr.report.actuated import COLUMNS, accuracy_row, actuated_figure, balance_residual

log = logging.getLogger(__name__)

MODELS: tuple[str, ...] = ("objective", "camera")


def study_settings(cfg: dict[str, Any]) -> SimSettings:
    """The study's time grid: the config's step and record interval over ``ports.study.t_end_s``."""
    sim = cfg["simulation"]
    return SimSettings(dt=float(sim["dt_s"]), t_end=float(cfg["ports"]["study"]["t_end_s"]),
                       record_every=int(sim["record_every"]), scheme=str(sim["scheme"]))


def actuated_data(cfg: dict[str, Any], signal: str, out: str, energy_out: str, inputs_out: str) -> None:
    """Rule ``actuated_data``: the record of one named sequence, its energy file (with the port
    work) and its inputs file (the sequence at every step time)."""
    st = study_settings(cfg)
    inputs = SignalInputs(cfg["ports"]["signals"][signal], signal)
    ports = ports_from_config(cfg)
    tr = simulate(float(cfg["ports"]["study"]["theta0_deg"]), rod_params(cfg), st, inputs=inputs, ports=ports)
    meta = {"kind": "actuated_record", "signal": signal, "inputs": inputs.describe(),
            "ports": ports.to_dict()}
    write_parquet(inputs_frame(inputs, np.arange(st.n_steps + 1) * st.dt), inputs_out, meta)
    write_parquet(energy_frame(tr), energy_out, meta)
    write_parquet(trajectory_frame(tr), out, meta)


def actuated_camera(cfg: dict[str, Any], record: str, out: str) -> None:
    """Rule ``actuated_camera``: positions of every node at ``ports.study.camera_rate_hz`` with
    Gaussian noise ``ports.study.camera_noise_m`` (seeded by ``seed``)."""
    study = cfg["ports"]["study"]
    df = read_parquet(record).sort_values(["t", "node"])
    t = np.unique(df["t"].to_numpy())
    q = df[["x", "y"]].to_numpy().reshape(t.size, -1, 2)
    k = int(round(1.0 / float(study["camera_rate_hz"]) / float(np.median(np.diff(t)))))
    rng = np.random.default_rng(int(cfg["seed"]) + 7001)
    write_parquet(camera_frame(t[::k], q[::k], float(study["camera_noise_m"]), rng), out,
                  {"kind": "measured", "source": record, "noise_std_m": float(study["camera_noise_m"])})


def learn_config(cfg: dict[str, Any]) -> dict[str, Any]:
    """The config ``crgpr learn`` sees in the study: the gradient GPs capped at
    ``ports.study.n_train_max`` points and ``n_hyper_max`` for the likelihood search, and the
    camera model on ``ports.study.camera_n_t_out`` frames (the study's run-time budget)."""
    out = copy.deepcopy(cfg)
    study = cfg["ports"]["study"]
    gm = out["gradient_models"]
    gm["n_hyper"] = min(int(gm["n_hyper"]), int(study["n_hyper_max"]))
    for group in ("models", "objective_models"):
        for spec in gm[group].values():
            spec["n_train"] = min(int(spec["n_train"]), int(study["n_train_max"]))
    out["camera"]["learn"]["n_t_out"] = int(study["camera_n_t_out"])
    return out


def actuated_learn(cfg: dict[str, Any], model: str, measured: str, inputs: str, out_dir: str) -> None:
    """Rule ``actuated_learn``: ``crgpr learn --inputs`` (objective features) on the training record
    (``objective``: the full state, prefilter ``ports.study.prefilter``; ``camera``: the camera
    positions, prefilter ``ports.study.camera_prefilter``)."""
    study = cfg["ports"]["study"]
    prefilter = study["prefilter"] if model == "objective" else study["camera_prefilter"]
    src = Path(measured)
    if model == "objective":  # the record as a full-state file (t, node, x, y, theta, p_x, p_y, p_theta)
        src = Path(out_dir).with_name(Path(out_dir).name + "_full.parquet")
        write_parquet(read_parquet(measured).drop(columns=["theta0_deg", "s"]), src)
    try:
        learn(src, out_dir, learn_config(cfg), "objective", prefilter, inputs)
    finally:
        if model == "objective":
            src.unlink(missing_ok=True)


def actuated_accuracy(cfg: dict[str, Any], records: list[str], inputs: list[str], signals: list[str],
                      model_dirs: list[str], models: list[str], out_csv: str, out_fig: str) -> None:
    """Rule ``actuated_accuracy``: every model and the E-off prior under every sequence, against its
    record (``report.actuated``): the table ``actuated_accuracy.csv`` and its figure."""
    study = cfg["ports"]["study"]
    st = study_settings(cfg)
    params = rod_params(cfg)
    ports = ports_from_config(cfg)
    theta0 = float(study["theta0_deg"])
    train = str(study["train_signal"])
    prior = params.replace(E=params.E * float(study["prior_E_factor"]))
    learned = {m: load_learned(d)[0] for m, d in zip(models, model_dirs, strict=True)}
    rows, curves = [], {}
    for sig, rec, upath in zip(signals, records, inputs, strict=True):
        gt = read_parquet(rec)
        u = read_inputs(upath, st.t_end)
        truth = trajectory_from_frame(gt, params)
        curves[sig] = {"truth": truth}
        tr = simulate(theta0, prior, st, inputs=u, ports=ports)
        en = energy_frame(tr)
        rows.append(accuracy_row(f"nominal_prior_E{float(study['prior_E_factor']):g}", train, sig, theta0, gt,
                                 trajectory_frame(tr), params.L0,
                                 balance_residual(en["H"], en["input_work"], en["dissipated"])))
        curves[sig]["prior"] = tr
        for m, model in learned.items():
            tr = rollout(model, theta0, st, what=f"actuated {m} model under {sig}", inputs=u, ports=ports)
            en = learned_energy(model, tr, st.dt)
            rows.append(accuracy_row(f"cr_gpr_objective_{m}" if m == "camera" else "cr_gpr_objective", train,
                                     sig, theta0, gt, trajectory_frame(tr), params.L0,
                                     balance_residual(en["H_learned"], en["input_work"], en["dissipated"])))
            curves[sig][m] = tr
            log.info("%s under %s: tip RMSE / L = %.3g", m, sig, rows[-1]["tip_rmse_over_L"])
    table = pd.DataFrame(rows, columns=list(COLUMNS))
    write_csv(table, out_csv)
    actuated_figure(curves, out_fig)
