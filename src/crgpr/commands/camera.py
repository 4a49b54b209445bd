"""Rule functions of the camera workflow (workflow/rules/camera.smk).

* ``camera_data``: the camera version of a ground-truth trajectory: positions only, every
  node, the camera's frame rate, Gaussian noise on x and y (seeded);
* ``camera_learn``: ``crgpr learn`` on it (one model directory per noise/prefilter/features);
* ``camera_rollout``: method ``cr_gpr_objective_camera`` at every test angle (for accuracy.parquet);
* ``camera_ablation_cell``: one cell of the noise ablation rolled out on the ablation angles;
* ``camera_ablation``: ``noise_ablation.csv`` and its figure.
"""

from __future__ import annotations

import json
import math
import time
import zlib
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.commands.learn import learn, load_learned
from crgpr.commands.rollout import rollout_models, rollout_settings, try_rollout
from crgpr.config import CAMERA_METHOD
from crgpr.io import atomic_path, read_parquet, write_csv, write_json, write_parquet
from crgpr.physics.simulate import TRAJECTORY_COLUMNS, trajectory_frame
from crgpr.report.metrics import accuracy


def camera_frame(t: np.ndarray, q: np.ndarray, noise_std_m: float, rng: np.random.Generator) -> pd.DataFrame:
    """Camera-like record of a trajectory: positions of every node only (``node`` column, so
    s = node * ds on the loader's grid), Gaussian position noise of ``noise_std_m`` [m] on x, y."""
    n_t, n_nodes, _ = q.shape
    noisy = q[..., :2] + noise_std_m * rng.standard_normal((n_t, n_nodes, 2))
    return pd.DataFrame({"t": np.repeat(t, n_nodes), "node": np.tile(np.arange(n_nodes, dtype=np.int32), n_t),
                         "x": noisy[..., 0].ravel(), "y": noisy[..., 1].ravel()})


def noise_seed(seed: int, noise_mm: float) -> int:
    """Seed of the camera noise of one noise level (recorded in the data's metadata)."""
    return (int(seed) * 1000003 + zlib.crc32(f"camera:{noise_mm:g}".encode())) % (2**32)


def camera_data(gt: str, out: str, noise_mm: float, sample_rate_hz: float, seed: int) -> None:
    """Positions-only camera record of a ground-truth file (see module docstring)."""
    df = read_parquet(gt, required=TRAJECTORY_COLUMNS).sort_values(["t", "node"])
    t = np.unique(df["t"].to_numpy())
    n_nodes = int(df["node"].max()) + 1
    q = df[["x", "y"]].to_numpy().reshape(t.size, n_nodes, 2)
    every = (1.0 / sample_rate_hz) / float(np.median(np.diff(t)))
    k = int(round(every))
    if k < 1 or abs(every - k) > 1e-6 * every:
        raise ValueError(f"{gt}: record interval {np.median(np.diff(t)):g} s does not divide the camera "
                         f"frame interval 1/{sample_rate_hz:g} s (camera.data.sample_rate_hz)")
    s = noise_seed(seed, noise_mm)
    frame = camera_frame(t[::k], q[::k], noise_mm * 1e-3, np.random.default_rng(s))
    write_parquet(frame, out, {"kind": "measured", "columns": "t [s], node, x [m], y [m]", "source": gt,
                               "noise_std_m": noise_mm * 1e-3, "sample_rate_hz": sample_rate_hz, "seed": s})


def camera_learn(cfg: dict[str, Any], measured: str, out_dir: str, features: str, prefilter: str) -> None:
    learn(measured, out_dir, cfg, features, prefilter)


def camera_rollout(cfg: dict[str, Any], model_dir: str, angles: list[int], outs: list[str],
                   energy_outs: list[str]) -> None:
    """Rule ``camera_rollout``: ``rollout_models`` of the camera model at each test angle, one
    trajectory and energy file per angle (in the order of ``angles``)."""
    for angle, out, energy_out in zip(angles, outs, energy_outs, strict=True):
        rollout_models(cfg, model_dir, float(angle), out, energy_out, label=CAMERA_METHOD)


