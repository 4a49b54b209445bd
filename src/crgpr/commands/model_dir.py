"""A ``crgpr learn`` model directory read back: its manifest, the learned rod it holds (the
learned models, the laws taken from the nominal rod, the record fit's warp and the bending law's
continuation), and the names of its models."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from crgpr.config import ConfigError
from crgpr.gp.evaluators import load_evaluator
from crgpr.learning.extrapolation import TangentContinuation, manifest_reach
from crgpr.learning.features import OBJ_N_FEATURES, segment_arclength
from crgpr.learning.gradient_models import MOMENTUM_MODELS
from crgpr.learning.learned import OBJECTIVE_COMPONENTS, PAPER_COMPONENTS, LearnedRod
from crgpr.learning.nominal import NOMINAL_LAWS, NominalContinuation, NominalLaw, SelectedInputs
from crgpr.learning.warp import BendingWarp, manifest_warp
from crgpr.physics.params import RodParams

MANIFEST = "manifest.json"
FEATURES: tuple[str, ...] = ("objective", "paper")


def model_names(features: str) -> list[str]:
    """Gradient models of one feature set (constitutive part, then momenta)."""
    if features not in FEATURES:
        raise ConfigError(f"unknown feature set {features!r}; expected one of {FEATURES}")
    comps = OBJECTIVE_COMPONENTS if features == "objective" else PAPER_COMPONENTS
    return [*comps, *MOMENTUM_MODELS]


def read_manifest(model_dir: str | Path) -> dict[str, Any]:
    """The manifest of a ``crgpr learn`` model directory (clear error if absent)."""
    path = Path(model_dir) / MANIFEST
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no model manifest (train the directory with crgpr learn)")
    man = json.loads(path.read_text())
    if man.get("kind") != "crgpr_models" or man.get("features") not in FEATURES:
        raise ValueError(f"{path}: not a crgpr learn manifest")
    return man


def learned_models(man: dict[str, Any]) -> list[str]:
    """The gradient models a directory's manifest says were learned (the others are nominal laws)."""
    return list(man.get("models", model_names(man["features"])))


def learned_components(model_dir: str | Path, man: dict[str, Any], load: Callable[[str], Any]
                       ) -> tuple[dict[str, Any], float | None]:
    """The components of a model directory's learned rod and its theta window: each learned model
    as ``load(name)`` gives it (the rollout's evaluator, or its posterior samples for the UQ
    rollout), seen through ``SelectedInputs`` where it was fitted on some feature columns, and
    the laws taken from the nominal rod (``nominal_laws``, grey box); learned stretch and shear
    laws continued by the nominal ones beyond their covered inputs (``nominal.NominalContinuation``);
    the bending law times its record-fit warp where the manifest keeps one
    (``learning.record_fit``). One assembly for the mean and the sampled rod."""
    params = RodParams.from_dict(man["rod"])
    comps: dict[str, Any] = {NOMINAL_LAWS[k]: NominalLaw(k, params) for k in man.get("nominal_laws", [])}
    center = None
    for m in learned_models(man):
        meta = json.loads((Path(model_dir) / f"{m}.json").read_text())
        cols = meta.get("feature_columns")
        comp = load(m)
        s_mid = segment_arclength(params.N, params.ds) if meta.get("arclength_input") else None
        comps[m] = comp if cols is None else SelectedInputs(comp, cols, s_mid)
        if m in ("q_x", "dH_dtheta"):
            center = meta.get("theta_center")
    covered = man.get("law_inputs_covered") or {}
    for law in ("n1", "n2"):  # learned stretch and shear laws: nominal beyond their record's strains
        m = NOMINAL_LAWS[law]
        if m in comps and m in learned_models(man) and m in covered:
            # a law of its own strain (camera.learn.strain_law_inputs: own) covers that input alone
            box = np.array([covered[m].get(f, [-np.inf, np.inf]) for f in OBJ_N_FEATURES], dtype=float)
            comps[m] = NominalContinuation(comps[m], law, params, box[:, 0], box[:, 1])
    warp = manifest_warp(man.get("record_fit"))
    if warp is not None:
        comps["obj_m"] = BendingWarp(comps["obj_m"], *warp)
    reach = manifest_reach(man)
    if reach is not None and "obj_m" in learned_models(man):
        comps["obj_m"] = TangentContinuation(comps["obj_m"], reach)
    return comps, (center if man["features"] == "paper" else None)


def load_learned(model_dir: str | Path) -> tuple[LearnedRod, dict[str, Any]]:
    """The learned rod of a model directory, on the rod recorded in its manifest."""
    man = read_manifest(model_dir)
    params = RodParams.from_dict(man["rod"])
    if man["features"] == "paper":
        return LearnedRod.from_dir(model_dir, "paper", params), man
    comps, center = learned_components(model_dir, man, lambda m: load_evaluator(Path(model_dir) / m))
    return LearnedRod(comps, man["features"], params, center, learned_damping(man)), man


def learned_damping(man: dict[str, Any]) -> float:
    """The bending damping c [N m^2 s] a directory's manifest records (0: none learned or kept)."""
    fit = man.get("bending_damping")
    return 0.0 if not fit else float(fit["coefficient"])
