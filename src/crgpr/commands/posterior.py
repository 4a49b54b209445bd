"""Posterior samples of a model directory's learned laws, for the studies that use them (the
control study's odds, the actuated study's bands; docs/uncertainty.md).

Not a stage of its own: shared by the ``control`` and ``ports`` command modules, so neither
imports the other.
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

log = logging.getLogger(__name__)


def posterior_components(model_dir: str | Path, man: dict[str, Any], cfg: dict[str, Any], n_samples: int
                         ) -> tuple[dict[str, Any], float | None]:
    """The components of a model directory's learned rod with its learned force laws replaced by
    ``n_samples`` joint posterior samples each (``crgpr.uq.samples``: the ``uq`` section's sampler,
    features and posterior scale; seed ``uq_seed(seed, name)``). The momentum maps stay at their
    means (a map p -> H_p learned from the exact kinematic identity; the control design's statics
    do not use them); nominal laws stay. Returns (components, theta centre) as
    ``commands.learn.learned_components``."""
    from crgpr.commands.learn import learned_components, learned_models
    from crgpr.gp.evaluators import load_evaluator
    from crgpr.learning.gradient_models import MOMENTUM_MODELS
    from crgpr.uq.samples import draw_model_samples, load_gp_spec, uq_seed
    from crgpr.uq.settings import UQSettings

    K = int(n_samples)
    u = dict(cfg["uq"])
    # K samples of the UQ path (its paper_n_samples, a reporting subset of S, does not apply)
    settings = UQSettings.from_section({**u, "n_samples": K,
                                        "paper_n_samples": min(K, int(u["paper_n_samples"]))})
    d = Path(model_dir)
    sampled = [m for m in learned_models(man) if m not in MOMENTUM_MODELS]

    def load(m: str) -> Any:
        if m not in sampled:
            return load_evaluator(d / m)
        spec, Z, grid = load_gp_spec(d / m, m)
        comp, info = draw_model_samples(spec, settings, uq_seed(int(cfg["seed"]), m), Z, grid)
        log.info("posterior samples of %s: %d in %.1f s (posterior scale %.3g)", m, K, info["seconds"],
                 info.get("posterior_scale", float("nan")))
        return comp
    return learned_components(d, man, load)
