"""Fixtures shared by several test modules."""

from __future__ import annotations

from pathlib import Path

import pytest
from hypothesis import settings

from crgpr.config import load_config, rod_params
from crgpr.physics.params import SimSettings
from crgpr.physics.simulate import Trajectory, simulate

SMOKE = Path(__file__).resolve().parent / "smoke_config.yaml"

# property tests draw the same examples on every run (the suite's outcome does not depend on
# the run); the examples each test draws are still many and varied
settings.register_profile("fixed", derandomize=True)
settings.load_profile("fixed")


@pytest.fixture(scope="session")
def smoke_training_run() -> tuple[dict, Trajectory]:
    """The smoke config and its 85 deg training trajectory (0.4 s, every 40th step of dt = 1e-4),
    the record the camera-learning tests train on."""
    cfg = load_config(SMOKE)
    settings = SimSettings(dt=1e-4, t_end=0.4, record_every=40, scheme="variational")
    return cfg, simulate(85.0, rod_params(cfg), settings)
