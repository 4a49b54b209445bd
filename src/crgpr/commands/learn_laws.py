"""The learned laws of a ``crgpr learn`` directory shown and checked: ``laws.parquet`` and
``laws.png`` (``learning.law_tables``, ``report.laws``), the bending law's reach
(``learning.extrapolation``) and its least tangent stiffness (manifest ``bending_tangent``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from crgpr.io import write_parquet
from crgpr.learning.extrapolation import Reach, continue_table, law_reach
from crgpr.learning.law_tables import bending_tangent, covered_ranges, law_tables
from crgpr.learning.warp import Warp
from crgpr.physics.params import RodParams

LAW_TABLE, LAW_FIGURE = "laws.parquet", "laws.png"


def law_outputs(out: Path, trained: list[str], params: RodParams, settings: dict[str, Any], seed: int,
                warp: Warp | None = None, warp_cov: np.ndarray | None = None,
                extrapolation: dict[str, Any] | None = None, center: float | None = None,
                reach: Reach | None = None, warp_truncation: np.ndarray | None = None,
                choice: dict[str, Any] | None = None) -> dict[str, Any]:
    """The learned laws shown: ``laws.parquet`` (``learning.law_tables``) and ``laws.png``
    (``report.laws``) in the model directory, the bending law times its record-fit ``warp``
    where it has one (``warp_cov``, ``warp_truncation``: its band), continued beyond its reach
    (``learning.extrapolation``,
    ``extrapolation`` = config ``camera.learn.extrapolation``, ``center`` the law's rest curvature;
    ``reach``: the one the record fit used, else found on the table written here; ``choice``: a
    nominal bending law's ``law_choice`` entry, ``nominal_choice``); returns the
    manifest's entries (the covered range of every learned model's inputs, the bending law's
    reach, the file names)."""
    from crgpr.report.laws import law_figure

    cov = {m: covered_ranges(out / m, json.loads((out / f"{m}.json").read_text())["features"])
           for m in trained}
    tab = law_tables(out, trained, params, settings, seed, True, warp, warp_cov, warp_truncation, choice)
    if reach is None and "obj_m" in trained and extrapolation is not None:
        reach = law_reach(tab, float(extrapolation["band"]), float(extrapolation["tangent_span"]), center)
    entries = {"law_inputs_covered": cov, "bending_extrapolation": None if reach is None else reach.to_dict(),
               "bending_tangent": _tangent(out, trained, params, warp, cov, int(settings["n_grid"]))}
    if tab.empty:
        return {**entries, "law_table": None, "law_figure": None}
    tab = continue_table(tab, reach)
    write_parquet(tab, out / LAW_TABLE, {"kind": "learned_laws", "columns": "law, input, x, mean, sd, at_s, "
                                         "nominal, covered, covered_lo, covered_hi, sd_points, sd_scale, "
                                         "sd_floor, continued (SI units)"})
    law_figure(tab, out / LAW_FIGURE, f"learned laws, {out.name}")
    return {**entries, "law_table": LAW_TABLE, "law_figure": LAW_FIGURE}


def bending_reach(out: Path, params: RodParams, cam: dict[str, Any], seed: int, center: float | None
                  ) -> Reach | None:
    """The ``Reach`` of the bending law just written to ``out`` as learned (before any record fit:
    its own band; ``cam``: config ``camera.learn``, its ``law_table`` and ``extrapolation``)."""
    ext = cam["extrapolation"]
    tab = law_tables(out, ["obj_m"], params, cam["law_table"], seed, False)  # the reach: no floor
    return law_reach(tab, float(ext["band"]), float(ext["tangent_span"]), center)


def _tangent(out: Path, trained: list[str], params: RodParams, warp: Warp | None,
             cov: dict[str, dict[str, list[float]]], n_grid: int) -> dict[str, Any] | None:
    """``law_tables.bending_tangent`` over the bending law's covered curvatures (a learned law's
    training range, a warped nominal law's warp range); None for the nominal law unwarped (EI)."""
    if "obj_m" in trained:
        lo, hi = cov["obj_m"]["kappa"]
    elif warp is not None:
        lo, hi = warp[0] - warp[1], warp[0] + warp[1]
    else:
        return None
    return bending_tangent(out, trained, params, lo, hi, n_grid, warp)


__all__ = ["LAW_FIGURE", "LAW_TABLE", "bending_reach", "law_outputs"]
