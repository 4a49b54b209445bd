"""Ground truth, step 1 of the paper's Sec. III-B (Sec. IV, "Step 1"): rule ``ground_truth``
and the command ``crgpr simulate``.

Writes ``results/ground_truth/{angle}.parquet`` (one row per (t, node)) and
``results/ground_truth/{angle}_energy.parquet`` (one row per t), with the parameters and
the code version in the Parquet metadata.
"""

from __future__ import annotations

import argparse
import logging
import math
from pathlib import Path
from typing import Any

from crgpr.config import ConfigError, cli_rod_sim, load_config, rod_params, schema_defaults, sim_settings
from crgpr.io import write_parquet
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import Ports, ports_from_config
from crgpr.physics.signals import Inputs, InputsError, SignalInputs, read_inputs
from crgpr.physics.simulate import energy_frame, simulate, trajectory_frame

log = logging.getLogger(__name__)


def write_ground_truth(theta0_deg: float, params: RodParams, settings: SimSettings,
                       out: str | Path, energy_out: str | Path | None = None,
                       extra_meta: dict[str, Any] | None = None, inputs: Inputs | None = None,
                       ports: Ports | None = None) -> None:
    """Simulate one angle and write the trajectory (and energy) Parquet files atomically;
    ``inputs`` drive the ``ports`` (``physics.ports``; recorded in the metadata, and the energy
    file gets the input work and each channel's u and y)."""
    dt_max = params.dt_stable()
    if settings.dt >= dt_max:
        raise ConfigError(f"dt = {settings.dt:g} s is too large for a stable run (need < {dt_max:.3g} s)")
    traj = simulate(theta0_deg, params, settings, inputs=inputs, ports=ports)
    meta = {"kind": "ground_truth", "theta0_deg": theta0_deg, "rod": params.to_dict(),
            "simulation": settings.to_dict(), **(extra_meta or {})}
    if inputs is not None and ports is not None:
        meta["inputs"] = inputs.describe()
        meta["ports"] = ports.to_dict()
    log.info("theta0 = %s deg: %d samples, tip at t_end = (%.4f, %.4f) m", theta0_deg,
             len(traj.t), traj.q[-1, -1, 0], traj.q[-1, -1, 1])
    if energy_out is not None:
        write_parquet(energy_frame(traj), energy_out, {**meta, "kind": "ground_truth_energy"})
    write_parquet(trajectory_frame(traj), out, meta)


def ground_truth(cfg: dict[str, Any], angle: int, out: str, energy_out: str) -> None:
    """Rule ``ground_truth`` (config: ``rod``, ``simulation`` incl. ``scheme``; deterministic, no seed)."""
    write_ground_truth(float(angle), rod_params(cfg), sim_settings(cfg), out, energy_out)


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="simulate the Cosserat rod from a straight initial state",
                       description="Simulate the planar Cosserat rod dPHS released at rest, "
                                   "straight at THETA0, clamped base, free tip.")
    p.add_argument("--theta0", type=float, required=True, help="initial angle from +x [deg]")
    p.add_argument("--out", required=True, help="trajectory Parquet file to write")
    p.add_argument("--energy-out", help="optional energy Parquet file (t, H, dissipation_rate)")
    p.add_argument("--config", default=None, help="config.yaml for the defaults (default: the "
                   "paper's parameters, or ./config.yaml if it exists)")
    p.add_argument("--t-end", type=float, help="simulated time [s]")
    p.add_argument("--dt", type=float, help="time step [s]")
    p.add_argument("--record-every", type=int, help="record every k-th step")
    p.add_argument("--scheme", help="spatial discretisation: variational | collocated "
                   "(config key simulation.scheme)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a rod parameter, e.g. --set E=2e6, or a key of its material, e.g. "
                        "--set material.bending_law=exponential (repeatable)")
    src = p.add_mutually_exclusive_group()
    src.add_argument("--inputs", help="actuation inputs: Parquet or CSV file with t [s] and one column "
                     "per channel (tip_force_x, tip_force_y, tip_moment, tendon_tension); docs/ports.md")
    src.add_argument("--signal", help="actuation inputs: a named sequence of the config's ports.signals")
    p.set_defaults(func=_cli)


def _cli(args: argparse.Namespace) -> None:
    cfg_path = args.config or ("config.yaml" if Path("config.yaml").exists() else None)
    if cfg_path:
        cfg = load_config(cfg_path)
        rod, sim, base = cfg["rod"], cfg["simulation"], str(cfg_path)
    else:  # the paper's rod and time grid: the config schema's defaults (= config.yaml's)
        rod, sim, base = schema_defaults("rod"), schema_defaults("simulation"), "the paper's defaults"
    params, settings = cli_rod_sim(rod, sim, args.set, args.dt, args.t_end, args.record_every, base,
                                   args.scheme)
    if not math.isfinite(args.theta0):
        raise ConfigError(f"--theta0 {args.theta0}: must be a finite angle [deg]")
    inputs, ports = cli_inputs(cfg if cfg_path else None, args.inputs, args.signal, settings.t_end, base)
    write_ground_truth(args.theta0, params, settings, args.out, args.energy_out, inputs=inputs, ports=ports)


def cli_inputs(cfg: dict[str, Any] | None, inputs_file: str | None, signal: str | None, t_end: float,
               source: str) -> tuple[Inputs | None, Ports | None]:
    """The inputs of ``--inputs FILE`` (checked to cover [0, t_end]) or ``--signal NAME`` (the
    config's ``ports.signals``) and the config's channels; (None, None) for neither."""
    if inputs_file is None and signal is None:
        return None, None
    if cfg is None:
        raise ConfigError("--inputs/--signal: need a config (--config, or ./config.yaml) for the "
                          "channels' G (ports.tendon_offset_m)")
    sec = cfg["ports"]
    ports = ports_from_config({"ports": sec})
    if inputs_file is not None:
        return read_inputs(inputs_file, t_end), ports
    if signal not in sec.get("signals", {}):
        raise InputsError(f"--signal {signal}: not in {source}'s ports.signals "
                          f"({sorted(sec.get('signals', {}))})")
    return SignalInputs(sec["signals"][signal], signal), ports
