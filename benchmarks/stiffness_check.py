"""Benchmark: is a learned rod's force field the gradient of one stored energy?

    python benchmarks/stiffness_check.py MODEL_DIR [--frames 5]

For a ``crgpr learn`` directory of objective features whose record (the manifest's ``source``:
a full-state trajectory or a camera record's reconstructed state) is still where it was, prints
``learning.stiffness.stiffness_check`` at ``--frames`` evenly spaced frames of the record (the
manifest's ``stiffness_check``, recomputed: directories written before it was recorded have
none), and at the frame of the largest reciprocity gap the clamp segment's law Jacobian
d(n1, n2, m)/d(nu1, nu2, kappa) beside the nominal one (docs/learned-laws.md, "Each law of its
own strain"). A directory that is not a crgpr learn directory, or a record that is not a
full-state trajectory, is one line on stderr (exit code 2).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from crgpr.commands.model_dir import load_learned
from crgpr.io import read_parquet
from crgpr.learning.stiffness import law_jacobian, reciprocity_gap, stiffness_check
from crgpr.physics.simulate import trajectory_from_frame


def record_states(path: str, params) -> np.ndarray:
    """Configurations (n_t, N+1, 3) of a full-state trajectory file."""
    df = read_parquet(path)
    if "node" not in df.columns:
        raise ValueError(f"{path}: not a full-state trajectory (no column node)")
    return trajectory_from_frame(df, params).q


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("model_dir")
    ap.add_argument("--frames", type=int, default=5)
    args = ap.parse_args()
    try:
        model, man = load_learned(args.model_dir)
        if man["features"] != "objective":
            raise ValueError(f"{args.model_dir}: {man['features']} features have no separate laws")
        q = record_states(man["source"], model.params)
    except (OSError, ValueError, KeyError) as exc:
        print(f"stiffness_check.py: {exc}", file=sys.stderr)
        sys.exit(2)
    print(f"{Path(args.model_dir)}: laws learned {man['models']}, nominal {man['nominal_laws']}")
    print(stiffness_check(model, q, args.frames))
    ks = np.unique(np.linspace(0, q.shape[0] - 1, args.frames).round().astype(int))
    k = max(ks, key=lambda i: reciprocity_gap(model, q[i]))
    P = model.params
    np.set_printoptions(precision=4, suppress=False)
    print(f"clamp segment at t index {k}: d(n1, n2, m)/d(nu1, nu2, kappa) =\n{law_jacobian(model, q[k])[0]}")
    print(f"nominal: diag(EA, GA, EI) = ({P.EA:.4g}, {P.GA:.4g}, {P.EI:.4g})")


if __name__ == "__main__":
    main()
