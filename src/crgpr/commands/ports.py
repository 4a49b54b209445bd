"""The actuated study (docs/ports.md): rules ``actuated_data``, ``actuated_camera``,
``actuated_learn`` and ``actuated_accuracy`` (config ``ports``; workflow/rules/ports.smk).

Records of the rod driven by the named input sequences of ``ports.signals`` (released straight
at rest at ``ports.study.theta0_deg``); the models learn from the training sequence's record
with its inputs (``crgpr learn --inputs``): ``objective`` from the full state, ``camera`` from
camera positions, ``paper`` (the paper's features, eqs. (14)-(16)) from the full state, and
``blackbox`` (the black-box GP baseline, ``baselines.blackbox``, with the input channels among
its features) from the full state. ``actuated_accuracy`` rolls every model out under every
sequence (the learned rollout with the simulator's G, ``learning.learned.rollout``) and scores
it against the record, next to the nominal physics prior with E off by
``ports.study.prior_E_factor``. A rollout that diverges is a row with NaN errors and a logged
reason.
"""

from __future__ import annotations

import json
import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.baselines import blackbox
from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import capped_config, learn, learned_damping, load_learned, read_manifest
from crgpr.commands.posterior import posterior_components
from crgpr.config import rod_params
from crgpr.io import atomic_dir, read_parquet, write_csv, write_json, write_parquet
from crgpr.learning.learned import learned_energy, rollout, rollout_members
from crgpr.learning.prefilter import fd_prefilter
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import ports_from_config
from crgpr.physics.rod import straight_rod
from crgpr.physics.signals import SignalInputs, inputs_frame, read_inputs
from crgpr.physics.simulate import Trajectory, energy_frame, simulate, trajectory_frame, trajectory_from_frame
from crgpr.report.actuated import (
    COLUMNS,
    UQ_COLUMNS,
    accuracy_row,
    actuated_figure,
    balance_residual,
    diverged_row,
    uq_figure,
)
from crgpr.seeds import name_seed
from crgpr.uq.coverage import coverage_rows, truth_arrays
from crgpr.uq.rollout import sampled_rod
from crgpr.uq.samples import select_samples

log = logging.getLogger(__name__)

MODELS: tuple[str, ...] = ("objective", "camera", "paper", "blackbox")
METHODS: dict[str, str] = {"objective": "cr_gpr_objective", "camera": "cr_gpr_objective_camera",
                           "paper": "cr_gpr", "blackbox": "blackbox_gp"}
PRIOR = "nominal_prior"  # the nominal rod with E x ports.study.prior_E_factor


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
    """The config ``crgpr learn`` sees in the study: ``commands.learn.capped_config`` with
    ``ports.study.n_train_max``, ``n_hyper_max`` and ``camera_n_t_out`` (the study's run-time
    budget), and the laws taken from the nominal rod ``ports.study.nominal_laws``."""
    study = cfg["ports"]["study"]
    out = capped_config(cfg, study["n_train_max"], study["n_hyper_max"], study["camera_n_t_out"])
    out["camera"]["learn"]["nominal_laws"] = study["nominal_laws"]
    return out

def actuated_learn(cfg: dict[str, Any], model: str, measured: str, inputs: str, out_dir: str) -> None:
    """Rule ``actuated_learn``: ``crgpr learn --inputs`` on the training record (``objective``:
    objective features from the full state, prefilter ``ports.study.prefilter``; ``camera``: the
    same from the camera positions, prefilter ``ports.study.camera_prefilter``; ``paper``: the
    paper's features from the full state), or the black box (``blackbox``: ``actuated_blackbox``)."""
    if model == "blackbox":
        actuated_blackbox(cfg, measured, inputs, out_dir)
        return
    study = cfg["ports"]["study"]
    prefilter = study["camera_prefilter"] if model == "camera" else study["prefilter"]
    src = Path(measured)
    full = model != "camera"
    if full:  # the record as a full-state file (t, node, x, y, theta, p_x, p_y, p_theta)
        src = Path(out_dir).with_name(Path(out_dir).name + "_full.parquet")
        write_parquet(read_parquet(measured).drop(columns=["theta0_deg", "s"]), src)
    try:
        features = "paper" if model == "paper" else "objective"
        learn(src, out_dir, learn_config(cfg), features, prefilter, inputs)
    finally:
        if full:
            src.unlink(missing_ok=True)


