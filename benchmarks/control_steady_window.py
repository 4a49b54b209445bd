"""Benchmark: how the steady-state window decides the control study's steady tip error
(docs/control.md, "The steady error and its window").

    python benchmarks/control_steady_window.py [--config config.yaml] [--models DIR] [--t-end 8]
        [--out benchmarks/control_steady_window.csv]

The study's regulation (``control.study.target_xy``) by the controller designed on the learned
model (``results/actuated/models/{control.study.model}``) and by the one designed on the nominal
rod with E x ``control.study.nominal_E_factor``, each from the study's two starts (``rest``,
``released``), is run on the ground-truth plant for ``--t-end`` seconds. For every window length W
and window end, the steady tip error is taken twice: the plain mean tip position over the window
and the Hann-weighted mean (``control.metrics.steady_error``), each's distance from the target
over L. Also written per run: the dominant frequency of the tip error after ``--settled`` seconds
and the decay time of its RMS (a log-linear fit over 1 s windows), and the offset the tip spring
leaves for the design's feedforward error (``control.metrics.predicted_offset``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import pandas as pd

from crgpr.commands.control import (
    base_angle,
    base_rod,
    gains,
    gravity,
    hold_settings,
    limits,
    nominal_internal,
    plant_for,
    rest_at,
    solver,
)
from crgpr.commands.learn import load_learned
from crgpr.config import load_config
from crgpr.control.closed_loop import run_closed_loop, simulator_plant
from crgpr.control.design import hold, regulation_policy
from crgpr.control.metrics import predicted_offset
from crgpr.physics.ports import Ports, ports_from_config


def window_error(t: np.ndarray, e: np.ndarray, end: float, width: float, hann: bool) -> float:
    m = (t >= end - width) & (t <= end + 1e-12)
    w = np.hanning(int(m.sum()) + 2)[1:-1] if hann else np.ones(int(m.sum()))
    return float(np.hypot(*(w @ e[m]) / w.sum()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--models", default=None, help="learned model directory (default: the study's)")
    ap.add_argument("--t-end", type=float, default=8.0, help="run length [s]")
    ap.add_argument("--settled", type=float, default=2.0, help="residual analysis from this time on [s]")
    ap.add_argument("--out", default="benchmarks/control_steady_window.csv")
    a = ap.parse_args()
    cfg = load_config(a.config)
    c, s = cfg["control"], cfg["control"]["study"]
    models = a.models or f"results/actuated/models/{s['model']}"
    learned, man = load_learned(models)
    ports = Ports(float(man["ports"]["tendon_offset_m"])) if man.get("ports") else ports_from_config(cfg)
    lo, hi = limits(cfg)
    g, sol = gains(cfg), solver(cfg)
    target = (float(s["target_xy"][0]), float(s["target_xy"][1]), None)
    params, dt = plant_for("ground_truth", cfg)
    L = params.L0
    plant = simulator_plant(params, hold_settings(cfg, dt), ports, base_angle(cfg))
    u_hold = rest_at(params, cfg, target[:2])[1]
    nominal = params.replace(E=params.E * float(s["nominal_E_factor"]))
    designs = {"learned": (learned.internal, learned.gu, learned.params),
               "nominal": (nominal_internal(nominal), gravity(nominal), nominal)}
    starts = {"rest": rest_at(params, cfg, tuple(s["start_xy"]))[0], "released": base_rod(cfg, params)}
    rate = float(c["control_rate_hz"])
    rows = []
    for name, (internal, grav, mp) in designs.items():
        eq = hold(internal, grav, base_rod(cfg, mp), mp.ds, target, sol, lo, hi)
        policy = regulation_policy(eq, target, g, lo, hi)
        for start, q0 in starts.items():
            run = run_closed_loop(policy, plant, q0, np.zeros_like(q0), rate, a.t_end, 10**9)
            t, e = run.t, run.pose[:, :2] - np.array(target[:2])
            late = t >= a.settled
            r = e[late] - e[late].mean(axis=0)
            spec = np.abs(np.fft.rfft(r, axis=0)).sum(axis=1)
            freq = np.fft.rfftfreq(int(late.sum()), 1.0 / rate)
            ends = np.arange(a.settled + 1.0, a.t_end + 1e-9, 1.0)
            rms = []
            for x in ends:
                ew = e[(t > x - 1) & (t <= x)]
                rms.append(np.sqrt(np.mean(np.sum((ew - ew.mean(axis=0)) ** 2, axis=1))))
            decay = -1.0 / np.polyfit(ends - 0.5, np.log(rms), 1)[0]
            base = {"controller": name, "start": start,
                    "predicted_offset_over_L": predicted_offset(eq.u, u_hold, g.kp_force) / L,
                    "residual_frequency_hz": float(freq[1:][np.argmax(spec[1:])]), "residual_decay_s": decay}
            for width in (0.5, 1.0, 1.5):
                for end in np.arange(3.0, a.t_end + 1e-9, 0.5):
                    for hann in (False, True):
                        err = window_error(t, e, end, width, hann) / L
                        rows.append({**base, "estimator": "hann" if hann else "plain", "window_s": width,
                                     "end_s": end, "steady_error_over_L": err})
            print(name, start, base, flush=True)
    df = pd.DataFrame(rows)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    df.to_csv(a.out, index=False, float_format="%.6g")
    piv = df[df.window_s.isin([0.5, 1.5])].pivot_table(
        index=["estimator", "window_s", "end_s"], columns=["controller", "start"],
        values="steady_error_over_L")
    print((100 * piv).round(4).to_string())


if __name__ == "__main__":
    main()
