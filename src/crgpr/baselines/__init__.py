"""Baselines of the paper's Sec. V ("Baseline Comparisons"): ``pinn`` and ``blackbox`` (GP)."""