def actuated_blackbox(cfg: dict[str, Any], measured: str, inputs: str, out_dir: str) -> None:
    """The black-box GP baseline with inputs (``baselines.blackbox``): six GPs from the state and
    u(t) to the full-state record's fd derivatives (``prefilter.n_t_out`` frames), capped at
    ``ports.study.blackbox_n_train`` / ``blackbox_n_hyper`` points; saved with a ``manifest.json``."""
    params, study = rod_params(cfg), cfg["ports"]["study"]
    traj = trajectory_from_frame(read_parquet(measured), params)
    table, _ = fd_prefilter(traj, int(cfg["prefilter"]["n_t_out"]))
    u = read_inputs(inputs, float(traj.t[-1]))
    F, Y, center = blackbox.training_set(table, params, bool(cfg["gradient_models"]["theta_wrap"]), u)
    st = blackbox.blackbox_settings(cfg)
    st["n_train"] = min(int(st["n_train"]), int(study["blackbox_n_train"]))
    st["n_hyper"] = min(int(st["n_hyper"]), int(study["blackbox_n_hyper"]))
    seed = name_seed(int(cfg["seed"]), "actuated_blackbox")
    gps = blackbox.fit_blackbox(F, Y, st, seed)
    with atomic_dir(out_dir) as tmp:
        for name, gp in zip(blackbox.TARGETS, gps, strict=True):
            gp.save(tmp / name, {"features": [*blackbox.FEATURES, *blackbox.INPUT_FEATURES], "target": name,
                                 "seed": seed, "theta_center": center})
        write_json({"kind": "blackbox_gp", "features": [*blackbox.FEATURES, *blackbox.INPUT_FEATURES],
                    "source": str(measured),
                    "inputs": u.describe(), "seed": seed, "theta_center": center, "settings": st},
                   tmp / "manifest.json")


def _blackbox_rollout(model_dir: str, theta0: float, params: Any, st: SimSettings, u: Any
                      ) -> tuple[Trajectory | None, str]:
    """The black box under the inputs; (trajectory, "") or (None, why) when it diverged."""
    man = json.loads((Path(model_dir) / "manifest.json").read_text())
    t, q, p, info = blackbox.rollout(blackbox.load_models(model_dir), theta0, params, st, man["theta_center"],
                                     inputs=u)
    if info["diverged"]:
        return None, (f"left the physical range at t = {info['t_diverged']:.4g} s "
                      f"(node {info['node_diverged']})")
    return Trajectory(theta0, t, q, p, params), ""


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
    dirs = dict(zip(models, model_dirs, strict=True))
    learned = {m: load_learned(d)[0] for m, d in dirs.items() if m != "blackbox"}
    rows, curves = [], {}
    for sig, rec, upath in zip(signals, records, inputs, strict=True):
        gt = read_parquet(rec)
        u = read_inputs(upath, st.t_end)
        truth = trajectory_from_frame(gt, params)
        curves[sig] = {"truth": truth}
        tr = simulate(theta0, prior, st, inputs=u, ports=ports)
        en = energy_frame(tr)
        rows.append(accuracy_row(PRIOR, train, sig, theta0, gt, trajectory_frame(tr), params.L0,
                                 balance_residual(en["H"], en["input_work"], en["dissipated"])))
        curves[sig][PRIOR] = tr
        for m in models:
            method = METHODS[m]
            if m == "blackbox":  # no H: no energy balance
                tr, why = _blackbox_rollout(dirs[m], theta0, params, st, u)
                res = float("nan")
            else:
                try:
                    tr, why = rollout(learned[m], theta0, st, what=f"actuated {m} model under {sig}",
                                      inputs=u, ports=ports), ""
                except SimulationDiverged as exc:
                    tr, why = None, str(exc)
                if tr is not None:
                    en = learned_energy(learned[m], tr, st.dt)
                    res = balance_residual(en["H_learned"], en["input_work"], en["dissipated"])
            if tr is None:
                log.warning("%s under %s diverged: %s", method, sig, why)
                rows.append(diverged_row(method, train, sig, theta0))
                continue
            rows.append(accuracy_row(method, train, sig, theta0, gt, trajectory_frame(tr), params.L0, res))
            curves[sig][method] = tr
            log.info("%s under %s: tip RMSE / L = %.3g", method, sig, rows[-1]["tip_rmse_over_L"])
    table = pd.DataFrame(rows, columns=list(COLUMNS))
    write_csv(table, out_csv)
    actuated_figure(curves, out_fig)