def camera_ablation_cell(cfg: dict[str, Any], model_dir: str, gts: list[str], angles: list[int],
                         t_end: float, out: str) -> None:
    """Roll one ablation cell out at every angle over [0, t_end]; divergences are recorded."""
    model, man = load_learned(model_dir)
    st = rollout_settings(cfg, model.params, t_end)
    rows = []
    for angle, gt in zip(angles, gts, strict=True):
        t0 = time.perf_counter()
        traj, status = try_rollout(model, float(angle), st)
        g = read_parquet(gt, required=TRAJECTORY_COLUMNS)
        g = g[g["t"] <= st.n_steps * st.dt + 1e-9]
        row: dict[str, Any] = {"theta0_deg": angle, **status, "seconds": time.perf_counter() - t0}
        if traj is None:
            row.update(rmse_theta=math.nan, tip_rmse_over_L=math.nan)
        else:
            acc = accuracy(g, trajectory_frame(traj), model.params.L0, gt, f"{model_dir} rollout")
            row.update(rmse_theta=acc["rmse_theta"], tip_rmse_over_L=acc["tip_rmse_over_L"])
        rows.append(row)
    write_json({"model_dir": model_dir, "features": man["features"], "prefilter": man["prefilter"],
                "noise_std_m_estimated": man["state"].get("noise_std_m_estimated"),
                "nominal_laws": man.get("nominal_laws", []),
                "learn_seconds": man["seconds"], "t_end_s": st.t_end, "rows": rows}, out)


def camera_ablation(cells: list[str], noise_mm: list[float], prefilters: list[str], features: list[str],
                    out_csv: str, out_fig: str) -> pd.DataFrame:
    """Collect the cells into noise_ablation.csv (one row per cell) and draw the figure."""
    keys = [(n, p, f) for n in noise_mm for p in prefilters for f in features]
    if len(keys) != len(cells):
        raise ValueError(f"{len(cells)} cell files for {len(keys)} ablation cells")
    rows = []
    for (n, p, f), path in zip(keys, cells, strict=True):
        cell = json.loads(Path(path).read_text())
        r = pd.DataFrame(cell["rows"])
        row: dict[str, Any] = {"noise_mm": n, "prefilter": p, "features": f,
                               "rmse_theta_mean": float(r["rmse_theta"].mean()) if not r["diverged"].any()
                               else math.nan,
                               "rmse_theta_mean_finite": float(r["rmse_theta"].mean()),
                               "tip_rmse_over_L_mean": float(r["tip_rmse_over_L"].mean()),
                               "divergences": int(r["diverged"].sum()), "n_angles": len(r),
                               "t_end_s": cell["t_end_s"],
                               "noise_mm_estimated": math.nan if cell["noise_std_m_estimated"] is None
                               else cell["noise_std_m_estimated"] * 1e3,
                               "nominal_laws": "+".join(cell.get("nominal_laws", [])) or "none",
                               "learn_seconds": cell["learn_seconds"]}
        for _, a in r.iterrows():
            row[f"rmse_theta_{int(a['theta0_deg'])}"] = a["rmse_theta"]
        rows.append(row)
    df = pd.DataFrame(rows)
    write_csv(df, out_csv)
    _ablation_figure(df, out_fig)
    return df


def _ablation_figure(df: pd.DataFrame, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    feats = list(dict.fromkeys(df["features"]))
    fig, axes = plt.subplots(1, len(feats), figsize=(5 * len(feats), 3.8), constrained_layout=True,
                             squeeze=False)
    for ax, f in zip(axes[0], feats, strict=True):
        for p, c in (("gp", "C0"), ("fd", "C3")):
            d = df[(df["features"] == f) & (df["prefilter"] == p)].sort_values("noise_mm")
            if d.empty:
                continue
            y = d["rmse_theta_mean_finite"].to_numpy()
            ax.plot(d["noise_mm"], y, "o-", color=c, label=f"{p} prefilter")
            nominal = d["nominal_laws"] if "nominal_laws" in d else ["none"] * len(d)
            for x, yy, k, nom in zip(d["noise_mm"], y, d["divergences"], nominal, strict=True):
                note = ([f"{k} div."] if k else []) + ([f"{nom} nominal"] if nom != "none" else [])
                if note:
                    ax.annotate(", ".join(note), (x, yy), textcoords="offset points", xytext=(4, 4),
                                fontsize=7, color=c)
        ax.set_yscale("log")
        ax.set_xlabel("camera position noise [mm]")
        ax.set_ylabel("mean RMSE(theta) [rad]")
        t_end = float(df[df["features"] == f]["t_end_s"].iloc[0])
        ax.set_title(f"features '{f}' ({t_end:g} s rollouts)")
        ax.legend(fontsize=8)
    fig.suptitle("Noise ablation: learned from camera positions only", fontsize=10)
    with atomic_path(out, ".png") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
