"""Rule functions and the ``crgpr discover`` / ``crgpr discover-data`` commands (missing physics).

Rules (``workflow/rules/discovery.smk``; rule = script = function): ``discovery_data``
(camera-like record of one hidden-effect case + its truth, kept apart), ``discovery_run`` (the
workflow on one measured file, never reading the truth), ``discovery_summary`` (table and
figure over the cases). Every value comes from the rule's ``params`` (config.yaml). The
commands take their configuration as ``crgpr simulate`` takes the rod (``crgpr.config.cli_config``:
the paper's rod by default, ``--config``, ``--set``); ``discovery.json`` records the values used.
"""

from __future__ import annotations

import argparse
import logging
import sys
import zlib
from pathlib import Path
from typing import Any

from crgpr.config import add_config_options, cli_config, rod_params
from crgpr.discovery.selection import discover
from crgpr.discovery.settings import DiscoverySettings
from crgpr.discovery.synthetic import find_case, make_measured
from crgpr.io import atomic_dir, write_json, write_parquet, write_text
from crgpr.measured.records import ScreenSettings, load_measured
from crgpr.physics.params import RodParams
from crgpr.report.discovery import figures, report_markdown, summary

log = logging.getLogger(__name__)


def case_seed(seed: int, case: str) -> int:
    """Seed of one case's camera noise: the workflow seed and the case name."""
    return (int(seed) * 1000003 + zlib.crc32(case.encode())) % (2**32)


def discovery_seed(seed: int) -> int:
    """Seed of the discovery run (GP hyperparameter subsets, bootstrap)."""
    return int(seed) + 6


def run_discovery(measured: str | Path, out_dir: str | Path, rod: RodParams, dt_s: float,
                  d: dict[str, Any], seed: int, provenance: dict[str, Any] | None = None) -> dict[str, Any]:
    """Load (``.parquet`` or ``.csv``), discover and write OUT/discovery.json, OUT/report.md and
    the figures.

    ``d`` is the ``discovery`` config section; ``discovery.json``'s ``config`` holds the values
    used (rod, time step, seed, the section's keys read) and ``provenance`` (``cli_config``).
    The output directory is written atomically (a temporary directory renamed into place)
    under a lock: a concurrent run into the same directory fails at once instead of both
    reporting success.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a directory")
    meas = load_measured(measured, rod.L0, rod.ds, ScreenSettings.from_config(d))
    for note in meas.notes:
        log.warning("%s: %s", measured, note)
    st = DiscoverySettings.from_config(d, discovery_seed(seed))
    with atomic_dir(out) as tmp:
        res = discover(meas, rod, dt_s, st)
        result = res["result"]
        result["config"] = {**(provenance or {}), "seed": seed, "rod": rod.to_dict(),
                            "simulation": {"dt_s": dt_s},
                            "discovery": {k: d[k] for k in (*ScreenSettings.config_keys(),
                                                            *DiscoverySettings.config_keys())}}
        files = figures(tmp, res["arrays"], result)
        write_text(report_markdown(result, files), tmp / "report.md")
        write_json(result, tmp / "discovery.json")
    return result


# ------------------------------------------------------------------------------------------------
# Snakemake rule functions
# ------------------------------------------------------------------------------------------------
def discovery_data(rod: dict[str, Any], discovery: dict[str, Any], seed: int, case: str, out: str,
                   truth_out: str) -> None:
    """Rule ``discovery_data``: measured Parquet (markers only) + truth JSON (elsewhere)."""
    c = find_case(discovery["cases"], case)
    frame, truth = make_measured(RodParams.from_dict(dict(rod)), discovery, c, case_seed(seed, case))
    write_json(truth, truth_out)
    cols = "t [s], " + ("s [m]" if "s" in frame.columns else "node") + ", x [m], y [m]"
    write_parquet(frame, out, {"kind": "measured", "columns": cols})


def discovery_run(rod: dict[str, Any], dt_s: float, discovery: dict[str, Any], seed: int, measured: str,
                  out_dir: str) -> None:
    """Rule ``discovery_run``: the workflow on one measured file (never reads the truth)."""
    run_discovery(measured, out_dir, RodParams.from_dict(dict(rod)), float(dt_s), discovery, seed)


def discovery_summary(cases: list[str], truths: list[str], results: list[str], min_gap_rad: float,
                      out_csv: str, out_fig: str) -> None:
    """Rule ``discovery_summary``: hidden vs named effects (table) and the gap figure."""
    summary(cases, truths, results, float(min_gap_rad), out_csv, out_fig)


# ------------------------------------------------------------------------------------------------
# CLI
# ------------------------------------------------------------------------------------------------
def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("discover", help="find, name and add missing physics from measured positions",
                       description="Compare camera markers on the rod with the nominal model of "
                                   "config.yaml, locate the disagreement, name the missing effect "
                                   "among the candidate library, add it and report the gap.")
    p.add_argument("--measured", required=True,
                   help="Parquet or CSV file, by extension: t [s], s [m] or node, x, y [m] (rows in any "
                        "order; NaN or an empty cell = missing)")
    p.add_argument("--out", required=True, help="output directory (discovery.json, report.md, figures)")
    add_config_options(p, "the nominal model and the discovery settings")
    p.set_defaults(func=_cli)
    g = sub.add_parser("discover-data", help="camera-like data of a hidden-effect case (for tests/demos)")
    g.add_argument("--case", required=True, help="name of a case in discovery.cases of the config")
    g.add_argument("--out", required=True, help="measured Parquet file to write")
    g.add_argument("--truth-out", required=True, help="truth JSON to write (keep it away from discover)")
    add_config_options(g, "the case and the rod")
    g.set_defaults(func=_cli_data)


def _cli(args: argparse.Namespace) -> None:
    cfg, provenance = cli_config(args.config, args.set)
    res = run_discovery(args.measured, args.out, rod_params(cfg), float(cfg["simulation"]["dt_s"]),
                        cfg["discovery"], int(cfg["seed"]), provenance)
    for note in res["input"]["notes"]:
        print(f"crgpr discover: warning: {args.measured}: {note}", file=sys.stderr)
    print(f"verdict: {res['verdict']}; effects: {[e['name'] for e in res['effects']]}; gap "
          f"{res['gap_before']:.4f} -> {res['gap_after']:.4f} rad; written to {args.out}")


def _cli_data(args: argparse.Namespace) -> None:
    cfg, _ = cli_config(args.config, args.set)
    try:
        find_case(cfg["discovery"]["cases"], args.case)
    except KeyError as exc:
        raise ValueError(f"--case: {exc.args[0]}") from None
    discovery_data(cfg["rod"], cfg["discovery"], int(cfg["seed"]), args.case, args.out, args.truth_out)
