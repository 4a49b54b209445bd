"""Control on the learned model (docs/control.md): the command ``crgpr control`` and the rule
``control_study`` (config ``control``; workflow/rules/control.smk).

``crgpr control --models DIR --target-x X --target-y Y [--target-angle A] [--path FILE]
--out POLICY.json [--simulate --out-trajectory R]`` designs the controller on the model
directory's learned rod (its manifest's rod) and writes the portable policy; ``--simulate`` runs
it as a digital controller on the simulator's rod (``--config``, ``--set`` as ``crgpr simulate``).
"""

from __future__ import annotations

import argparse
import logging
import math
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.commands.posterior import posterior_components
from crgpr.config import ConfigError, cli_rod_sim, load_config, rod_params
from crgpr.control.closed_loop import ClosedLoop, run_closed_loop, simulator_plant
from crgpr.control.design import Gains, Solver, circle_path, hold, regulation_policy, tracking_policy
from crgpr.control.policy import Policy, tables, to_document
from crgpr.control.statics import CONTROL_CHANNELS, solve_equilibrium
from crgpr.io import write_csv, write_json, write_parquet
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import Ports, ports_from_config
from crgpr.physics.rod import internal_forces, node_weights, straight_rod

log = logging.getLogger(__name__)


def gains(cfg: dict[str, Any]) -> Gains:
    g = cfg["control"]["gains"]
    return Gains(float(g["kp_force_N_per_m"]), float(g["kd_force_Ns_per_m"]),
                 float(g["kp_moment_Nm_per_rad"]),
                 float(g["kd_moment_Nms_per_rad"]))


def solver(cfg: dict[str, Any]) -> Solver:
    s = cfg["control"]["solver"]
    return Solver(float(s["tol"]), int(s["max_iter"]), float(s["workspace_margin"]))


