"""Seeds: every random choice of the pipeline derives its seed from the one config key ``seed``.

Call these instead of writing a formula at the call site. The formulas are the ones that
produced the committed results (changing one changes every random subset downstream of it):

* ``stage_seed(seed, stage, index)``: seed + STAGE_OFFSETS[stage] + index, for stages that draw
  per angle or per model (prefilter: index = angle in deg; gradient_model: index = the model's
  position in ``gradient_models.ALL_MODELS``; blackbox: index 0, its k-th GP adds k);
* ``name_seed(seed, name)``: (seed * 1000003 + crc32(name)) mod 2^32, for named cases
  (discovery cases);
* ``sequence_seed(seed, *keys)``: numpy's SeedSequence of (seed, *keys), for streams keyed by
  several integers (UQ samples: keys = (5, model index));
* ``pinn_seed(seed, variant)``: (seed * 1000003 + 7919 sum(ord(variant))) mod (2^31 - 1), the
  PINN variants' torch seed.
"""

from __future__ import annotations

import zlib

import numpy as np

STAGE_OFFSETS: dict[str, int] = {"prefilter": 1000, "gradient_model": 2000, "blackbox": 4000}


def stage_seed(seed: int, stage: str, index: int = 0) -> int:
    """seed + STAGE_OFFSETS[stage] + index (module docstring)."""
    if stage not in STAGE_OFFSETS:
        raise KeyError(f"unknown seed stage {stage!r}; expected one of {sorted(STAGE_OFFSETS)}")
    return int(seed) + STAGE_OFFSETS[stage] + int(index)


def name_seed(seed: int, name: str) -> int:
    """(seed * 1000003 + crc32(name)) mod 2^32: a stable seed per named case."""
    return (int(seed) * 1000003 + zlib.crc32(name.encode())) % (2**32)


def sequence_seed(seed: int, *keys: int) -> int:
    """First 32-bit word of numpy's SeedSequence([seed, *keys])."""
    return int(np.random.SeedSequence([int(seed), *map(int, keys)]).generate_state(1)[0])


def pinn_seed(seed: int, variant: str) -> int:
    """(seed * 1000003 + 7919 sum(ord(variant))) mod (2^31 - 1), the PINN variants' seed."""
    return (int(seed) * 1000003 + sum(map(ord, variant)) * 7919) % (2**31 - 1)
