"""A digital controller in closed loop with a plant: zero-order hold at the control rate.

At every sample t_k = k / f_c the policy reads the plant's tip pose and rate
(``policy.tip_pose``, ``policy.tip_pose_rate``) and sets u_k; the plant then runs with u_k held
over [t_k, t_k+1) (a constant input sequence of ``physics.signals``). The plant is any
``Plant``: ``simulator_plant`` runs the compiled ground-truth kernel (``integrator.run_rod``), and
``learned_plant`` the learned model's rollout (``learning.learned.rollout``), both through the
one integrator, each run continuing from the last state of the previous one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from crgpr.control.policy import Policy, tip_pose, tip_pose_rate
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.physics.integrator import run_rod
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import CHANNELS, Ports
from crgpr.physics.rod import free_mask, masses
from crgpr.physics.signals import SignalInputs
from crgpr.physics.simulate import dissipation_coefficients, kelvin_voigt_kick, rod_kernel_args


@dataclass(frozen=True)
class Plant:
    """``step(q, p, u)`` -> (q, p, work): the state (configuration, the plant's momentum variable)
    after one hold interval under the inputs u (channel -> value), and the port work done over it
    [J]; ``velocity(p)`` -> dq/dt (N+1, 3); ``momentum(v)``: the momentum variable of velocities."""

    step: Callable[[np.ndarray, np.ndarray, dict[str, float]], tuple[np.ndarray, np.ndarray, float]]
    velocity: Callable[[np.ndarray], np.ndarray]
    momentum: Callable[[np.ndarray], np.ndarray]


def _held(u: dict[str, float]) -> SignalInputs:
    return SignalInputs({c: {"kind": "constant", "value": float(v)} for c, v in u.items()}, "held")


def simulator_plant(params: RodParams, settings: SimSettings, ports: Ports, theta_base: float) -> Plant:
    """The ground-truth simulator over one hold interval (``settings.t_end``, step ``settings.dt``):
    the compiled kernel (``integrator.run_rod``) as ``physics.simulate`` calls it, the held
    inputs at every step, the velocities as the plant's momentum variable. ``theta_base`` [rad]:
    the clamp's angle, the base spring's rest angle for the whole closed-loop run (as
    ``simulate`` takes the initial base angle), not the base angle at each hold."""
    m_t, m_r = masses(params)
    rod_args = rod_kernel_args(params, float(theta_base))
    lam_t, lam_r, k_quad = dissipation_coefficients(params)
    free = free_mask(params)
    kv = kelvin_voigt_kick(params, m_r, lam_r, settings.dt)
    n = settings.n_steps

    def step(q, v, u):
        uu = np.zeros((n + 1, len(CHANNELS)))
        for c, x in u.items():
            uu[:, CHANNELS.index(c)] = x
        out = run_rod(q, v, free, m_t, m_r, lam_t, lam_r, k_quad, -m_t * params.g,
                      rod_args, settings.dt, n, n, length=params.L0, kv=kv,
                      scheme=settings.scheme, u=uu, tendon_offset=ports.tendon_offset_m)
        return out.q[-1], out.v[-1], float(out.input_work[-1])
    return Plant(step, lambda v: v, lambda v: v)


def learned_plant(model: LearnedRod, settings: SimSettings, ports: Ports) -> Plant:
    """The learned model's rollout over one hold interval (momenta p per length; velocities by
    the learned H_p; a start at velocities v takes p = (rho A, rho A, rho I) v)."""
    P = model.params
    scale = np.array([P.rhoA, P.rhoA, P.rhoI])

    def step(q, p, u):
        tr = rollout(model, math.nan, settings, what="closed-loop learned rod", inputs=_held(u),
                     ports=ports, initial=(q, p, 0.0))
        return tr.q[-1], tr.p[-1], float(tr.input_work[-1])
    return Plant(step, model.velocity, lambda v: v * scale)


@dataclass
class ClosedLoop:
    """Samples of a closed-loop run: t (n,), tip pose and rate (n, 3), inputs (n, channels),
    the target and u_ff (n, ...), the port work so far [J] (n,), and the rod's shape at every
    ``keep_every``-th sample (t_shapes, shapes, and the velocities there, shape_rates)."""

    t: np.ndarray
    pose: np.ndarray
    rate: np.ndarray
    u: np.ndarray
    target: np.ndarray
    work: np.ndarray
    t_shapes: np.ndarray
    shapes: np.ndarray
    shape_rates: np.ndarray
    q: np.ndarray
    v: np.ndarray


def run_closed_loop(policy: Policy, plant: Plant, q0: np.ndarray, v0: np.ndarray, rate_hz: float,
                    t_end: float, keep_every: int) -> ClosedLoop:
    """Run ``policy`` on ``plant`` from (q0, v0) for ``t_end`` seconds, sampling at ``rate_hz``."""
    n = int(round(t_end * rate_hz))
    q, p = np.array(q0, dtype=float), plant.momentum(np.array(v0, dtype=float))
    rows_t, poses, rates, us, tgts, works, shapes, t_sh, vs = [], [], [], [], [], [], [], [], []
    work = 0.0
    for k in range(n + 1):
        t = k / rate_hz
        v = plant.velocity(p)
        pose, rate = tip_pose(q), tip_pose_rate(q, v)
        u = policy(t, pose, rate)
        rows_t.append(t)
        poses.append(pose)
        rates.append(rate)
        us.append(u)
        tgts.append(policy.reference(t)[1])
        works.append(work)
        if k % keep_every == 0 or k == n:
            shapes.append(q.copy())
            vs.append(v.copy())
            t_sh.append(t)
        if k == n:
            break
        u_map = {c: float(x) for c, x in zip(policy.channels, u, strict=True) if c in CHANNELS}
        q, p, w = plant.step(q, p, u_map)
        work += w
    return ClosedLoop(np.array(rows_t), np.array(poses), np.array(rates), np.array(us), np.array(tgts),
                      np.array(works), np.array(t_sh), np.array(shapes), np.array(vs), q, v)
