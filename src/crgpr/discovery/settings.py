"""Selection settings of the missing-physics workflow (config section ``discovery``)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any


@dataclass(frozen=True)
class DiscoverySettings:
    """Selection settings of the ``discovery`` config section (units in the names; the values
    live in config.yaml and its schema only)."""

    edge_trim_s: float
    init_window_s: float
    init_modes: int
    window_s: float
    min_gap_rad: float
    min_explained: float
    max_remaining: float
    min_effect_fraction: float
    max_confirm: int
    max_effects: int
    bic_min_improvement: float
    refine_max_nfev: int
    gp_max_points: int
    bootstrap_replicates: int
    floor_clamp_m: float
    clamp_form_m: float
    floor_clamp_factor: float
    holdout_blocks: int
    holdout_min_evidence: float
    describe_knots: int
    describe_prior_std: float
    describe_length_scale: float
    describe_iterations: int
    describe_band_z: float
    seed: int

    @classmethod
    def config_keys(cls) -> tuple[str, ...]:
        """The keys of the ``discovery`` config section these settings read (all but the seed)."""
        return tuple(f.name for f in fields(cls) if f.name != "seed")

    @classmethod
    def from_config(cls, d: dict[str, Any], seed: int) -> DiscoverySettings:
        """From the ``discovery`` section ``d``; ``seed`` is the workflow's seed."""
        return cls(edge_trim_s=float(d["edge_trim_s"]), init_window_s=float(d["init_window_s"]),
                   init_modes=int(d["init_modes"]), window_s=float(d["window_s"]),
                   min_gap_rad=float(d["min_gap_rad"]), min_explained=float(d["min_explained"]),
                   max_remaining=float(d["max_remaining"]),
                   min_effect_fraction=float(d["min_effect_fraction"]), max_confirm=int(d["max_confirm"]),
                   max_effects=int(d["max_effects"]), bic_min_improvement=float(d["bic_min_improvement"]),
                   refine_max_nfev=int(d["refine_max_nfev"]), gp_max_points=int(d["gp_max_points"]),
                   bootstrap_replicates=int(d["bootstrap_replicates"]),
                   floor_clamp_m=float(d["floor_clamp_m"]), clamp_form_m=float(d["clamp_form_m"]),
                   floor_clamp_factor=float(d["floor_clamp_factor"]),
                   holdout_blocks=int(d["holdout_blocks"]),
                   holdout_min_evidence=float(d["holdout_min_evidence"]),
                   describe_knots=int(d["describe_knots"]), describe_prior_std=float(d["describe_prior_std"]),
                   describe_length_scale=float(d["describe_length_scale"]),
                   describe_iterations=int(d["describe_iterations"]),
                   describe_band_z=float(d["describe_band_z"]), seed=int(seed))
