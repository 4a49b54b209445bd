"""Benchmark: the arclength test of ``crgpr learn`` (``law_choice.arclength_dependence``) on the
records of many rods, with its variants side by side (docs/learned-laws.md, "Arclength as an
input of the bending law").

    python benchmarks/arclength_test.py --csv benchmarks/arclength_test.csv
    python benchmarks/arclength_test.py --inputs camera --cases stiff_local,linear --csv OUT.csv

For each rod (the materials study's six cases, the rods of ``benchmarks/materials_unseen.py``'s
``CASES`` and the six probes of docs/materials.md, "Rods of one's own"; each at its own release
angle) the training record is made as the study makes it (``materials_study`` of ``--config``:
its 2 s release, the full state, and every node's positions at 250 Hz with 1 mm noise, seeded by
the case name as ``commands.materials.camera_seed``). The bending law's samples are built as
``crgpr learn`` builds them (positions: the ``gp`` reconstruction with ``camera.learn``, its
``n_t_out`` frames and ``trim_ends``; full state: the ``fd`` prefilter, the study's), and the
uniform spline in kappa is compared with the spline whose coefficients are polynomials in s, for
s-degrees 1-3, unweighted (``none``) and with every segment weighted alike (``segment``). One row
per (case, input, s_degree, weights): the held-out mean log error ratio, its se, and whether the
law takes s (``richer``); ``varies_along_s``: whether the true rod's stiffness varies along s (a
profile or a defect). Learns nothing; the segments are ``crgpr learn``'s trimmed inner ones, not
its curvature-SNR selection.
"""

from __future__ import annotations

import argparse
import copy
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))
from materials_unseen import CASES as UNSEEN  # noqa: E402

from crgpr.commands.camera import camera_frame  # noqa: E402
from crgpr.commands.learn import model_params  # noqa: E402
from crgpr.commands.materials import camera_seed, study_settings  # noqa: E402
from crgpr.config import load_config, material_case_rod, rod_params  # noqa: E402
from crgpr.learning.camera import LearnSettings, positions_to_state  # noqa: E402
from crgpr.learning.features import segment_arclength  # noqa: E402
from crgpr.learning.gradient_models import inner_segments, training_data  # noqa: E402
from crgpr.learning.law_choice import arclength_dependence  # noqa: E402
from crgpr.learning.prefilter import PrefilterSettings, prefilter, prefiltered_arrays  # noqa: E402
from crgpr.measured.records import ScreenSettings, validate_frame  # noqa: E402
from crgpr.physics.simulate import Trajectory, simulate  # noqa: E402

PROBES: dict[str, tuple[dict, float]] = {
    "stiff_local": ({"defect_start": 0.55, "defect_end": 0.75, "defect_factor": 1.8}, 85.0),
    "soft_precurved": ({"bending_law": "saturating", "saturation_moment": 0.1,
                        "rest_curvature_profile": [[0, 1.5], [1, 1.5]]}, 100.0),
    "exponential_small": ({"bending_law": "exponential", "bending_beta": 0.05}, 45.0),
    "graded_soft_tip": ({"bending_law": "saturating", "saturation_moment": 0.08,
                         "stiffness_profile": [[0, 1.0], [0.5, 1.0], [1.0, 0.4]]}, 85.0),
    "stretch_cubic": ({"stretch_law": "cubic", "stretch_stiffening": 50, "bending_law": "exponential",
                       "bending_beta": 0.03}, 85.0),
    "visco_precurved": ({"kelvin_voigt": 1.0e-4, "rest_curvature_profile": [[0, 2.0], [1, 2.0]]}, 70.0),
}


def samples(cfg: dict, case: str, material: dict, theta0: float, source: str, seed: int):
    """(kappa, s, m) of the bending law's samples of one rod's training record (module docstring)."""
    cfg = copy.deepcopy(cfg)
    cfg["materials_study"]["cases"] = {case: material}
    ms = cfg["materials_study"]
    truth = material_case_rod(cfg, case)
    tr = simulate(float(theta0), truth, study_settings(cfg, float(ms["t_end_s"])))
    cam = cfg["camera"]["learn"]
    if source == "camera":
        every = int(round(1.0 / (float(ms["camera_rate_hz"]) * float(np.median(np.diff(tr.t))))))
        table = camera_frame(tr.t[::every], tr.q[::every], float(ms["camera_noise_m"]),
                             camera_seed(int(cfg["seed"]), case))
        params = model_params(table, cfg)
        meas = validate_frame(table, case, params.L0, params.ds, ScreenSettings.from_config(cfg["discovery"]))
        arr, _ = positions_to_state(meas, params, "gp", LearnSettings.from_config(cam), seed)
        trim = int(cam["trim_ends"])
    else:
        params = rod_params(cfg)
        traj = Trajectory(float("nan"), tr.t, tr.q, tr.p, params)
        pre = prefilter(traj, str(ms["prefilter"]), PrefilterSettings.from_config(cfg), seed)
        arr = prefiltered_arrays(pre[0])
        trim = 0
    mask = inner_segments(params.N, trim)
    X, m = training_data(arr, params, "obj_m", None, mask)
    S = np.broadcast_to(segment_arclength(params.N, params.ds), (arr["x"].shape[0], params.N))
    S = S[:, mask].ravel()
    return X[:, 0], S, m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--cases", default=None, help="comma-separated case names (default: all)")
    ap.add_argument("--inputs", default="camera,full_state")
    ap.add_argument("--csv", default="benchmarks/arclength_test.csv")
    a = ap.parse_args()
    cfg = load_config(a.config)
    ms = cfg["materials_study"]
    cases = {**{k: (v, float(ms["theta0_deg"])) for k, v in ms["cases"].items()}, **UNSEEN, **PROBES}
    names = a.cases.split(",") if a.cases else list(cases)
    cam = cfg["camera"]["learn"]
    rows = []
    for case in names:
        material, theta0 = cases[case]
        varies = bool(material.get("stiffness_profile")) or "defect_factor" in material
        for source in a.inputs.split(","):
            kappa, s, m = samples(cfg, case, material, theta0, source, int(cfg["seed"]) + 3000)
            for s_degree in (1, 2, 3):
                for weights in ("none", "segment"):
                    c = arclength_dependence(kappa, s, m, int(cam["choice_degree"]), int(cam["choice_knots"]),
                                             s_degree, int(cam["choice_blocks"]), weights)
                    rows.append({"case": case, "input": source, "varies_along_s": varies,
                                 "s_degree": s_degree, "weights": weights, "richer": c.richer,
                                 "heldout_log_ratio": c.heldout_log_ratio,
                                 "heldout_log_ratio_se": c.heldout_log_ratio_se, "n_samples": int(m.size)})
                    print(rows[-1], flush=True)
    pd.DataFrame(rows).to_csv(a.csv, index=False)


if __name__ == "__main__":
    main()