def limits(cfg: dict[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    lim = cfg["control"]["u_limits"]
    return (np.array([float(lim[c][0]) for c in CONTROL_CHANNELS]),
            np.array([float(lim[c][1]) for c in CONTROL_CHANNELS]))


def hold_settings(cfg: dict[str, Any], dt: float) -> SimSettings:
    """One hold interval of the controller at ``control.control_rate_hz`` on the step dt."""
    rate = float(cfg["control"]["control_rate_hz"])
    n = round(1.0 / (rate * dt))
    if n < 1 or abs(n * rate * dt - 1.0) > 1e-9:
        raise ConfigError(f"control.control_rate_hz = {rate:g}: 1 / rate must be a whole number of "
                          f"time steps ({dt:g} s)")
    return SimSettings(dt=dt, t_end=n * dt, record_every=n, scheme=str(cfg["simulation"]["scheme"]))


def nominal_internal(params: RodParams):
    """-dH/dq per unit length of the nominal (simulator's) rod with these parameters."""
    wds = node_weights(params.N) * params.ds

    def internal(q: np.ndarray) -> np.ndarray:
        return internal_forces(q, params)[0] / wds[:, None]
    return internal


def gravity(params: RodParams) -> np.ndarray:
    return np.array([0.0, -params.rhoA * params.g, 0.0])


def base_angle(cfg: dict[str, Any]) -> float:
    """The clamp's angle of the controlled rod [rad] (``control.base_angle_deg``)."""
    return math.radians(float(cfg["control"]["base_angle_deg"]))


def base_rod(cfg: dict[str, Any], params: RodParams) -> np.ndarray:
    return straight_rod(base_angle(cfg), params)


def rest_at(params: RodParams, cfg: dict[str, Any], xy: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """The plant's own static state holding its tip at xy (its nominal forces), and that input:
    the from-rest start of a run."""
    eq = solve_equilibrium(nominal_internal(params), gravity(params), base_rod(cfg, params), params.ds,
                           (float(xy[0]), float(xy[1]), None), solver(cfg).tol, solver(cfg).max_iter)
    return eq.q, eq.u


def read_path(path: str | Path) -> pd.DataFrame:
    """A tip path file: Parquet, or CSV by its suffix, with t [s], x, y [m] (one line per error)."""
    p = Path(path)
    try:
        df = pd.read_csv(p) if p.suffix == ".csv" else pd.read_parquet(p)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is one user error
        raise ConfigError(f"{p}: cannot read the path file ({type(exc).__name__})") from None
    for c in ("t", "x", "y"):
        if c not in df.columns:
            raise ConfigError(f"{p}: column {c!r} missing (need t, x, y)")
        if not np.all(np.isfinite(pd.to_numeric(df[c], errors="coerce"))):
            raise ConfigError(f"{p}: column {c!r} has a non-numeric or non-finite value")
    if len(df) < 2 or not np.all(np.diff(df["t"].to_numpy(float)) > 0):
        raise ConfigError(f"{p}: column 't' must be strictly increasing over at least two rows")
    return df


def write_policy(policy: Policy, out: str | Path, extra: dict[str, Any]) -> None:
    """The policy JSON (tracking: with its two tables next to it, named in the JSON)."""
    out = Path(out)
    if policy.t_path.size == 1:
        write_json(to_document(policy, extra=extra), out)
        return
    uf, tg = tables(policy)
    names = (f"{out.stem}_u_ff.csv", f"{out.stem}_target.csv")
    write_csv(uf, out.parent / names[0])
    write_csv(tg, out.parent / names[1])
    write_json(to_document(policy, *names, extra=extra), out)


def run_frame(run: ClosedLoop) -> pd.DataFrame:
    """A closed-loop run as a table: t, tip pose, target, inputs, port work."""
    cols: dict[str, Any] = {"t": run.t, "x": run.pose[:, 0], "y": run.pose[:, 1], "phi": run.pose[:, 2],
                            "target_x": run.target[:, 0], "target_y": run.target[:, 1],
                            "target_phi": run.target[:, 2], "input_work": run.work}
    cols.update({f"u_{c}": run.u[:, k] for k, c in enumerate(CONTROL_CHANNELS)})
    return pd.DataFrame(cols)


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("control", help="design a tip controller on a learned model and write it as a policy",
                       description="Feedforward by energy shaping on the learned model plus tip feedback "
                                   "(docs/control.md); writes a portable policy file.")
    p.add_argument("--models", required=True, help="crgpr learn model directory")
    p.add_argument("--target-x", type=float, help="tip target x [m]")
    p.add_argument("--target-y", type=float, help="tip target y [m]")
    p.add_argument("--target-angle", type=float, help="tip target angle phi (last segment) [rad]")
    p.add_argument("--path", help="tip path file (t, x, y; Parquet or CSV): track it instead")
    p.add_argument("--out", required=True, help="policy JSON to write")
    p.add_argument("--simulate", action="store_true", help="run the closed loop on the simulator")
    p.add_argument("--out-trajectory", help="closed-loop run table (Parquet) of --simulate")
    p.add_argument("--config", default=None, help="config.yaml (default: ./config.yaml)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a rod parameter of the simulated plant (repeatable)")
    p.set_defaults(func=_cli)


def _cli(a: argparse.Namespace) -> None:
    from crgpr.commands.learn import load_learned

    cfg_path = a.config or "config.yaml"
    cfg = load_config(cfg_path)
    if a.simulate and not a.out_trajectory:
        raise ConfigError("--simulate needs --out-trajectory")
    point = a.target_x is not None and a.target_y is not None
    if (a.path is None) != point or (a.path and a.target_angle is not None):
        raise ConfigError("give --target-x and --target-y (and optionally --target-angle), or --path")
    for name in ("target_x", "target_y", "target_angle"):
        v = getattr(a, name)
        if v is not None and not math.isfinite(v):
            raise ConfigError(f"--{name.replace('_', '-')} {v}: must be a finite number")
    model, man = load_learned(a.models)
    plant_params, settings = cli_rod_sim(cfg["rod"], cfg["simulation"], a.set, None, None, None,
                                         str(cfg_path))
    path_df = read_path(a.path) if a.path else None
    model_q0 = base_rod(cfg, model.params)
    lo, hi = limits(cfg)
    P = model.params
    extra: dict[str, Any] = {"model_dir": str(a.models), "rod": P.to_dict(),
                             "base_angle_deg": float(cfg["control"]["base_angle_deg"]),
                             "control_rate_hz": float(cfg["control"]["control_rate_hz"])}
    if path_df is None:
        target = (a.target_x, a.target_y, a.target_angle)
        eq = hold(model.internal, model.gu, model_q0, P.ds, target, solver(cfg), lo, hi)
        policy = regulation_policy(eq, target, gains(cfg), lo, hi)
        extra["equilibrium_residual_N"] = eq.residual
        t_end = float(cfg["control"]["t_end_s"])
    else:
        t = path_df["t"].to_numpy(float)
        xy = path_df[["x", "y"]].to_numpy(float)
        rate = np.column_stack([np.gradient(xy[:, 0], t), np.gradient(xy[:, 1], t)])
        policy, _ = tracking_policy(model.internal, model.gu, model_q0, P.ds, t, xy, rate, gains(cfg),
                                    solver(cfg), lo, hi)
        t_end = float(t[-1])
    write_policy(policy, a.out, extra)
    if a.simulate:
        ports = Ports(float(man["ports"]["tendon_offset_m"])) if man.get("ports") else ports_from_config(cfg)
        plant = simulator_plant(plant_params, hold_settings(cfg, settings.dt), ports, base_angle(cfg))
        q0 = base_rod(cfg, plant_params)
        run = run_closed_loop(policy, plant, q0, np.zeros_like(q0), float(cfg["control"]["control_rate_hz"]),
                              t_end, 10**9)
        write_parquet(run_frame(run), a.out_trajectory, {"kind": "closed_loop", "policy": str(a.out),
                                                         "rod": plant_params.to_dict(),
                                                         "simulation": settings.to_dict()})


def plant_for(kind: str, cfg: dict[str, Any]) -> tuple[RodParams, float]:
    """The plants of the study and their time steps: ``ground_truth`` (the config's rod and step)
    and ``fine_grid`` (``control.study.fine_N`` segments, the step times ``fine_dt_factor``)."""
    params, dt = rod_params(cfg), float(cfg["simulation"]["dt_s"])
    if kind == "fine_grid":
        s = cfg["control"]["study"]
        params, dt = params.replace(N=int(s["fine_N"])), dt * float(s["fine_dt_factor"])
    return params, dt


COLUMNS = ("task", "target", "start", "plant", "controller", "steady_tip_error_over_L",
           "residual_oscillation_over_L", "settling_time_s",
           "overshoot_over_L", "peak_input", "tracking_rmse_over_L", "converged_fraction",
           "steady_tip_error_spread_over_L", "predicted_offset_over_L")


def posterior_rows(cfg: dict[str, Any], model_dir: str, man: dict[str, Any], ports: Ports,
                   target: tuple[float, float, float | None], starts: dict[str, np.ndarray]
                   ) -> list[dict[str, Any]]:
    """Rows ``learned_posterior`` of the study: the regulation controller designed on each of K
    posterior samples of the learned model, run on the ground-truth plant from each start of
    ``control.posterior.starts`` (``starts``: start name -> the plant's configuration at rest)."""
    from crgpr.control import metrics
    from crgpr.control.posterior import posterior_regulation, sample_internals
    from crgpr.uq.rollout import n_samples_of

    c = cfg["control"]
    comps, center = posterior_components(model_dir, man, cfg, int(c["posterior"]["n_samples"]))
    P = RodParams.from_dict(man["rod"])
    internals = sample_internals(comps, man["features"], P, center)
    point_mass = n_samples_of(comps, default=0) == 0  # no learned force law: one deterministic rod
    lo, hi = limits(cfg)
    L = rod_params(cfg).L0
    band, window = float(c["settle_band_over_L"]) * L, float(c["steady_window_s"])
    params, dt = plant_for("ground_truth", cfg)
    plant = simulator_plant(params, hold_settings(cfg, dt), ports, base_angle(cfg))
    u_hold = rest_at(params, cfg, target[:2])[1]
    kp = gains(cfg).kp_force
    rows = []
    for start in c["posterior"]["starts"]:
        q0 = starts[start]
        res = posterior_regulation(internals, gravity(P), base_rod(cfg, P), P.ds, target, gains(cfg),
                                   solver(cfg), lo, hi, plant, q0, float(c["control_rate_hz"]),
                                   float(c["t_end_s"]), band, window)
        ok = res.converged
        log.info("posterior designs from %s: designed %s, converged %s, steady error / L %s", start,
                 res.designed.tolist(), ok.tolist(), (res.steady_error / L).tolist())
        med = res.median_converged
        rows.append({"task": "regulation", "target": f"({target[0]:g}, {target[1]:g})", "start": start,
                     "plant": "ground_truth", "controller": "learned_posterior",
                     "steady_tip_error_over_L": med(res.steady_error) / L,
                     "residual_oscillation_over_L": med(res.oscillation) / L,
                     "settling_time_s": med(res.settling), "overshoot_over_L": float("nan"),
                     "peak_input": float("nan"), "tracking_rmse_over_L": float("nan"),
                     "converged_fraction": res.converged_fraction,
                     "steady_tip_error_spread_over_L": res.spread(point_mass) / L,
                     "predicted_offset_over_L": med(np.array(
                         [metrics.predicted_offset(u, u_hold, kp) for u in res.u_ff])) / L})
        log.info("%s", rows[-1])
    return rows


def _designs(cfg: dict[str, Any], learned: Any) -> dict[str, tuple[Any, np.ndarray, RodParams, bool]]:
    """Controller name -> (model -dH/dq per length, gravity per length, model rod, feedforward)."""
    f = float(cfg["control"]["study"]["nominal_E_factor"])
    nominal = rod_params(cfg)
    nominal = nominal.replace(E=nominal.E * f)
    return {"learned": (learned.internal, learned.gu, learned.params, True),
            f"nominal_E{abs(1 - f) * 100:g}": (nominal_internal(nominal), gravity(nominal), nominal, True),
            "pd_only": (learned.internal, learned.gu, learned.params, False)}


def control_study(cfg: dict[str, Any], model_dir: str, out_csv: str, out_fig: str) -> None:
    """Rule ``control_study``: regulation and tracking by the controller designed on the learned
    model, on the nominal model with E off, and plain PD, each run on the ground-truth and the
    finer-grid simulator, and the same design on each posterior sample of the learned model
    (``posterior_rows``) (``control.csv`` and its figure; docs/control.md)."""
    from crgpr.commands.learn import load_learned
    from crgpr.control import metrics
    from crgpr.report.control import control_figure

    c, s = cfg["control"], cfg["control"]["study"]
    learned, man = load_learned(model_dir)
    ports = Ports(float(man["ports"]["tendon_offset_m"])) if man.get("ports") else ports_from_config(cfg)
    lo, hi = limits(cfg)
    g, sol = gains(cfg), solver(cfg)
    rate, t_end = float(c["control_rate_hz"]), float(c["t_end_s"])
    keep = max(1, round(float(c["shapes_every_s"]) * rate))
    L = rod_params(cfg).L0
    target = (float(s["target_xy"][0]), float(s["target_xy"][1]), None)
    tp = np.linspace(0.0, t_end, int(s["path_points"]))
    xy, xy_rate = circle_path(tuple(s["path_center_xy"]), float(s["path_radius_m"]),
                              float(s["path_frequency_hz"]), tp)
    policies: dict[str, tuple[Policy, Policy]] = {}
    for name, (internal, grav, mp, ff) in _designs(cfg, learned).items():
        q_rest = base_rod(cfg, mp)
        eq = hold(internal, grav, q_rest, mp.ds, target, sol, lo, hi)
        track, _ = tracking_policy(internal, grav, q_rest, mp.ds, tp, xy, xy_rate, g, sol, lo, hi, ff)
        policies[name] = (regulation_policy(eq, target, g, lo, hi, ff), track)
        log.info("%s: u_ff at the target %s (residual %.2g N)", name, eq.u, eq.residual)
    rows, runs, truth_starts = [], {}, {}
    band, window = float(c["settle_band_over_L"]) * L, float(c["steady_window_s"])
    nan = float("nan")
    for plant_name in ("ground_truth", "fine_grid"):
        params, dt = plant_for(plant_name, cfg)
        plant = simulator_plant(params, hold_settings(cfg, dt), ports, base_angle(cfg))
        q_start, _ = rest_at(params, cfg, tuple(s["start_xy"]))
        q_path, _ = rest_at(params, cfg, (float(xy[0, 0]), float(xy[0, 1])))
        starts = {"rest": q_start, "released": base_rod(cfg, params)}
        truth_starts = starts if plant_name == "ground_truth" else truth_starts
        u_hold = rest_at(params, cfg, target[:2])[1]
        for name, (reg, track) in policies.items():
            for start, q0 in starts.items():
                run = run_closed_loop(reg, plant, q0, np.zeros_like(q0), rate, t_end, keep)
                runs[("regulation", plant_name, name, start)] = run
                rows.append({"task": "regulation", "target": f"({target[0]:g}, {target[1]:g})",
                             "start": start,
                             "plant": plant_name, "controller": name,
                             "steady_tip_error_over_L": metrics.steady_error(run, window) / L,
                             "residual_oscillation_over_L": metrics.residual_oscillation(run, window) / L,
                             "settling_time_s": metrics.settling_time(run, band),
                             "overshoot_over_L": metrics.overshoot(run) / L,
                             "peak_input": metrics.peak_force(run),
                             "tracking_rmse_over_L": nan, "converged_fraction": nan,
                             "steady_tip_error_spread_over_L": nan,
                             "predicted_offset_over_L":
                                 metrics.predicted_offset(reg.u_ff[0], u_hold, g.kp_force) / L})
                log.info("%s", rows[-1])
            run = run_closed_loop(track, plant, q_path, np.zeros_like(q_path), rate, t_end, keep)
            runs[("tracking", plant_name, name, "rest")] = run
            rows.append({"task": "tracking", "target": f"circle r = {float(s['path_radius_m']):g} m at "
                         f"{float(s['path_frequency_hz']):g} Hz", "start": "rest", "plant": plant_name,
                         "controller": name, "steady_tip_error_over_L": nan,
                         "residual_oscillation_over_L": nan, "settling_time_s": nan,
                         "overshoot_over_L": nan, "peak_input": metrics.peak_force(run),
                         "tracking_rmse_over_L": metrics.tracking_rmse(run, float(s["tracking_skip_s"])) / L,
                         "converged_fraction": nan, "steady_tip_error_spread_over_L": nan,
                         "predicted_offset_over_L": nan})
            log.info("%s", rows[-1])
    t0 = time.perf_counter()
    rows += posterior_rows(cfg, model_dir, man, ports, target, truth_starts)
    log.info("posterior designs: %.1f s", time.perf_counter() - t0)
    write_csv(pd.DataFrame(rows, columns=list(COLUMNS)), out_csv)
    control_figure(runs, out_fig)
