"""Learned rollouts, step 4 of the paper's Sec. III-B: rule ``rollout`` and ``crgpr rollout``.

Writes ``results/rollouts/{method}/{angle}.parquet`` and ``_energy.parquet`` (algorithm:
``crgpr.learning.learned``).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from crgpr.config import ConfigError, add_config_options, cli_config
from crgpr.learning import learned


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
        from crgpr.commands.learn import rollout_models

        rollout_models(cfg, a.models, a.theta0, a.out, a.energy_out, a.t_end, inputs_file=a.inputs,
                       initial=a.initial)
    elif a.initial is not None or a.inputs is not None:
        raise ConfigError("--initial and --inputs apply to manifest models (without --method)")
    elif a.t_end is not None:
        raise ConfigError("--t-end applies to manifest models (without --method); configured methods "
                          "use simulation.t_end_s")
    else:
        learned.run_rollout(cfg, a.method, a.theta0, a.models, a.out, a.energy_out)
