"""Figures, report and summary of the missing-physics workflow (``crgpr discover``).

Per run: ``heatmap.png`` (theta error over s and t), ``before_after.png``, ``residual.png``
(the cut-moment residual, ``crgpr.discovery.residual``) and ``report.md``; over the hidden-
effect cases: the table ``discovery.csv`` and the figure ``discovery_gap.png``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.discovery.residual import Residual
from crgpr.io import atomic_path, write_csv


def figures(out: Path, arrays: dict[str, Any], result: dict[str, Any]) -> list[str]:
    """Write the per-run figures into ``out``; returns their file names."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kin, q_nom, q_aug, params = arrays["kin"], arrays["q_nom"], arrays["q_aug"], arrays["params"]
    t = kin.t - kin.t[0]
    s = params.s
    e0 = q_nom[..., 2] - kin.q[..., 2]
    e1 = q_aug[..., 2] - kin.q[..., 2]
    vmax = float(np.max(np.abs(e0))) or 1.0
    fig, axs = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True, constrained_layout=True)
    for ax, e, title in ((axs[0], e0, f"nominal model (RMSE {result['gap_before']:.3g} rad)"),
                         (axs[1], e1, f"augmented model (RMSE {result['gap_after']:.3g} rad)")):
        im = ax.pcolormesh(t, s, e.T, cmap="RdBu_r", vmin=-vmax, vmax=vmax, shading="auto")
        ax.set_xlabel("t [s]")
        ax.set_title(title, fontsize=10)
    axs[0].set_ylabel("s [m]")
    fig.colorbar(im, ax=axs, label="theta model - measured [rad]")
    fig.suptitle(f"Where the model and the measurement disagree (verdict: {result['verdict']})")
    files = []
    with atomic_path(out / "heatmap.png", ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    files.append("heatmap.png")
    plt.close(fig)

    fig, axs = plt.subplots(1, 3, figsize=(13, 3.6), constrained_layout=True)
    for ax, i in ((axs[0], params.N // 2), (axs[1], params.N)):
        ax.plot(t, kin.q[:, i, 2], "k", lw=2, label="measured (GP-smoothed)")
        ax.plot(t, q_nom[:, i, 2], "C3--", label="nominal model")
        if result["effects"]:
            ax.plot(t, q_aug[:, i, 2], "C0", label="augmented model")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(f"theta at node {i} (s = {i * params.ds:.2f} m) [rad]")
    axs[0].legend(fontsize=8)
    M = arrays["M"]  # the comparison at the markers
    s_m = M @ s
    axs[2].plot(s_m, np.sqrt(np.mean((e0 @ M.T) ** 2, axis=0)), "C3o-", label="nominal")
    axs[2].plot(s_m, np.sqrt(np.mean((e1 @ M.T) ** 2, axis=0)), "C0s-", label="augmented")
    axs[2].set_xlabel("s [m]")
    axs[2].set_ylabel("RMSE theta [rad]")
    axs[2].legend(fontsize=8)
    with atomic_path(out / "before_after.png", ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    files.append("before_after.png")
    plt.close(fig)

    res: Residual = arrays["residual"]
    rm = float(np.percentile(np.abs(res.rho), 99)) or 1.0
    fig, ax = plt.subplots(figsize=(6, 3.6), constrained_layout=True)
    im = ax.pcolormesh(t, (np.arange(params.N) + 0.5) * params.ds, res.rho.T, cmap="RdBu_r",
                       vmin=-rm, vmax=rm, shading="auto")
    fig.colorbar(im, ax=ax, label="mb_const - mb_dyn [N m]")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("s [m]")
    ax.set_title("port-Hamiltonian (cut-moment) residual of the nominal model", fontsize=10)
    with atomic_path(out / "residual.png", ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    files.append("residual.png")
    plt.close(fig)
    d = result.get("described")
    if d:
        c = d["curve"]
        fig, ax = plt.subplots(figsize=(6, 3.6), constrained_layout=True)
        ax.fill_between(c["s_m"], c["lower"], c["upper"], color="C0", alpha=0.25,
                        label=f"band ({d['band_z']:g} posterior std of log f)")
        ax.plot(c["s_m"], c["factor"], "C0", label="learned EI(s) / nominal")
        ax.plot(d["knots_s_m"], d["factor_at_knots"], "C0o", ms=4)
        ax.axhline(1.0, color="k", ls="--", lw=1, label="nominal")
        ax.set_xlabel("s [m]")
        ax.set_ylabel("bending stiffness factor f(s) [-]")
        ax.set_title(f"learned bending stiffness ({'accepted' if d['accepted'] else 'not accepted'})",
                     fontsize=10)
        ax.legend(fontsize=8)
        with atomic_path(out / "learned_law.png", ".png") as tmp:
            fig.savefig(tmp, format="png", dpi=110)
        files.append("learned_law.png")
        plt.close(fig)
    return files


def report_markdown(result: dict[str, Any], files: list[str]) -> str:
    """The per-run report (Markdown)."""
    w = result["where"]
    lines = [
        "# Missing-physics discovery", "",
        f"Measured data: `{result['measured']}` ({result['n_samples']} samples at "
        f"{result['sample_rate_hz']:.0f} Hz from t = {result['input']['t0_s']:.3g} s, "
        f"{result['input']['n_markers']} markers (base marker: {result['input']['base_marker']}); "
        f"model grid N = {result['model_N']}; GP noise estimate "
        f"{1e3 * result['gp_noise_std_m']:.2f} mm).", "",
        *[f"- input: {n}" for n in result["input"]["notes"]], "",
        f"Gap floor (nothing missing) {result['gap_floor']:.4f} rad: camera noise and initial state "
        f"{result['gap_floor_noise']:.4f}, model discretisation {result['gap_floor_discretisation']:.4f}, "
        f"model form (the clamp's) {result.get('gap_floor_model_form', 0.0):.4f}; "
        f"excess of the nominal gap over it {result['gap_excess_over_floor']:.4f} rad.", "",
        f"**Verdict: `{result['verdict']}`**", "",
        "| | nominal | augmented |", "|---|---|---|",
        f"| RMSE theta [rad] | {result['gap_before']:.4f} | {result['gap_after']:.4f} |",
        f"| tip RMSE / L | {result['tip_gap_before']:.4f} | {result['tip_gap_after']:.4f} |", "",
        f"Fraction of the gap explained: {result['explained_fraction']:.1%}", "",
        "## Effects (ranked)", "",
    ]
    if result["effects"]:
        lines += ["| rank | effect | coefficient | std | unit | residual-regression estimate | place |",
                  "|---|---|---|---|---|---|---|"]
        for i, e in enumerate(result["effects"], 1):
            rc = "-" if e["regression_coefficient"] is None else \
                f"{e['regression_coefficient']:.4g} +- {e['regression_std']:.2g}"
            lines.append(f"| {i} | {e['name']} | {e['coefficient']:.4g} | {e['coefficient_std']:.2g} | "
                         f"{e['unit']} | {rc} | {e['place']} |")
        for a in result.get("indistinguishable_alternatives", []):
            lines.append(f"\nNot told apart by these data: {a['alternative']} instead of {a['named']} "
                         f"(RMSE {a['rmse']:.4f} rad, trajectory delta BIC {a['trajectory_delta_bic']:.1f}).")
    for h in result.get("not_needed", []):
        lines.append(f"\nNot needed: {h['effect']} (the model without it, RMSE {h['rmse_without']:.4f} rad, "
                     f"still closes the gap and reaches its own floor {h['floor_without']:.4f} rad).")
    for h in result.get("rejected_out_of_sample", []):
        lines.append(f"\nRejected out of sample: {h['effect']} (entered {h['model']} in-sample; held-out "
                     f"evidence {h['held_out_evidence']:.1f} < holdout_min_evidence).")
    if not result["effects"]:
        lines.append("None added.")
        if result["best_attempt"]:
            b = result["best_attempt"]
            names = ", ".join(f"{e['name']} = {e['coefficient']:.3g}" for e in b["effects"])
            lines.append(f"Best candidate set ({names}) closes {b['explained_fraction']:.1%} of the "
                         f"gap (RMSE {b['gap_after']:.4f} rad) and leaves {b['remaining_excess']:.4f} rad "
                         f"over the floor: not accepted (it does not describe the disagreement).")
        if result["significant_but_below_tolerance"]:
            lines.append(f"Significant in the residual but the gap is below tolerance: "
                         f"{result['significant_but_below_tolerance']}.")
    d = result.get("described")
    if d:
        lines += ["", "## Learned law (no named effect closes the gap)", ""]
        if d["summary"]:
            lines.append(f"{'Described' if d['accepted'] else 'Not accepted'}: {d['summary']}.")
        c = d.get("closest_library_model")
        if c:
            lines.append(f"Closest library model: {', '.join(c['effects'])} (RMSE {c['rmse']:.4f} rad; the "
                         f"learned law's BIC is lower by {c['delta_bic']:.1f}).")
        if d.get("clamp_form"):
            lines.append("The change is confined to the clamp's neighbourhood (discovery.clamp_form_m): "
                         "the clamp's form, not a missing effect; verdict none.")
        else:
            lines.append("The learned bending-stiffness factor's band contains the nominal law everywhere.")
        lines.append(f"Learned EI(s) f(s) through {len(d['knots_s_m'])} knots: closes "
                     f"{d['explained_excess_fraction']:.1%} of the excess over the floor, leaves "
                     f"{d['remaining_excess']:.4f} rad, trajectory delta BIC "
                     f"{d['trajectory_delta_bic']:.1f}.")
    lines += ["", "## Where", "",
              f"- markers with at least half the largest theta error: s = {w['s_m'][0]:.3f} to "
              f"{w['s_m'][1]:.3f} m, worst at s = {w['worst_marker_s_m']:.3f} m",
              f"- residual moment of the nominal model at least half its peak: s = "
              f"{w['residual_moment_s_m'][0]:.3f} to {w['residual_moment_s_m'][1]:.3f} m, peak at "
              f"s = {w['residual_moment_peak_s_m']:.3f} m",
              f"- worst time window: {w['time_window_s'][0]:.2f} to {w['time_window_s'][1]:.2f} s; "
              f"error above tolerance from t = {w['onset_s']} s",
              f"- state group with the largest normalised error: {w['state_group']}",
              f"- missing terms do net work {w['net_work_missing_J']:.3g} J "
              f"(|P| integral {w['abs_work_missing_J']:.3g} J): **{w['character']}**", "",
              "## Selection (forward stepwise)", ""]
    for st in result["selection"]["steps"]:
        gains = ", ".join(f"{k} {g:.1f}" for k, g in st["residual_bic_gain"].items())
        lines.append(f"- model {st['model'] or '(nominal)'}: residual BIC gain per candidate: {gains}")
        if "trajectory_score" in st:
            ranked = sorted(st["trajectory_score"].items(), key=lambda kv: -kv[1])
            sc = ", ".join(f"{k} {v:.3g}" for k, v in ranked)
            lines.append(f"  - linearised trajectory evidence (RSS decrease, rad^2): {sc}")
        for c in st["confirmation"]:
            lines.append(f"  - trajectory fit with {c['effect']}: RMSE {c['rmse']:.4f} rad, BIC gain "
                         f"{c['trajectory_delta_bic']:.1f}, {'accepted' if c['accepted'] else 'rejected'}")
    for h in result["selection"].get("holdout", []):
        lines.append(f"- held-out time blocks, {h['effect']} in {h['model']}: RMSE "
                     f"{h['held_out_rmse_with']:.4f} with, {h['held_out_rmse_without']:.4f} rad without, "
                     f"evidence {h['held_out_evidence']:.1f}, {'dropped' if h['dropped'] else 'stays'}")
    lines += ["", "## Figures", ""] + [f"![{f}]({f})" for f in files]
    lines += ["", f"Run time {result['timing_s']['total']:.1f} s "
              f"(GP smoothing {result['timing_s']['gp_smoothing']:.1f} s)."]
    return "\n".join(lines) + "\n"


def summary(cases: list[str], truths: list[str], results: list[str], min_gap_rad: float,
            out_csv: str | Path, out_fig: str | Path) -> pd.DataFrame:
    """Hidden vs named effect table (``out_csv``) and the gap figure (``out_fig``)."""
    rows = []
    for case, tp, rp in zip(cases, truths, results, strict=True):
        truth = json.loads(Path(tp).read_text())
        res = json.loads(Path(rp).read_text())
        dist = truth.get("disturbance") or {}
        hidden = list(truth["effects"]) or list(dist)
        named = [e["name"] for e in res["effects"]]
        # a stiffness defect is out of the library but within the learned EI(s) law: described
        expected = ("effect_found" if truth["effects"] else "described" if "stiffness_defect" in dist
                    else "unexplained" if dist else "none")
        region = (res.get("described") or {}).get("region") if res["verdict"] == "described" else None
        place_ok = True
        if expected == "described":  # the right place and direction of the change
            defect = dist["stiffness_defect"]
            place_ok = bool(region and region["s_from_m"] <= float(defect["s_m"]) <= region["s_to_m"]
                            and (region["direction"] == "softer") == (float(defect["depth"]) > 0))
        inp = res["input"]
        coef = {e["name"]: e for e in res["effects"]}
        alts = res.get("indistinguishable_alternatives", [])
        # a wrong name whose true replacement the data cannot tell apart from it (|delta BIC| <
        # bic_min_improvement in the named model) is reported as such, not counted correct
        swapped = {a["named"]: a["alternative"] for a in alts}
        named_or_alt = {swapped[k] if k in swapped and swapped[k] in truth["effects"] else k for k in named}
        rows.append({
            "case": case, "hidden": ";".join(hidden) or "none", "named": ";".join(named) or "none",
            "verdict": res["verdict"], "expected_verdict": expected,
            # every hidden effect named and nothing else
            "correct": bool(res["verdict"] == expected and set(named) == set(truth["effects"]) and place_ok),
            "indistinguishable": ";".join(f"{a['named']}~{a['alternative']}" for a in alts) or None,
            "correct_up_to_indistinguishable": bool(res["verdict"] == expected and place_ok
                                                    and named_or_alt == set(truth["effects"])),
            "described": (f"EI x{region['factor']:.2g} ({region['band'][0]:.2g}-{region['band'][1]:.2g}) "
                          f"s = {region['s_from_m']:.2f}-{region['s_to_m']:.2f} m" if region else None),
            "coefficient_true": ";".join(f"{v:.4g}" for v in truth["effects"].values()) or None,
            "coefficient_est": ";".join(f"{coef[k]['coefficient']:.4g}" for k in named) or None,
            "coefficient_std": ";".join(f"{coef[k]['coefficient_std']:.2g}" for k in named) or None,
            "effect_size_rad": truth["effect_size_rmse_theta_rad"],
            "markers": inp["n_markers"], "t0_s": inp["t0_s"],
            "missing_max": max(inp["missing_fraction"]), "outliers_excluded": inp["outliers_total"],
            "gap_before_rad": res["gap_before"], "gap_floor_rad": res["gap_floor"],
            "gap_after_rad": res["gap_after"],
            "tip_gap_before": res["tip_gap_before"], "tip_gap_after": res["tip_gap_after"],
            "explained_fraction": res["explained_fraction"],
            "explained_excess_fraction": res.get("explained_excess_fraction"),
            "residual_peak_s_m": res["where"]["residual_moment_peak_s_m"],
            "local_stiffness_peak_s_m": res["where"].get("local_stiffness_peak_s_m"),
            "local_stiffness_peak_error": (res["where"].get("local_stiffness_error") or {}).get(
                "peak_relative_error"),
            "worst_window_s": "-".join(f"{v:.2g}" for v in res["where"]["time_window_s"]),
            "runtime_s": res["timing_s"]["total"],
        })
    df = pd.DataFrame(rows)
    write_csv(df, out_csv)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(max(6, 0.9 * len(df)), 4), constrained_layout=True)
    x = np.arange(len(df))
    ax.bar(x - 0.2, df["gap_before_rad"], 0.4, color="C3", label="nominal model")
    ax.bar(x + 0.2, df["gap_after_rad"], 0.4, color="C0", label="after discovery")
    for i, r in df.iterrows():
        ax.text(i, max(r["gap_before_rad"], r["gap_after_rad"]) * 1.15, r["verdict"], ha="center",
                fontsize=7, va="bottom")
    ax.set_yscale("log")
    lo = float(np.nanmin(np.r_[df["gap_after_rad"], df["gap_before_rad"]]))
    ax.set_ylim(0.5 * lo, 8.0 * float(np.nanmax(df["gap_before_rad"])))
    ax.set_xticks(x, df["case"], rotation=30, ha="right")
    ax.set_ylabel("RMSE theta [rad]")
    ax.axhline(min_gap_rad, color="k", ls=":", lw=1, label="min_gap_rad")
    ax.set_title("Missing-physics discovery: the gap before and after adding the named effect")
    ax.legend(fontsize=8, loc="upper right", ncol=3)
    with atomic_path(out_fig, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return df
