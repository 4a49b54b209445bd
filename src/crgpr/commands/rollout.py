"""Learned rollouts, step 4 of the paper's Sec. III-B: rule ``rollout`` and ``crgpr rollout``.

Writes ``results/rollouts/{method}/{angle}.parquet`` and ``_energy.parquet`` (algorithm:
``crgpr.learning.learned``); ``rollout_models`` rolls a ``crgpr learn`` directory out from an
angle or a measured frame, under actuation inputs.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path
from typing import Any

import numpy as np

from crgpr.commands.learn import MOMENTUM_COLUMNS, checked_step, full_state_momenta, load_learned
from crgpr.config import ConfigError, add_config_options, cli_config, sim_settings
from crgpr.io import write_parquet
from crgpr.learning import learned
from crgpr.learning.camera import LearnSettings, check_node_grid, positions_to_state
from crgpr.learning.learned import LearnedRod
from crgpr.measured.records import MeasuredDataError, ScreenSettings, read_measured, validate_frame
from crgpr.physics.integrator import SimulationDiverged
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import Ports, ports_from_config
from crgpr.physics.signals import read_inputs
from crgpr.physics.simulate import Trajectory, trajectory_frame


def rollout(cfg: dict[str, Any], method: str, angles: list[int], outs: list[str], energy_outs: list[str],
            model_json: str) -> None:
    """Rule ``rollout``: integrate one method's learned rod from the straight rod at every angle
    (one batch, ``learned.run_rollouts``), one trajectory and energy file per angle."""
    learned.run_rollouts(cfg, method, [float(a) for a in angles], Path(model_json).parent, outs, energy_outs)


def variant_rollout(cfg: dict[str, Any], method: str, angle: int, out: str, energy_out: str,
                    model_json: str) -> None:
    """Rule ``variant_rollout``: one method of a pipeline variant at one angle (the same
    ``learned.run_rollouts``; a variant's test angles come from its own config)."""
    learned.run_rollouts(cfg, method, [float(angle)], Path(model_json).parent, [out], [energy_out])


def rollout_settings(cfg: dict[str, Any], params: RodParams, t_end: float | None) -> SimSettings:
    """The config's integrator settings (dt, record_every), optionally another t_end; dt checked."""
    base = sim_settings(cfg)
    if t_end is not None and not (math.isfinite(t_end) and t_end > 0):
        raise ConfigError(f"--t-end {t_end}: must be a positive number of seconds")
    return checked_step(SimSettings(dt=base.dt, t_end=base.t_end if t_end is None else float(t_end),
                                    record_every=base.record_every, scheme=base.scheme), params)


def initial_state(path: str | Path, cfg: dict[str, Any], params: RodParams, prefilter_method: str = "gp"
                  ) -> tuple[np.ndarray, np.ndarray, float, dict[str, Any]]:
    """A rollout's initial state (q0, p0 per length, t0) from the first frame of a measured file
    (the format of ``--measured``, on the model's node grid), and how it was obtained.

    A full-state file gives x, y, theta and the momenta of its first frame as they are. From
    positions only, the state is derived as ``crgpr learn`` derives its training state
    (``learning.camera.positions_to_state``: the ``prefilter_method`` position GPs over the whole
    record, whose time derivatives give the velocities, hence p = rho A v, rho I omega), taken at
    the first frame it keeps (``camera.learn.edge_trim_s`` after the record's start, where the
    GP derivatives are no longer end-affected)."""
    table = read_measured(path)
    screen = ScreenSettings.from_config(cfg["discovery"])
    meas = validate_frame(table, str(path), params.L0, params.ds, screen)
    full = full_state_momenta(table, str(path), meas.t.size, meas.x.shape[1])
    if full is not None:
        check_node_grid(meas, params)
        theta, p = full
        q0 = np.stack([meas.x[0], meas.y[0], theta[0]], axis=-1)
        return q0, p[0].copy(), float(meas.t[0]), {"initial": "first frame of a full-state file",
                                                  "t0_s": float(meas.t[0])}
    st = LearnSettings.from_config(cfg["camera"]["learn"])
    arr, _ = positions_to_state(meas, params, prefilter_method, st, int(cfg["seed"]) + 3000)
    q0 = np.stack([arr["x"][0], arr["y"][0], arr["theta"][0]], axis=-1)
    p0 = np.stack([arr[c][0] for c in MOMENTUM_COLUMNS], axis=-1)
    return q0, p0, float(arr["t"][0]), {"initial": f"positions, {prefilter_method} prefilter state at its "
                                        "first kept frame", "t0_s": float(arr["t"][0])}


def rollout_models(cfg: dict[str, Any], model_dir: str | Path, theta0_deg: float | None, out: str | Path,
                   energy_out: str | Path | None = None, t_end: float | None = None,
                   label: str | None = None, inputs_file: str | Path | None = None,
                   initial: str | Path | None = None) -> Trajectory:
    """Roll a ``crgpr learn`` model directory out from the straight rod at rest at ``theta0_deg``
    or from the first frame of the measured file ``initial`` (``initial_state``), driven by the
    actuation inputs of ``inputs_file`` (with the G of the model's manifest, else of the config's
    ``ports``) besides the model's gravity. Every input is checked before anything is written."""
    model, man = load_learned(model_dir)
    st = rollout_settings(cfg, model.params, t_end)
    if (theta0_deg is None) == (initial is None):
        raise ConfigError("give exactly one of --theta0 and --initial")
    init = None
    if initial is not None:
        q0, p0, t_init, how = initial_state(initial, cfg, model.params, man["prefilter"])
        if q0.shape != (model.params.N + 1, 3):
            raise MeasuredDataError(f"{initial}: {q0.shape[0]} nodes, the model has N + 1 = "
                                    f"{model.params.N + 1}")
        init = (q0, p0, t_init)
        theta0_deg = math.nan
    inputs, ports = None, None
    if inputs_file is not None:
        t_init = 0.0 if init is None else init[2]
        inputs = read_inputs(inputs_file, t_init + st.t_end, t_init)
        ports = Ports(float(man["ports"]["tendon_offset_m"])) if man.get("ports") else ports_from_config(cfg)
    label = label or f"{man['features']}/{man['prefilter']} model {model_dir}"
    where = f"theta0 = {theta0_deg:g} deg" if init is None else f"the first frame of {initial}"
    t0 = time.perf_counter()
    traj = learned.rollout(model, theta0_deg, st, what=f"{label} from {where}", inputs=inputs, ports=ports,
                   initial=init)
    meta = {"kind": "rollout", "method": label, "theta0_deg": theta0_deg, "features": man["features"],
            "prefilter": man["prefilter"], "model_dir": str(model_dir), "trained_on": man["source"],
            "seconds": time.perf_counter() - t0, "rod": model.params.to_dict(), "simulation": st.to_dict(),
            "initial": None if init is None else {"file": str(initial), **how},
            "inputs": None if inputs is None else inputs.describe(),
            "ports": None if ports is None else ports.to_dict()}
    write_parquet(trajectory_frame(traj), out, meta)
    if energy_out is not None:
        write_parquet(learned.learned_energy(model, traj, st.dt), energy_out,
                      {**meta, "kind": "rollout_energy"})
    return traj


def try_rollout(model: LearnedRod, theta0_deg: float, st: SimSettings) -> tuple[Trajectory | None, dict]:
    """A rollout that records a divergence instead of raising (for sweeps)."""
    try:
        return learned.rollout(model, theta0_deg, st), {"diverged": False}
    except SimulationDiverged as exc:
        return None, {"diverged": True, "diverged_t_s": exc.t, "diverged_node": exc.node}


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("rollout", help="step 4: simulate a learned CR-GPR model",
                       description="Integrate dz/dt = (J - R) H_z_hat + G u (eq. (17)) from the "
                                   "straight rod at rest.")
    p.add_argument("--method", help="a key of rollouts.methods (cr_gpr, ...); without it, the "
                   "features and rod are read from MODELS/manifest.json (a crgpr learn directory)")
    start = p.add_mutually_exclusive_group(required=True)
    start.add_argument("--theta0", type=float, help="initial angle [deg] (straight rod at rest)")
    start.add_argument("--initial", help="start from the first frame of this measured file (the format "
                       "of crgpr learn --measured; manifest models)")
    p.add_argument("--inputs", help="actuation inputs: Parquet or CSV with t [s] and one column per channel "
                   "(manifest models; docs/ports.md)")
    p.add_argument("--models", required=True, help="directory of the model files")
    p.add_argument("--out", required=True)
    p.add_argument("--energy-out")
    p.add_argument("--t-end", type=float,
                   help="simulated time [s] (manifest models; default simulation.t_end_s)")
    add_config_options(p, "simulation settings, ports and, with --method, rollouts.methods")
    p.set_defaults(func=_cli_rollout)


def _cli_rollout(a: argparse.Namespace) -> None:
    cfg, _ = cli_config(a.config, a.set)
    if a.method is None:
        rollout_models(cfg, a.models, a.theta0, a.out, a.energy_out, a.t_end, inputs_file=a.inputs,
                       initial=a.initial)
    elif a.initial is not None or a.inputs is not None:
        raise ConfigError("--initial and --inputs apply to manifest models (without --method)")
    elif a.t_end is not None:
        raise ConfigError("--t-end applies to manifest models (without --method); configured methods "
                          "use simulation.t_end_s")
    else:
        learned.run_rollout(cfg, a.method, a.theta0, a.models, a.out, a.energy_out)
