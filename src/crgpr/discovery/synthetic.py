"""Camera-like records of hidden-effect cases (test and demonstration data, beyond the paper).

The data simulator differs from the nominal model: ``truth_refine`` times more segments and
its own time step (``truth_dt_s``). Hidden effects are RodParams fields; disturbances outside
the library are a horizontal periodic tip force and a localized stiffness defect (EI reduced
over a stretch of the rod). The camera: markers at every model node (``node`` column) or at
given arc lengths (``s`` column), a frame rate, Gaussian position noise, a record that may
start mid-motion (``t_start_s``), dropped frames, occlusions (NaN), gross outliers (a marker
at the origin, two neighbouring markers swapped) and rows in random order.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pandas as pd

from crgpr.discovery.effects import effect_params
from crgpr.measured.kinematics import marker_positions
from crgpr.physics.integrator import run_generic, run_rod
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.rod import free_mask, internal_forces, masses, segment_EI, straight_rod
from crgpr.physics.simulate import dissipation_coefficients, kelvin_voigt_kick, rod_kernel_args, simulate


def aligned_settings(params: RodParams, dt_max: float, period: float, n_samples: int,
                     safety: float = 0.8) -> SimSettings:
    """Time step <= dt_max (and stable) that divides the sampling period exactly."""
    dt = min(dt_max, safety * params.dt_stable())
    every = max(1, math.ceil(period / dt - 1e-9))
    dt = period / every
    return SimSettings(dt=dt, t_end=(n_samples - 1) * period, record_every=every, scheme="variational")


class _PeriodicTipForce:
    """Nodal forces of the rod plus gravity plus a horizontal tip force F0 sin(2 pi f t).

    The time is tracked by counting calls (``run_generic`` evaluates the force once at t = 0
    and once per step after the drift).
    """

    def __init__(self, params: RodParams, theta_base: float, amplitude: float, freq: float, dt: float):
        self.params, self.theta_base = params, theta_base
        self.amp, self.omega, self.dt = amplitude, 2.0 * math.pi * freq, dt
        self.m_t = masses(params)[0]
        self.calls = 0

    def __call__(self, q: np.ndarray) -> np.ndarray:
        F, _ = internal_forces(q, self.params, self.theta_base)
        F[:, 1] -= self.m_t * self.params.g
        F[-1, 0] += self.amp * math.sin(self.omega * self.calls * self.dt)
        self.calls += 1
        return F


def defect_EI(params: RodParams, s_m: float, width_m: float, depth: float) -> np.ndarray:
    """Segment EI with a localized defect: EI (1 - depth) where |s_mid - s_m| < width / 2."""
    s_mid = (np.arange(params.N) + 0.5) * params.ds
    EI = segment_EI(params).copy()
    EI[np.abs(s_mid - s_m) < 0.5 * width_m] *= 1.0 - depth
    return EI


def simulate_truth(params: RodParams, theta0_deg: float, settings: SimSettings,
                   disturbance: dict[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Data-generating simulation (t, q) released straight at rest, with an optional disturbance."""
    if not disturbance:
        tr = simulate(theta0_deg, params, settings)
        return tr.t, tr.q
    q0 = straight_rod(math.radians(theta0_deg), params)
    m_t, m_r = masses(params)
    lam_t, lam_r, k_quad = dissipation_coefficients(params)
    free = free_mask(params)
    kv = kelvin_voigt_kick(params, m_r, lam_r, settings.dt)
    if "stiffness_defect" in disturbance:
        d = disturbance["stiffness_defect"]
        args = list(rod_kernel_args(params, float(q0[0, 2])))
        args[3] = defect_EI(params, float(d["s_m"]), float(d["width_m"]), float(d["depth"]))
        out = run_rod(q0, np.zeros_like(q0), free, m_t, m_r, lam_t, lam_r, k_quad, -m_t * params.g,
                      tuple(args), settings.dt, settings.n_steps, settings.record_every, kv=kv)
        return out.t, out.q
    f = disturbance["periodic_tip_force"]
    force = _PeriodicTipForce(params, float(q0[0, 2]), float(f["tip_force_N"]), float(f["frequency_hz"]),
                              settings.dt)
    out = run_generic(q0, np.zeros_like(q0), force, free, m_t, m_r, lam_t, lam_r, settings.dt,
                      settings.n_steps, settings.record_every, k_quad=k_quad, what="disturbed truth", kv=kv)
    return out.t, out.q


def theta_rmse_nodes(qa: np.ndarray, qb: np.ndarray) -> float:
    """RMSE of theta over nodes 1..N and all samples [rad]."""
    return float(np.sqrt(np.mean((qa[:, 1:, 2] - qb[:, 1:, 2]) ** 2)))


