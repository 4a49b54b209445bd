"""Physics of the planar Cosserat rod (paper Sec. III-A, eqs. (3)-(10); Sec. IV, Table I).

Public API:
* ``RodParams``, ``SimSettings``: the rod's parameters (Table I) and the time grid;
* ``Material`` (``material``): the rod's constitutive laws, config ``rod.material``
  (docs/materials.md);
* ``rod``: the variational discretisation (strains, resultants, ``variational_derivative``);
* ``collocated``: the collocated nodal finite-difference force kernels (config key
  ``simulation.scheme``; ``SCHEMES``), integrated by the same compiled kernel;
* ``integrator``: the one Stormer-Verlet scheme with Strang-split dissipation (``run_verlet``
  and its forms ``run_hamiltonian``, ``run_generic``, compiled ``run_rod``) and the one
  divergence policy (``diverged_nodes``, ``MAX_SPEED``, ``REACH``);
* ``simulate``: ground-truth trajectories (``simulate``, ``Trajectory``, Parquet frames).
"""

from crgpr.physics.integrator import (
    MAX_SPEED,
    REACH,
    Integration,
    SimulationDiverged,
    diverged_nodes,
    run_generic,
    run_hamiltonian,
    run_rod,
    run_verlet,
)
from crgpr.physics.material import BENDING_LAWS, STRETCH_LAWS, Material
from crgpr.physics.params import SCHEMES, RodParams, SimSettings
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
    "BENDING_LAWS", "STRETCH_LAWS", "Material",
    "MAX_SPEED", "REACH", "SCHEMES", "STATE_NAMES", "TRAJECTORY_COLUMNS", "Integration", "RodParams",
    "SimSettings",
    "SimulationDiverged", "Trajectory", "diverged_nodes", "free_mask", "masses", "node_weights",
    "run_generic", "run_hamiltonian", "run_rod", "run_verlet", "simulate", "straight_rod",
    "trajectory_frame", "trajectory_from_frame", "variational_derivative",
]
