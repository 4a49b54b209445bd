"""Missing-physics workflow (beyond the paper).

* ``measured``: loading, validating and screening camera markers (``load_measured``);
* ``kinematics``: GP smoothing in time, the rod on the model grid from the markers;
* ``effects``: the library of candidate effects (``EFFECTS``);
* ``residual``: the cut-moment (port-Hamiltonian) residual and each candidate's signature;
* ``selection``: locate, floor, stepwise selection confirmed by trajectory fits (``discover``);
* ``synthetic``: camera-like records of hidden-effect cases (``make_measured``).
Figures and reports are in ``crgpr.report.discovery``; rules and CLI in
``crgpr.commands.discovery``.
"""

from crgpr.discovery.effects import EFFECT_NAMES, EFFECTS, Effect, effect_params
from crgpr.discovery.measured import Measured, MeasuredDataError, ScreenSettings, load_measured
from crgpr.discovery.selection import DiscoverySettings, discover

__all__ = ["EFFECTS", "EFFECT_NAMES", "DiscoverySettings", "Effect", "Measured", "MeasuredDataError",
           "ScreenSettings", "discover", "effect_params", "load_measured"]