def actuated_uq(cfg: dict[str, Any], records: list[str], inputs: list[str], signals: list[str],
                model_dirs: list[str], models: list[str], out_csv: str, out_fig: str) -> None:
    """Rule ``actuated_uq``: the learned models' trajectory bands under every sequence through the
    one UQ path: ``ports.uq.n_samples`` joint posterior samples of each model's learned
    force laws (``commands.posterior``; the momentum maps at their means) rolled out as one batch
    under the sequence's inputs (``learning.learned.rollout_members``), the band's coverage of the
    record (``uq.coverage``, level ``ports.uq.level``): ``actuated_uq.csv`` and its figure."""
    study = cfg["ports"]["study"]
    st = study_settings(cfg)
    ports = ports_from_config(cfg)
    theta0 = float(study["theta0_deg"])
    K, level = int(cfg["ports"]["uq"]["n_samples"]), float(cfg["ports"]["uq"]["level"])
    L0 = rod_params(cfg).L0
    rows, bands = [], {}
    for m, d in zip(models, model_dirs, strict=True):
        man = read_manifest(d)
        comps, center = posterior_components(d, man, cfg, K)
        P = RodParams.from_dict(man["rod"])
        q0 = np.repeat(straight_rod(math.radians(theta0), P)[None], K, axis=0)

        def model_for(keys: np.ndarray, comps: dict[str, Any] = comps, P: RodParams = P,
                      center: float | None = center, features: str = man["features"],
                      c: float = learned_damping(man)) -> Any:
            return sampled_rod({k: select_samples(v, keys) for k, v in comps.items()}, features, P, center, c)

        for sig, rec, upath in zip(signals, records, inputs, strict=True):
            t0 = time.perf_counter()
            runs = rollout_members(model_for, q0, np.arange(K), P, st, f"{METHODS[m]} samples under {sig}",
                                   inputs=read_inputs(upath, st.t_end), ports=ports)
            ok = [r for r in runs if r.diverged is None and r.t.size == runs[0].t.size]
            for b, r in enumerate(runs):
                if r.diverged is not None:
                    log.warning("%s sample %d under %s diverged at t = %.4g s", METHODS[m], b, sig,
                                r.diverged["t_s"])
            row = {"method": METHODS[m], "test_signal": sig, "theta0_deg": theta0, "n_samples": K,
                   "n_diverged": K - len(ok), "level": level}
            if len(ok) >= 2:
                arr = np.stack([r.q for r in ok])
                g = truth_arrays(read_parquet(rec), ok[0].t, ("x", "y", "theta"))
                cov = coverage_rows(arr, g, [level], [len(ok)])[0]
                row.update({k: cov[k] for k in ("expected_coverage", "tip_coverage", "theta_coverage",
                                                "theta_band_width_mean")})
                row["tip_band_width_mean_over_L"] = cov["tip_band_width_mean"] / L0
                bands[(METHODS[m], sig)] = (ok[0].t, arr[:, :, -1, :2], g[:, -1, :2])
            row["seconds"] = time.perf_counter() - t0
            rows.append(row)
            log.info("%s", row)
    write_csv(pd.DataFrame(rows, columns=list(UQ_COLUMNS)), out_csv)
    uq_figure(bands, level, out_fig)
