"""Learning H_z from data (paper Sec. III-B, steps 2-4).

* ``prefilter``: state derivatives from a trajectory (GP or finite differences, step 2);
* ``features``: feature sets (the paper's, frame-indifferent) and H_z targets (eq. (13));
* ``gradient_models``: the gradient GPs of Table II (step 3);
* ``learned``: the learned rod H_z_hat and its rollouts (step 4, eq. (17));
* ``oracle``: the constitutive law written in the paper's features (components for LearnedRod,
  the oracle ablation).
"""
