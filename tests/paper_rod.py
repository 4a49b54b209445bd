"""The paper's rod and time grid for tests, read from config.yaml (the one place they live).

``paper_rod(N=8)`` is Table I's rod with the given fields changed; ``paper_sim(t_end=0.5)``
the paper's time grid (Sec. IV: dt = 1e-4 s, T = 2 s, every 5th step recorded) likewise.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

from crgpr.config import load_config, rod_params, sim_settings
from crgpr.physics.params import RodParams, SimSettings

_CFG = load_config(Path(__file__).resolve().parents[1] / "config.yaml")
PAPER_ROD: RodParams = rod_params(_CFG)
PAPER_SIM: SimSettings = sim_settings(_CFG)


def paper_rod(**changes: Any) -> RodParams:
    return PAPER_ROD.replace(**changes)


def paper_sim(**changes: Any) -> SimSettings:
    return dataclasses.replace(PAPER_SIM, **changes)
