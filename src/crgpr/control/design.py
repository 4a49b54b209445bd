"""Controller design on a learned model: feedforward by energy shaping plus tip feedback.

Regulation (docs/control.md): u_ff from the static equilibrium of the model holding the tip at
the target (``statics.solve_equilibrium``), K_p a spring on the tip pose error (forces on
x, y; the moment on phi when an angle is targeted) and K_d damping injection on the collocated
rate (the same structure). Tracking: u_ff(t) from the model's quasi-static equilibria along the
path (sampled, continued from one path point to the next), the same feedback, the path's rate as
the rate reference. Inputs beyond a limit are refused (``UnreachableTarget``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from crgpr.control.policy import Policy
from crgpr.control.statics import (
    CONTROL_CHANNELS,
    Equilibrium,
    UnreachableTarget,
    check_workspace,
    solve_equilibrium,
)


@dataclass(frozen=True)
class Gains:
    """Tip feedback gains: translational spring [N/m] and damper [N s/m] on x, y; rotational
    spring [N m/rad] and damper [N m s/rad] on phi (used when an angle is targeted)."""

    kp_force: float
    kd_force: float
    kp_moment: float
    kd_moment: float

    def matrices(self, with_angle: bool) -> tuple[np.ndarray, np.ndarray]:
        """K_p, K_d (channels x 3) in ``CONTROL_CHANNELS`` order."""
        a = 1.0 if with_angle else 0.0
        return (np.diag([self.kp_force, self.kp_force, a * self.kp_moment]),
                np.diag([self.kd_force, self.kd_force, a * self.kd_moment]))


@dataclass(frozen=True)
class Solver:
    """Equilibrium solver settings: tolerance (relative to the rod's weight), Newton iterations, and
    the workspace margin (fraction of L)."""

    tol: float
    max_iter: int
    workspace_margin: float


def check_limits(u: np.ndarray, u_min: np.ndarray, u_max: np.ndarray, what: str) -> None:
    """Refuse a feedforward outside the input limits (one line naming the channel)."""
    for k, c in enumerate(CONTROL_CHANNELS):
        if not u_min[k] <= u[k] <= u_max[k]:
            raise UnreachableTarget(f"{what} needs {c} = {u[k]:.4g}, beyond the limit "
                                    f"control.u_limits.{c} = [{u_min[k]:.4g}, {u_max[k]:.4g}]")


def hold(internal: Callable[[np.ndarray], np.ndarray], gravity: np.ndarray, q_rest: np.ndarray, ds: float,
         target: tuple[float, float, float | None], solver: Solver, u_min: np.ndarray, u_max: np.ndarray
         ) -> Equilibrium:
    """The model's equilibrium at the target, after the workspace and input-limit checks."""
    check_workspace(target, q_rest[0], ds * (q_rest.shape[0] - 1), solver.workspace_margin)
    eq = solve_equilibrium(internal, gravity, q_rest, ds, target, solver.tol, solver.max_iter)
    check_limits(eq.u, u_min, u_max, "holding the tip at the target")
    return eq


def regulation_policy(eq: Equilibrium, target: tuple[float, float, float | None], gains: Gains,
                      u_min: np.ndarray, u_max: np.ndarray, feedforward: bool = True) -> Policy:
    """Hold one target: u = clip(u_ff + K_p e + K_d de/dt); ``feedforward=False`` is plain PD."""
    with_angle = target[2] is not None
    kp, kd = gains.matrices(with_angle)
    phi = float(target[2]) if with_angle else 0.0
    u_ff = eq.u if feedforward else np.zeros(3)
    return Policy(CONTROL_CHANNELS, np.zeros(1), u_ff[None].copy(), np.array([[target[0], target[1], phi]]),
                  np.zeros((1, 3)), kp, kd, u_min, u_max)


def circle_path(center: tuple[float, float], radius: float, frequency_hz: float, t: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
    """Tip path (n, 2) on a circle starting at its rightmost point, counter-clockwise, and its rate."""
    w = 2 * np.pi * frequency_hz
    xy = np.column_stack([center[0] + radius * np.cos(w * t), center[1] + radius * np.sin(w * t)])
    rate = np.column_stack([-radius * w * np.sin(w * t), radius * w * np.cos(w * t)])
    return xy, rate


def tracking_policy(internal: Callable[[np.ndarray], np.ndarray], gravity: np.ndarray, q_rest: np.ndarray,
                    ds: float, t: np.ndarray, xy: np.ndarray, rate: np.ndarray, gains: Gains, solver: Solver,
                    u_min: np.ndarray, u_max: np.ndarray, feedforward: bool = True
                    ) -> tuple[Policy, np.ndarray]:
    """Track the position path xy (n, 2) at times t by quasi-static feedforward: the model's
    equilibrium at every path point (each continued from the previous one) plus the feedback.
    Returns the policy and the equilibrium shapes (n, N+1, 3)."""
    kp, kd = gains.matrices(False)
    us, shapes = [], []
    eq = hold(internal, gravity, q_rest, ds, (float(xy[0, 0]), float(xy[0, 1]), None), solver, u_min, u_max)
    for k in range(len(t)):
        tgt = (float(xy[k, 0]), float(xy[k, 1]), None)
        if k:
            check_workspace(tgt, q_rest[0], ds * (q_rest.shape[0] - 1), solver.workspace_margin)
            eq = solve_equilibrium(internal, gravity, eq.q, ds, tgt, solver.tol, solver.max_iter, eq.u)
            check_limits(eq.u, u_min, u_max, f"the path at t = {t[k]:.3g} s")
        us.append(eq.u if feedforward else np.zeros(3))
        shapes.append(eq.q)
    target = np.column_stack([xy, np.zeros(len(t))])
    trate = np.column_stack([rate, np.zeros(len(t))])
    policy = Policy(CONTROL_CHANNELS, np.asarray(t, float), np.array(us), target, trate, kp, kd, u_min, u_max)
    return policy, np.array(shapes)
