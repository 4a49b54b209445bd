"""Section ``uq`` of config.yaml as a typed record (units and ranges: its schema)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from crgpr.config import ConfigError

SAMPLERS = ("sparse_pathwise", "exact_pathwise")
POSTERIOR_SCALES = ("jackknife_covariance", "heldout_jackknife", "heldout_split", "heldout_median",
                    "heldout_rms", "none")


@dataclass(frozen=True)
class UQSettings:
    """Trajectory-UQ settings: which methods are sampled, how, and which bands are scored.

    ``levels`` are the nominal central band levels in percent (band = percentiles
    50 -/+ level / 2 over the S sampled trajectories); ``paper_n_samples`` is the paper's
    S = 10, reported from the first samples of the same ensemble.
    """

    methods: tuple[str, ...]
    sampler: str
    n_samples: int
    paper_n_samples: int
    n_features: int
    inducing: int
    levels: tuple[float, ...]
    angles_deg: tuple[int, ...]
    figure_angle_deg: int
    figure_level: float
    figure_time_fractions: tuple[float, ...]
    exact_check_max_n: int
    check_points: int
    posterior_scale: str
    heldout_blocks: int
    kernel_tol: float
    update_rank_tol: float
    update_rank_max_error: float
    tabulated_exact_max_n: int

    @classmethod
    def from_section(cls, u: dict[str, Any]) -> UQSettings:
        """From the ``uq`` section (already schema-validated); cross-key checks here."""
        s = cls(methods=tuple(str(m) for m in u["methods"]), sampler=str(u["sampler"]),
                n_samples=int(u["n_samples"]), paper_n_samples=int(u["paper_n_samples"]),
                n_features=int(u["n_features"]), inducing=int(u["inducing"]),
                levels=tuple(float(v) for v in u["levels"]),
                angles_deg=tuple(int(a) for a in u["angles_deg"]),
                figure_angle_deg=int(u["figure_angle_deg"]), figure_level=float(u["figure_level"]),
                figure_time_fractions=tuple(float(f) for f in u["figure_time_fractions"]),
                exact_check_max_n=int(u["exact_check_max_n"]), check_points=int(u["check_points"]),
                posterior_scale=str(u["posterior_scale"]), heldout_blocks=int(u["heldout_blocks"]),
                kernel_tol=float(u["kernel_tol"]), update_rank_tol=float(u["update_rank_tol"]),
                update_rank_max_error=float(u["update_rank_max_error"]),
                tabulated_exact_max_n=int(u["tabulated_exact_max_n"]))
        if s.sampler not in SAMPLERS:
            raise ConfigError(f"config key uq.sampler: {s.sampler!r} is not one of {SAMPLERS}")
        if s.posterior_scale not in POSTERIOR_SCALES:
            raise ConfigError(f"config key uq.posterior_scale: {s.posterior_scale!r} is not one of "
                              f"{POSTERIOR_SCALES}")
        if s.posterior_scale == "jackknife_covariance" and s.sampler != "sparse_pathwise":
            raise ConfigError("config key uq.posterior_scale: jackknife_covariance needs uq.sampler "
                              "sparse_pathwise (the DTC coefficients it resamples)")
        if s.paper_n_samples > s.n_samples:
            raise ConfigError(f"config key uq.paper_n_samples: {s.paper_n_samples} > uq.n_samples "
                              f"= {s.n_samples} (the paper's row uses the first samples)")
        if s.figure_level not in s.levels:
            raise ConfigError(f"config key uq.figure_level: {s.figure_level:g} is not in uq.levels")
        if not all(0.0 < v < 100.0 for v in s.levels):
            raise ConfigError("config key uq.levels: every level must lie in (0, 100)")
        return s

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def band_percentiles(level: float) -> tuple[float, float]:
    """Central band of nominal ``level`` % as (lower, upper) percentiles, e.g. 95 -> (2.5, 97.5)."""
    return 50.0 - 0.5 * level, 50.0 + 0.5 * level
