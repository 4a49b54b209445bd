"""Missing-physics workflow (beyond the paper), on measured records (``crgpr.measured``).

* ``effects``: the library of candidate effects (``EFFECTS``);
* ``residual``: the cut-moment (port-Hamiltonian) residual and each candidate's signature;
* ``settings``: the selection settings of the ``discovery`` config section;
* ``trajectory``: the model simulated from a fitted initial state and fitted to the markers;
* ``regression``: the candidates' regression on the residual (BIC, autocorrelation);
* ``locate``: where, when and in which state group the nominal model departs;
* ``floor``: the gap with nothing missing (camera noise, initial state, discretisation);
* ``stepwise``: entry threshold, backward elimination, swaps, indistinguishable alternatives;
* ``holdout``: leave-one-effect-out on held-out time blocks (no effect the others make redundant);
* ``prune``: the smallest model that reaches its own floor (effects a named model does not need);
* ``describe``: a learned EI(s) where no library effect closes the gap (verdict ``described``);
* ``selection``: the workflow (``discover``);
* ``synthetic``: camera-like records of hidden-effect cases (``make_measured``).
Figures and reports are in ``crgpr.report.discovery``; rules and CLI in
``crgpr.commands.discovery``.
"""

from crgpr.discovery.effects import EFFECT_NAMES, EFFECTS, Effect, effect_params
from crgpr.discovery.selection import discover
from crgpr.discovery.settings import DiscoverySettings

__all__ = ["EFFECTS", "EFFECT_NAMES", "DiscoverySettings", "Effect", "discover", "effect_params"]
