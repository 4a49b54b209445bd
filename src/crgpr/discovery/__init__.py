"""Missing-physics workflow (beyond the paper).

* ``measured``: loading and validating measured rod positions, kinematics by GP smoothing;
* ``effects``: the library of candidate effects and the cut-moment residual;
* ``selection``: stepwise selection confirmed by trajectory fits (``run_discovery``).
"""
