"""crgpr: Cosserat-rod Gaussian-process regression (CR-GPR), a reproducibility study."""

__version__ = "0.1.0"
