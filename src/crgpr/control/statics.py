"""Static equilibrium of a learned rod under tip inputs: the feedforward of energy shaping.

At rest the port-Hamiltonian model (paper eqs. (9), (17)) reduces to the force balance of the
free degrees of freedom

    0 = -dH/dq(q) w ds + f_g w ds + G(q) u          (every free node; G at the tip, physics.ports)

for the learned -dH/dq (``LearnedRod.internal``, per unit length), the gravity load per length
f_g and the tip channels ``tip_force_x``, ``tip_force_y``, ``tip_moment``. Together with the
tip pose constraints x_N = x*, y_N = y* (and phi = phi*, the last segment's chord angle, when
an angle is targeted) this is a square system in (q_free, u): 3N equations of force balance
plus 3 pose/input conditions. For a position-only target the tip moment is not used
(u_moment = 0, the documented choice: the rod takes the shape a pure tip force gives it).
The system is solved by Newton's method (Levenberg-Marquardt damped) with a finite-difference
Jacobian in the rod's angle/strain coordinates (``from_strains``), started from a smooth shape
that reaches the target (``shape_guess``) or from a neighbouring equilibrium; the residual is
reported.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from crgpr.physics.rod import node_weights

CONTROL_CHANNELS: tuple[str, ...] = ("tip_force_x", "tip_force_y", "tip_moment")


class UnreachableTarget(ValueError):
    """A target the rod cannot be held at (outside the workspace, no equilibrium, or beyond a limit)."""


@dataclass(frozen=True)
class Equilibrium:
    """A static equilibrium: configuration q (N+1, 3), inputs u (3,) in ``CONTROL_CHANNELS``
    order, the largest residual nodal force [N or N m] and the Newton iterations used."""

    q: np.ndarray
    u: np.ndarray
    residual: float
    iterations: int


def nodal_residual(internal: Callable[[np.ndarray], np.ndarray], gravity: np.ndarray, q: np.ndarray,
                   u: np.ndarray, ds: float) -> np.ndarray:
    """Nodal force balance (N+1, 3) [N, N, N m]: (-dH/dq + f_g) w ds + G u at the tip."""
    wds = node_weights(q.shape[0] - 1) * ds
    r = (internal(q) + gravity) * wds[:, None]
    r[-1] += u
    return r


def _newton(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, tol: float, max_iter: int,
            h: np.ndarray) -> tuple[np.ndarray, int, float]:
    """Newton's method damped by Levenberg-Marquardt (forward-difference Jacobian, steps ``h``):
    dx = -(J^T J + mu diag(J^T J))^-1 J^T r, mu shrunk after a step that lowers |r|, grown
    otherwise; near the solution it is Newton's method."""
    r = fun(x)
    mu = 1e-3
    for it in range(1, max_iter + 1):
        if np.max(np.abs(r)) <= tol:
            return x, it - 1, float(np.max(np.abs(r)))
        J = np.empty((r.size, x.size))
        for j in range(x.size):
            xp = x.copy()
            xp[j] += h[j]
            J[:, j] = (fun(xp) - r) / h[j]
        A, g = J.T @ J, J.T @ r
        d = np.diag(A).copy()
        while mu < 1e12:
            dx = np.linalg.solve(A + mu * np.diag(d), -g)
            xn = x + dx
            rn = fun(xn)
            if np.all(np.isfinite(rn)) and np.linalg.norm(rn) < np.linalg.norm(r):
                mu = max(mu / 10.0, 1e-12)
                break
            mu *= 10.0
        else:
            break
        x, r = xn, rn
    return x, max_iter, float(np.max(np.abs(r)))


def from_strains(base: np.ndarray, ds: float, x: np.ndarray) -> np.ndarray:
    """Configuration (N+1, 3) from the clamp ``base`` and x = [theta_1..N, a_0..N-1, b_0..N-1]:
    node angles and each segment's chord ds (a, b) in the frame of its mid angle
    (theta_j + theta_j+1) / 2 (a - 1: stretch, b: shear). The solver's unknowns: rigid rotations
    are linear in them, which keeps Newton's steps from stretching the rod."""
    n = (x.size) // 3
    th = np.concatenate([[base[2]], x[:n]])
    a, b = x[n:2 * n], x[2 * n:]
    tb = 0.5 * (th[1:] + th[:-1])
    q = np.empty((n + 1, 3))
    q[:, 2] = th
    q[0, :2] = base[:2]
    q[1:, 0] = base[0] + np.cumsum(ds * (a * np.cos(tb) - b * np.sin(tb)))
    q[1:, 1] = base[1] + np.cumsum(ds * (a * np.sin(tb) + b * np.cos(tb)))
    return q


def to_strains(q: np.ndarray, ds: float) -> np.ndarray:
    """Inverse of ``from_strains``."""
    th = q[:, 2]
    tb = 0.5 * (th[1:] + th[:-1])
    dx, dy = np.diff(q[:, 0]) / ds, np.diff(q[:, 1]) / ds
    a = dx * np.cos(tb) + dy * np.sin(tb)
    b = -dx * np.sin(tb) + dy * np.cos(tb)
    return np.concatenate([th[1:], a, b])


