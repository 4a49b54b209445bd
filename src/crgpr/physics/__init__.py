"""Physics of the planar Cosserat rod (paper Sec. III-A, eqs. (3)-(10); Sec. IV, Table I).

Public API:
* ``RodParams``, ``SimSettings``: the rod's parameters (Table I) and the time grid;
* ``rod``: the variational discretisation (strains, resultants, ``variational_derivative``);
* ``integrator``: the Stormer-Verlet scheme with Strang-split dissipation;
* ``simulate``: ground-truth trajectories (``simulate``, ``Trajectory``, Parquet frames).
"""

from crgpr.physics.integrator import Integration, SimulationDiverged, run_generic, run_hamiltonian, run_rod
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import (
    STATE_NAMES,
    free_mask,
    masses,
    node_weights,
    straight_rod,
    variational_derivative,
)
from crgpr.physics.simulate import (
    TRAJECTORY_COLUMNS,
    Trajectory,
    simulate,
    trajectory_frame,
    trajectory_from_frame,
)

__all__ = [
    "Integration", "RodParams", "STATE_NAMES", "SimSettings", "SimulationDiverged", "TRAJECTORY_COLUMNS",
    "Trajectory", "free_mask", "masses", "node_weights", "run_generic", "run_hamiltonian", "run_rod",
    "simulate", "straight_rod", "trajectory_frame", "trajectory_from_frame", "variational_derivative",
]