def camera_frame(t: np.ndarray, q: np.ndarray, params: RodParams, camera: dict[str, Any],
                 rng: np.random.Generator, node_ds: float) -> pd.DataFrame:
    """Camera records of trajectories q (n_t, N+1, 3) of a rod ``params`` (module docstring).

    ``camera``: ``noise_std_m``; optional ``markers_s`` (else every node of spacing
    ``node_ds``, written as a ``node`` column), ``drop_frames``, ``occluded`` (fractions),
    ``outliers`` (count), ``shuffle_rows``.
    """
    if camera.get("markers_s") is not None:
        s = np.asarray(camera["markers_s"], float)
        place = {"s": s}
    else:
        n_nodes = int(round(params.L0 / node_ds)) + 1
        s = np.arange(n_nodes) * node_ds
        place = {"node": np.arange(n_nodes, dtype=np.int32)}
    pos = marker_positions(q, s, params)
    n_t, n_m, _ = pos.shape
    pos = pos + float(camera["noise_std_m"]) * rng.standard_normal(pos.shape)
    mask = np.ones((n_t, n_m), dtype=bool)
    drop = float(camera.get("drop_frames", 0.0))
    if drop > 0:
        mask[rng.random(n_t) < drop] = False
    occ = float(camera.get("occluded", 0.0))
    nan = rng.random((n_t, n_m)) < occ
    n_out = int(camera.get("outliers", 0))
    for k in range(n_out):  # alternately a marker at the origin and two markers swapped
        i, j = int(rng.integers(2, n_t - 2)), int(rng.integers(1, n_m - 1))
        if k % 2 == 0:
            pos[i, j] = 0.0
        else:
            pos[i, [j, j + 1]] = pos[i, [j + 1, j]]
    rows = {
        "t": np.repeat(t, n_m),
        **{k: np.tile(v, n_t) for k, v in place.items()},
        "x": np.where(nan, np.nan, pos[..., 0]).ravel(),
        "y": np.where(nan, np.nan, pos[..., 1]).ravel(),
    }
    df = pd.DataFrame(rows)[mask.ravel()]
    if camera.get("shuffle_rows", False):
        df = df.sample(frac=1.0, random_state=int(rng.integers(2**31)))
    return df.reset_index(drop=True)


def find_case(cases: list[dict[str, Any]], case: str) -> dict[str, Any]:
    for c in cases:
        if c["name"] == case:
            return c
    raise KeyError(f"discovery.cases has no case named {case!r}; known: {[c['name'] for c in cases]}")


def make_measured(nominal: RodParams, d: dict[str, Any], case: dict[str, Any], seed: int
                  ) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Camera data of one hidden-effect case and its truth record (kept in a separate file).

    ``d`` is the ``discovery`` config section (record defaults), ``case`` one of its cases
    (``effects``, ``disturbance``, ``truth_refine``, ``model_form`` and ``camera`` overrides).
    ``model_form`` makes the data simulator differ from the model in form with nothing hidden:
    ``rigid_base_m`` of the rod next to the clamp ``rigid_base_factor`` times stiffer (a clamp
    of finite length, through ``rod.material``'s defect law); the reference run has it too.
    """
    cam = {"noise_std_m": float(d["noise_std_m"]), "sample_rate_hz": float(d["sample_rate_hz"]),
           "duration_s": float(d["duration_s"]), "t_start_s": 0.0, **case.get("camera", {})}
    refine = int(case.get("truth_refine", d["truth_refine"]))
    fine = nominal.replace(N=nominal.N * refine)
    form = case.get("model_form")
    if form:
        edge = 0.25 / fine.N  # sharp: a quarter of the data simulator's segment [s / L0]
        fine = fine.replace(material=dataclasses.replace(
            fine.material, defect_start=0.0, defect_end=float(form["rigid_base_m"]) / fine.L0,
            defect_factor=float(form["rigid_base_factor"]), defect_edge=edge))
    p_truth = effect_params(fine, case.get("effects", {}))
    period = 1.0 / float(cam["sample_rate_hz"])
    skip = int(round(float(cam["t_start_s"]) / period))
    n_samples = skip + int(round(float(cam["duration_s"]) / period)) + 1
    st = aligned_settings(p_truth, float(d["truth_dt_s"]), period, n_samples)
    t, q = simulate_truth(p_truth, float(d["theta0_deg"]), st, case.get("disturbance"))
    t_ref, q_ref = simulate_truth(fine, float(d["theta0_deg"]), aligned_settings(fine, float(d["truth_dt_s"]),
                                                                                   period, n_samples))
    t, q, q_ref = t[skip:], q[skip:], q_ref[skip:]
    effect_size = theta_rmse_nodes(q[:, ::refine], q_ref[:, ::refine])
    rng = np.random.default_rng(seed)
    frame = camera_frame(t, q, p_truth, cam, rng, nominal.ds)
    truth = {"case": case["name"], "effects": dict(case.get("effects", {})),
             "disturbance": case.get("disturbance"), "model_form": form,
             "effect_size_rmse_theta_rad": effect_size,
             "theta0_deg": float(d["theta0_deg"]), "truth_N": p_truth.N, "truth_dt_s": st.dt,
             "camera": cam, "seed": seed, "rod": p_truth.to_dict()}
    return frame, truth
