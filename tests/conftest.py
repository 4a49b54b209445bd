"""Fixtures shared by several test modules."""

from __future__ import annotations

import os

# one BLAS / OpenMP thread, as the pipeline's rules and the command line run (commands/smk.py,
# limit_threads): a module's numbers are then those of `crgpr` itself, and do not depend on whether
# a test that ran before it on the same worker called the command line in-process (which limits
# the threads for the rest of that process)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

from pathlib import Path  # noqa: E402

import pytest  # noqa: E402
import scipy.linalg  # noqa: E402,F401 - its own BLAS loaded before the limit below
from hypothesis import settings  # noqa: E402

from crgpr.commands.smk import limit_threads  # noqa: E402
from crgpr.config import load_config, rod_params  # noqa: E402
from crgpr.physics.params import SimSettings  # noqa: E402
from crgpr.physics.simulate import Trajectory, simulate  # noqa: E402

limit_threads()

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
