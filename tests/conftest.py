"""Fixtures shared by several test modules."""

from __future__ import annotations

from pathlib import Path

import pytest

from crgpr.config import load_config, rod_params
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import Trajectory, simulate

SMOKE = Path(__file__).resolve().parent / "smoke_config.yaml"


@pytest.fixture(scope="session")
def smoke_training_run() -> tuple[dict, Trajectory]:
    """The smoke config and its 85 deg training trajectory (0.4 s, every 40th step of dt = 1e-4),
    the record the camera-learning tests train on."""
    cfg = load_config(SMOKE)
    settings = SimSettings(dt=1e-4, t_end=0.4, record_every=40, scheme="variational")
    return cfg, simulate(85.0, rod_params(cfg), settings)
