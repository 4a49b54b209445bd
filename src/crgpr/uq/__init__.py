"""Trajectory uncertainty by posterior function samples (paper Sec. III-B, "Uncertainty
Quantification via RFF Sampling"; Sec. V, "Uncertainty Quantification Results").

Public API, one module per step (imported from the modules themselves, so that
``crgpr.config``, which reads ``uq.settings``, does not pull the sampler, the rollout and the
coverage code into every rule's code inputs):

* ``uq.samples``: ``draw_model_samples``, ``sample_model``, ``load_samples``,
  ``TabulatedSamples``: S joint posterior samples of every gradient GP of a method (sample sets
  that are ``LearnedRod`` components with a leading sample axis);
* ``uq.rollout``: ``rollout_samples``, ``sampled_rod``: the sampled ``LearnedRod`` through
  ``learning.learned.rollout`` as one batch;
* ``uq.coverage``: ``coverage_rows``, ``expected_coverage``: band coverage at several levels and
  the calibrated reference e(S, L);
* ``uq.calibration``: ``function_calibration``: function-level calibration of the gradient GPs
  (diagnostic);
* ``uq.settings``: ``UQSettings``, ``band_percentiles``: the ``uq`` config section.
Figures: ``crgpr.report.uq``; rule functions: ``crgpr.commands.uq``.
"""

__all__ = ["calibration", "coverage", "rollout", "samples", "settings"]
