"""Trajectory uncertainty by posterior function samples (paper Sec. III-B, "Uncertainty
Quantification via RFF Sampling"; Sec. V, "Uncertainty Quantification Results").

* ``samples``: S joint posterior samples of every gradient GP of a method (sample sets that are
  ``LearnedRod`` components with a leading sample axis);
* ``rollout``: the sampled ``LearnedRod`` through ``learning.learned.rollout`` as one batch;
* ``coverage``: band coverage at several levels and the calibrated reference e(S, L);
* ``calibration``: function-level calibration of the gradient GPs (diagnostic);
* ``settings``: the ``uq`` config section.
Figures: ``crgpr.report.uq``; rule functions: ``crgpr.commands.uq``.
"""

from crgpr.uq.coverage import coverage_rows, expected_coverage
from crgpr.uq.rollout import rollout_samples, sampled_rod
from crgpr.uq.samples import TabulatedSamples, draw_model_samples, load_samples, sample_model
from crgpr.uq.settings import UQSettings, band_percentiles

__all__ = [
    "TabulatedSamples", "UQSettings", "band_percentiles", "coverage_rows", "draw_model_samples",
    "expected_coverage", "load_samples", "rollout_samples", "sample_model", "sampled_rod",
]