def shape_guess(base: np.ndarray, ds: float, n: int, target: tuple[float, float, float | None]) -> np.ndarray:
    """A rod shape (N+1, 3) from the clamp ``base`` (x, y, theta) whose tip reaches the target: the
    angle theta(s) = theta_b + a s + b s^2 (+ c s^3 for an angle target), segments of length ds,
    coefficients by least squares. Newton's first guess, not an equilibrium."""
    from scipy.optimize import least_squares

    s_mid = (np.arange(n) + 0.5) * ds
    s_node = np.arange(n + 1) * ds
    n_coef = 3 if target[2] is not None else 2

    def shape(c: np.ndarray) -> np.ndarray:
        powers = np.arange(1, n_coef + 1)
        th_mid = base[2] + (c[None] * s_mid[:, None] ** powers).sum(axis=1)
        q = np.empty((n + 1, 3))
        q[0] = base
        q[1:, 0] = base[0] + np.cumsum(ds * np.cos(th_mid))
        q[1:, 1] = base[1] + np.cumsum(ds * np.sin(th_mid))
        q[1:, 2] = base[2] + (c[None] * s_node[1:, None] ** powers).sum(axis=1)
        return q

    def res(c: np.ndarray) -> np.ndarray:
        q = shape(c)
        r = [q[-1, 0] - target[0], q[-1, 1] - target[1]]
        if target[2] is not None:
            r.append(ds * n * _wrap(tip_angle(q) - target[2]))
        return np.array(r)

    best = None
    for a0 in np.linspace(-6.0, 6.0, 13) / (ds * n):
        sol = least_squares(res, np.r_[a0, np.zeros(n_coef - 1)], xtol=1e-14, ftol=1e-14)
        if best is None or sol.cost < best.cost:
            best = sol
    return shape(best.x)


def solve_equilibrium(internal: Callable[[np.ndarray], np.ndarray], gravity: np.ndarray, q_start: np.ndarray,
                      ds: float, target: tuple[float, float, float | None], tol: float, max_iter: int,
                      u_start: np.ndarray | None = None) -> Equilibrium:
    """The equilibrium holding the tip at ``target`` = (x*, y*, phi* or None) (module doc).

    ``internal(q)``: the model's -dH/dq per unit length (N+1, 3); ``gravity``: f_g per length (3,);
    ``q_start`` (N+1, 3): the clamp (node 0) and, with ``u_start`` (its inputs), the first guess
    (an earlier equilibrium); without, Newton starts from ``shape_guess``. ``tol``
    bounds the largest residual force relative to the rod's weight. Raises ``UnreachableTarget``
    when Newton's method does not reach ``tol``."""
    q0 = np.array(q_start, dtype=float)
    n = q0.shape[0] - 1
    free = np.ones((n + 1, 3), dtype=bool)
    free[0] = False
    length = ds * n
    w_scale = float(np.abs(gravity).max() * ds * n) or 1.0
    x_angle = target[2] is not None
    h = np.concatenate([np.full(3 * n, 1e-7), np.full(3, 1e-7 * w_scale)])

    def unpack(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return from_strains(q0[0], ds, x[:3 * n]), x[3 * n:]

    def fun_for(tgt: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
        def fun(x: np.ndarray) -> np.ndarray:
            q, u = unpack(x)
            r = nodal_residual(internal, gravity, q, u, ds)[free] / w_scale
            extra = np.array([(q[-1, 0] - tgt[0]) / length, (q[-1, 1] - tgt[1]) / length,
                              _wrap(tip_angle(q) - tgt[2]) if x_angle else u[2] / w_scale])
            return np.concatenate([r, extra])
        return fun

    goal = np.array([target[0], target[1], 0.0 if target[2] is None else target[2]])
    if u_start is None:
        q0 = shape_guess(q0[0], ds, n, target)
        x = np.concatenate([to_strains(q0, ds), np.zeros(3)])
    else:
        x = np.concatenate([to_strains(q0, ds), np.asarray(u_start, dtype=float)])
    x, its, res = _newton(fun_for(goal), x, tol, max_iter, h)
    if not res <= tol:
        raise UnreachableTarget(f"no static equilibrium holds the tip at {_fmt(target)} "
                                f"(residual {res:.2g} of the rod's weight)")
    q, u = unpack(x)
    if not x_angle:
        u = u.copy()
        u[2] = 0.0
    return Equilibrium(q, u, float(np.max(np.abs(nodal_residual(internal, gravity, q, u, ds)[free]))), its)


def tip_angle(q: np.ndarray) -> float:
    """The last segment's angle phi [rad] (its chord; the policy's tip angle)."""
    d = q[-1, :2] - q[-2, :2]
    return float(np.arctan2(d[1], d[0]))


def _wrap(a: float) -> float:
    return float((a + np.pi) % (2 * np.pi) - np.pi)


def _fmt(target: tuple[float, float, float | None]) -> str:
    ang = "" if target[2] is None else f", angle {target[2]:.4g} rad"
    return f"x = {target[0]:.4g} m, y = {target[1]:.4g} m{ang}"


def check_workspace(target: tuple[float, float, float | None], base: np.ndarray, length: float,
                    margin: float) -> None:
    """Refuse a tip position farther from the clamp than (1 - margin) L (the inextensible reach)."""
    d = float(np.hypot(target[0] - base[0], target[1] - base[1]))
    if d > (1.0 - margin) * length:
        raise UnreachableTarget(f"target {_fmt(target)} is {d:.4g} m from the clamp, outside the workspace "
                                f"(reach (1 - control.workspace_margin) L = {(1 - margin) * length:.4g} m)")
