"""Stormer-Verlet time integration with Strang-split dissipation (paper Sec. IV).

One step of length dt for a state (q, p) with dq/dt = V(q, p), dp/dt = F(q, p) - R p:

    p <- D(dt/2) p                      exact dissipative flow (damping, drag)
    p <- p + dt/2 F(q, p)               kick
    q <- q + dt V(q, p)                 drift
    p <- p + dt/2 F(q, p)               kick (F reused by the next step's first kick)
    p <- D(dt/2) p

For a separable Hamiltonian (V = H_p(p), F = -H_q(q) + G u, the rod of eq. (9), Sec. III-A,
and the learned rod of eq. (17), Sec. III-B step 4) this is the symplectic Stormer-Verlet
(velocity Verlet) scheme the paper uses; the dissipation R is applied by its exact flow, so it
can only remove energy and is stable for any damping. The scheme is symmetric and second
order; the energy removed by D is accumulated as the dissipated energy.
The Kelvin-Voigt bending damping (m += c dkappa/dt, ``rod.material.kelvin_voigt``, the
missing-physics library's internal damping, a learned bending damping) couples neighbouring
angular rates with rates c / (rho I ds^2) far above 1 / dt; split around the kick as above it
makes the scheme first order (its overdamped short modes answer the kick's impulse instead of
the balance of the couples: ``benchmarks/kv_step_convergence.py``). Where it is present the
rotational entries therefore take no separate damping half-step: each rotational half-kick is
the exact flow of d omega/dt = a - A omega with the force a frozen over dt/2 and A the
Kelvin-Voigt and zeta rates together (``dissipation.kelvin_voigt_flow``), which is the kick when
A = 0, symmetric, second order, passive and unconditionally stable; the energy it dissipates
is booked exactly (the frozen couples' work less the kinetic-energy gain). The translational
entries keep the split above. The dissipative flows and their tangents live in
``physics.dissipation``.

One implementation, ``run_verlet`` (the generic form: any F(q, p), V(q, p); the black-box
baseline, which has no p/m structure, uses it directly), with two thin forms:
``run_hamiltonian`` (learned H_z: F(q), V(p), damping dp/dt = -zeta H_p(p)) and
``run_generic`` (positions and velocities with lumped masses). ``run_rod`` is a compiled
private kernel of the same scheme and divergence policy for the analytic rod (ground truth);
tests/test_integrator.py checks that it and ``run_hamiltonian``/``run_generic`` agree to
round-off.

Actuation inputs (``physics.ports``): the tip load G(z) u at the step time is added in every kick
(``run_rod``: after the elastic kick of the tip; ``run_verlet``: to F). Their work is booked
per kick as the port impulse dotted with the mean of the velocities before and after the whole
kick, which is that kick's exact share of the kinetic-energy change, so
H(T) - H(0) = input work - dissipated holds to the scheme's O(dt^2) energy error.

Divergence policy (one for every path): at each recorded step a node is diverged when its
state is non-finite, a velocity component |dq/dt| reaches ``MAX_SPEED``, or its position
leaves the disc of radius ``REACH`` x the rod length around the clamped base (node 0). The
run then stops with ``SimulationDiverged``, which carries the time, the first bad node and
the records up to the last good one (``partial``); the caller decides whether that fails
the rule (learned rollouts, ground truth) or is scored as a frozen state (black box).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from crgpr.physics.dissipation import _damp_exponentials, _damp_factors, kelvin_voigt_flow, kv_flow_step
from crgpr.physics.kernels import MAX_SPEED, _rod_kernel
from crgpr.physics.momentum_maps import MomentumMaps
from crgpr.physics.params import SCHEMES

# A rod of length L released from rest cannot move its material points faster than about
# its elastic wave speed sqrt(E / rho) (55 m/s for Table I's rod) nor stretch to twice its
# length; states beyond these bounds are a diverged run, not physics (MAX_SPEED [m/s, rad/s]
# lives with the compiled kernel, ``kernels``, that checks it too).
REACH = 2.0  # [-] nodes stay within REACH x the rod length of the clamped base


class SimulationDiverged(RuntimeError):
    """Raised when the state leaves the physical range; carries where and when."""

    def __init__(self, message: str, step: int, t: float, node: int,
                 partial: Integration | None = None, members: np.ndarray | None = None):
        super().__init__(message)
        self.step = step
        self.t = t
        self.node = node
        self.partial = partial  # the records up to the last good one
        # batched runs (leading axes on the state): indices of the batch members that left the
        # physical range, (k, n_batch_axes); None for an unbatched run
        self.members = members


@dataclass
class Integration:
    """Recorded output of a run: positions q, velocities v (n_rec, N+1, 3) and energy terms."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    dissipated: np.ndarray  # cumulative energy removed by the dissipative flow [J]
    # tangent-linear records (n_rec, m, N+1, 3) of m initial-state directions (``run_rod``'s
    # dq0/dv0): dq/d(direction); None when no direction was given
    dq: np.ndarray | None = None
    # cumulative work of the actuation inputs (``physics.ports``) [J]: at every kick the port
    # impulse dotted with the mean of the pre- and post-kick velocities; None without inputs
    input_work: np.ndarray | None = None
    # cumulative work of ``force`` along the drifts [J] (``run_verlet(book_force=True)``): per
    # step, the trapezoid of the force at the drift's ends dotted with the displacement; None
    # when not booked
    force_work: np.ndarray | None = None


def rod_length(q: np.ndarray) -> float:
    """Length of the polygon through the nodes of one rod (N+1, 3) (the longest of a batch)."""
    return float(np.max(np.hypot(np.diff(q[..., 0], axis=-1), np.diff(q[..., 1], axis=-1)).sum(-1)))


def diverged_nodes(q: np.ndarray, v: np.ndarray, base: np.ndarray, reach: float) -> np.ndarray:
    """The divergence policy (module docstring): True for every node (..., N+1) whose q or
    v = dq/dt is non-finite, with |v| >= MAX_SPEED, or farther than ``reach`` from ``base``."""
    base = np.asarray(base, dtype=float)
    bx, by = base[..., 0], base[..., 1]
    if bx.ndim:  # one base per rod of a batch (..., 2) -> broadcast over the nodes
        bx, by = bx[..., None], by[..., None]
    ok = (np.isfinite(q).all(-1) & np.isfinite(v).all(-1) & (np.abs(v) < MAX_SPEED).all(-1)
          & (np.hypot(q[..., 0] - bx, q[..., 1] - by) <= reach))
    return ~ok


def _diverged(what: str, k: int, dt: float, bad: np.ndarray, hint: str,
              partial: Integration | None) -> SimulationDiverged:
    node = int(np.nonzero(bad.reshape(-1, bad.shape[-1]))[1][0])
    members = np.argwhere(bad.any(axis=-1)) if bad.ndim > 1 else None
    return SimulationDiverged(
        f"{what} diverged at t = {k * dt:.6g} s (step {k}), first bad node {node}: state "
        f"non-finite, speed >= {MAX_SPEED:g} or farther than {REACH:g} rod lengths from the "
        f"base.{hint}", k, k * dt, node, partial, members)


def run_rod(q0, v0, free, m_t, m_r, lam_t, lam_r, k_quad, grav_force, rod_args, dt, n_steps, every,
            length=None, kv: np.ndarray | None = None, scheme: str = "variational",
            dq0: np.ndarray | None = None, dv0: np.ndarray | None = None,
            u: np.ndarray | None = None, tendon_offset: float = 0.0):
    """Integrate the analytic rod (compiled ``run_generic``). ``rod_args`` are the trailing
    arguments of the force kernel; ``grav_force`` the nodal y-force of gravity (-m_i g);
    ``length`` the rod length for the reach bound (default: that of q0); ``kv`` the
    Kelvin-Voigt rod's rotational half-kick flow over dt/2 (``kelvin_voigt_flow`` with these
    lam_r; None or an empty stack: no internal damping);
    ``scheme`` the spatial discretisation of the elastic forces (``SCHEMES``: 'variational',
    rod.py; 'collocated' or 'collocated_nodal', collocated.py). ``dq0``, ``dv0`` (m, N+1, 3):
    directions of the initial state whose tangent-linear propagation (the exact derivative of
    this discrete scheme's records with respect to the initial state) is returned in
    ``Integration.dq`` (variational scheme; the rollout is the same to the last bit with or
    without them). ``u`` (n_steps + 1, n_channels): the actuation inputs at the step times
    k dt (``physics.ports``, tendon offset ``tendon_offset`` [m]; None: none, the kernel's
    arithmetic is then that of a rod without ports), their work in ``Integration.input_work``.
    Raises SimulationDiverged."""
    if scheme not in SCHEMES:
        raise ValueError(f"unknown spatial scheme {scheme!r}; expected one of {SCHEMES}")
    law = np.asarray(rod_args[5])
    if scheme != "variational" and (law[0] != 0.0 or law[2] != 0.0 or np.any(rod_args[4])):
        raise ValueError(f"rod.material: the {scheme!r} scheme implements linear laws and a uniform "
                         "rest curvature only; use simulation.scheme: variational for this material")
    n_nodes = np.shape(q0)[0]
    kv = np.zeros((0, n_nodes, n_nodes)) if kv is None else np.ascontiguousarray(kv, dtype=float)
    n_rec = n_steps // every + 1
    q = np.array(q0, dtype=float, order="C")
    v = np.array(v0, dtype=float, order="C") * free
    if dq0 is None:
        dq = np.zeros((0, q.shape[0], 3))
        dv = np.zeros_like(dq)
    else:
        if scheme != "variational":
            raise ValueError(f"tangent directions need the variational scheme, not {scheme!r}")
        dq = np.array(dq0, dtype=float, order="C")
        dv = np.array(np.zeros_like(dq) if dv0 is None else dv0, dtype=float, order="C") * free
    base = q[0, :2].copy()
    reach = REACH * (rod_length(q) if length is None else float(length))
    out_q = np.zeros((n_rec, q.shape[0], 3))
    out_v = np.zeros_like(out_q)
    out_d = np.zeros(n_rec)
    out_dq = np.zeros((n_rec if dq.shape[0] else 0, *dq.shape))
    uu = np.zeros((0, 4)) if u is None else np.ascontiguousarray(u, dtype=float)
    if u is not None and uu.shape != (n_steps + 1, 4):
        raise ValueError(f"inputs u must be (n_steps + 1, 4) = ({n_steps + 1}, 4), not {uu.shape}")
    out_w = np.zeros(n_rec)
    status = _rod_kernel(q, v, free, m_t, m_r, lam_t, lam_r, k_quad, grav_force, *rod_args,
                         dt, n_steps, every, reach, out_q, out_v, out_d, kv, SCHEMES.index(scheme),
                         dq, dv, out_dq, uu, float(tendon_offset), out_w)
    t = np.arange(n_rec) * dt * every
    w = None if u is None else out_w
    if status >= 0:
        r = status // every
        raise _diverged("simulation", status, dt, diverged_nodes(q, v, base, reach),
                        " Reduce the time step (config key simulation.dt_s) or check the parameters.",
                        Integration(t[:r], out_q[:r], out_v[:r], out_d[:r],
                                    input_work=None if w is None else w[:r]))
    return Integration(t, out_q, out_v, out_d, out_dq if dq.shape[0] else None, w)


def run_verlet(
    q0: np.ndarray,
    p0: np.ndarray,
    force: Callable[[np.ndarray, np.ndarray], np.ndarray],
    velocity: Callable[[np.ndarray, np.ndarray], np.ndarray],
    free: np.ndarray,
    dt: float,
    n_steps: int,
    every: int,
    damp: Callable[[np.ndarray], tuple[np.ndarray, float]] | None = None,
    kick_scale: np.ndarray | None = None,
    length: float | None = None,
    what: str = "rollout",
    port: Callable[[int, np.ndarray], np.ndarray] | None = None,
    port_weight: np.ndarray | None = None,
    book_force: bool = False,
    rot_flow: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray | float]] | None = None,
) -> Integration:
    """The Strang-split Stormer-Verlet scheme of the module docstring, generic form.

    ``force(q, p)`` -> dp/dt without dissipation (N+1, 3) (or (..., 3) stacked rods);
    ``velocity(q, p)`` -> dq/dt; ``damp(p)`` -> (p after the exact dissipative flow over
    dt/2, energy removed); ``kick_scale`` multiplies the kicks (default ``free``; inverse
    masses for a velocity state); ``free`` masks the clamped entries. ``length``: rod length
    for the reach bound (default: that of q0). Returns an ``Integration`` whose ``v`` holds
    the state p. Batches: q0, p0 may carry leading axes (..., N+1, 3) when ``force`` and
    ``velocity`` do; every member is integrated independently, ``damp`` returns the energy
    removed per member and ``dissipated`` is (n_rec, ...). Raises SimulationDiverged
    (divergence policy of the module docstring; for a batch ``members`` names the bad ones).
    ``port(k, q)``: the actuation inputs' addition to dp/dt at step time k dt (G(z) u,
    ``physics.ports``), added to ``force``; their work, h (port force) . (mean of the pre- and
    post-kick velocities) per kick weighted per node by ``port_weight`` (N+1,) (the node's
    length w_i ds for forces per length; 1 for nodal forces), is ``Integration.input_work``.
    ``book_force``: also book the work of ``force`` along every drift, h (f(q_n) + f(q_n+1)) .
    dq weighted by ``port_weight`` (``Integration.force_work``; minus the potential energy for a
    conservative force, the learned path energy otherwise).
    ``rot_flow(x, f)`` (a Kelvin-Voigt rod, module docstring): the rotational half-kick, x the
    rotational entries of the state (..., N+1) and f those of the force (ports included) ->
    (x after the exact affine flow over dt/2, energy dissipated); ``damp`` must then leave the
    rotational entries alone.
    """
    q = np.array(q0, dtype=float)
    p = np.array(p0, dtype=float) * free
    ks = free if kick_scale is None else kick_scale
    base = q[..., 0, :2].copy()
    reach = REACH * (rod_length(q) if length is None else float(length))
    n_rec = n_steps // every + 1
    out_q = np.zeros((n_rec, *q.shape))
    out_p = np.zeros_like(out_q)
    out_d = np.zeros((n_rec, *q.shape[:-2]))
    out_q[0], out_p[0] = q, p
    t = np.arange(n_rec) * dt * every
    h = 0.5 * dt
    f = force(q, p)
    diss = np.zeros(q.shape[:-2])
    work = np.zeros(q.shape[:-2])
    out_w = np.zeros((n_rec, *q.shape[:-2])) if port is not None else None
    fwork = np.zeros(q.shape[:-2])
    out_fw = np.zeros((n_rec, *q.shape[:-2])) if book_force else None
    pw = np.ones(q.shape[-2]) if port_weight is None else np.asarray(port_weight, dtype=float)
    pw = pw[:, None] * free

    def advance(p: np.ndarray, g: np.ndarray) -> np.ndarray:
        """p after the half-kick by the force g (the rotational entries by ``rot_flow``)."""
        p1 = p + h * g * ks
        if rot_flow is not None:
            p1[..., 2], lost = rot_flow(p[..., 2], g[..., 2])
            diss[...] += lost
        return p1

    def kick(q: np.ndarray, p: np.ndarray, fu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """p after a port-carrying kick and the velocity there; adds the port work."""
        v0 = velocity(q, p)
        p = advance(p, f + fu)
        v1 = velocity(q, p)
        work[...] += h * (pw * fu * 0.5 * (v0 + v1)).sum(axis=(-2, -1))
        return p, v1

    fu = port(0, q) if port is not None else None
    for k in range(1, n_steps + 1):
        if damp is not None:
            p, e1 = damp(p)
        if fu is None:
            p = advance(p, f)
            dq = dt * velocity(q, p) * free
        else:
            p, v1 = kick(q, p, fu)
            dq = dt * v1 * free
        q = q + dq
        f0 = f
        f = force(q, p)
        if out_fw is not None:
            fwork += 0.5 * (pw * (f0 + f) * dq).sum(axis=(-2, -1))
        if fu is None:
            p = advance(p, f)
        else:
            fu = port(k, q)
            p, _ = kick(q, p, fu)
        if damp is not None:
            p, e2 = damp(p)
            diss += e1 + e2
        if k % every == 0:
            r = k // every
            bad = diverged_nodes(q, velocity(q, p), base, reach)
            if bad.any():
                raise _diverged(what, k, dt, bad, "", Integration(
                    t[:r], out_q[:r], out_p[:r], out_d[:r],
                    input_work=None if out_w is None else out_w[:r],
                    force_work=None if out_fw is None else out_fw[:r]))
            out_q[r], out_p[r], out_d[r] = q, p, diss
            if out_w is not None:
                out_w[r] = work
            if out_fw is not None:
                out_fw[r] = fwork
    return Integration(t, out_q, out_p, out_d, input_work=out_w, force_work=out_fw)


def run_generic(
    q0: np.ndarray,
    v0: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    free: np.ndarray,
    m_t: np.ndarray,
    m_r: np.ndarray,
    lam_t: np.ndarray,
    lam_r: np.ndarray,
    dt: float,
    n_steps: int,
    every: int,
    k_quad: np.ndarray | None = None,
    what: str = "rollout",
    length: float | None = None,
    kv: np.ndarray | None = None,
    port: Callable[[int, np.ndarray], np.ndarray] | None = None,
) -> Integration:
    """``run_verlet`` in positions and velocities with lumped masses m_t, m_r: dq/dt = v,
    m dv/dt = force(q) (including gravity) + port(k, q) (the nodal actuation forces at step k,
    ``run_verlet``), damping by the exact flow of ``run_rod`` (rates lam_t, lam_r, quadratic
    drag k_quad; ``kv`` as there: the rotational half-kick flow of a Kelvin-Voigt rod). Same
    scheme as ``run_rod``."""
    n = q0.shape[0]
    k_quad = np.zeros(n) if k_quad is None else k_quad
    minv = np.stack([1.0 / m_t, 1.0 / m_t, 1.0 / m_r], axis=1) * free
    h = 0.5 * dt
    use_kv = kv is not None and kv.shape[0] > 0
    lam_r = np.asarray(lam_r, dtype=float) * (0.0 if use_kv else 1.0)  # then in the flow
    ft, fr = _damp_exponentials(np.asarray(lam_t, dtype=float), lam_r, h)

    def damp(v: np.ndarray) -> tuple[np.ndarray, float]:
        v = np.ascontiguousarray(v)
        return v, _damp_factors(v, m_t, m_r, ft, fr, k_quad, free, h)

    def rot_flow(w: np.ndarray, f: np.ndarray) -> tuple[np.ndarray, np.ndarray | float]:
        return kv_flow_step(kv, w, f * minv[:, 2], m_r)

    return run_verlet(q0, v0, lambda q, v: force(q), lambda q, v: v, free, dt, n_steps, every,
                      damp=damp, kick_scale=minv, length=length, what=what, port=port,
                      rot_flow=rot_flow if use_kv else None)


def run_hamiltonian(
    q0: np.ndarray,
    p0: np.ndarray,
    force: Callable[[np.ndarray], np.ndarray],
    velocity: Callable[[np.ndarray], np.ndarray],
    free: np.ndarray,
    zeta: float,
    dt: float,
    n_steps: int,
    every: int,
    wds: np.ndarray | None = None,
    what: str = "rollout",
    velocity_slope: Callable[[np.ndarray], np.ndarray] | None = None,
    length: float | None = None,
    port: Callable[[int, np.ndarray], np.ndarray] | None = None,
    bending: tuple[float, float, float] | None = None,
    inverse_mass: np.ndarray | None = None,
    momentum_maps: MomentumMaps | None = None,
    book_energy: bool = True,
) -> Integration:
    """``run_verlet`` in (q, p) for a learned H_z (eq. (17), Sec. III-B step 4).

    ``force(q)`` -> (N+1, 3): -H_q + G u per unit length (dp/dt without damping);
    ``velocity(p)`` -> (N+1, 3): H_p, so that dq/dt = H_p and the damping R of eq. (8) gives
    dp/dt = -zeta H_p. The damping flow over h = dt/2 is taken exactly for an affine H_p
    (exponential Euler with the slope s = dH_p/dp from ``velocity_slope``, or a central
    difference): p <- p - (1 - exp(-zeta s h)) / s * H_p(p). For the analytic
    H_p = p / (rho A) this is ``run_rod``'s exact exponential, so with the analytic H_z the
    two agree to round-off. ``v`` of the result holds the MOMENTA p per length;
    ``dissipated`` accumulates the energy each damping half-step removes, int zeta sum_i w_i ds
    |H_p|^2 dt over the exact flow = sum_i w_i ds (H_p(p0) + H_p(p1))/2 . (p0 - p1), exact for
    an affine H_p (a trapezoid of the rate would be off by O((zeta s h)^3), which the tip's
    small rotational inertia makes large; needs ``wds``). The work of ``force`` (-H_q and
    gravity) along the drifts is ``force_work`` (``run_verlet(book_force=True)``). States may
    carry leading batch axes (..., N+1, 3) when
    ``force`` and ``velocity`` do (several initial states, or a LearnedRod of posterior
    samples); ``dissipated`` is then per member (n_rec, ...). ``port(k, q)``: G(z) u per unit
    length at step k (``physics.ports``); its work (weighted by ``wds``) is ``input_work``.
    ``bending`` = (c, ds, mu): a learned Kelvin-Voigt bending damping m_d = c dkappa/dt
    (``physics.dissipation``) for the rotational momentum map H_p_theta = mu p_theta (a learned
    table map is taken at its slope at rest there): the rotational half-kicks and their zeta
    damping are then the exact affine flow (``kelvin_voigt_flow`` over dt/2, lumped rotational
    masses w_i ds / mu, rates zeta mu), p_theta <- P p_theta + Phi f_theta, and ``dissipated``
    adds the energy it removes (``dissipation.kv_flow_step``); the other damping half-steps
    leave p_theta alone. (c and ds are for the caller's power, ``dissipation.bending_power``.)
    ``inverse_mass`` (3,): the momentum map is linear, H_p = inverse_mass * p (``velocity`` must
    be that map); each damping half-step is then the fixed linear map it is exactly (the zeta
    flow p <- exp(-zeta inverse_mass h) p), precomputed, and the energy it removes is the
    drop of the kinetic energy sum_i w_i ds inverse_mass p^2 / 2 (what the trapezoid books for an
    affine H_p).
    ``momentum_maps`` (``physics.momentum_maps.MomentumMaps``, the maps ``velocity`` evaluates:
    each linear or a table): the same generic damping half-step in one compiled pass.
    ``book_energy`` False (a fit that reads only the states): no ``force_work``, and with
    ``inverse_mass`` no ``dissipated`` either (zeros); the states are the same.
    """
    wds = np.ones(q0.shape[-2]) if wds is None else np.asarray(wds, dtype=float)
    h = 0.5 * dt
    rot_flow = None
    damped = free
    if bending is not None and bending[0] > 0:
        c, ds, mu = bending
        m_rot = wds * mu
        flow = kelvin_voigt_flow(c, ds, wds / mu, np.full(wds.shape, zeta * mu), free[:, 2], h)
        damped = free * np.array([1.0, 1.0, 0.0])  # p_theta: damped in the rotational flow

        def rot_flow(x: np.ndarray, g: np.ndarray) -> tuple[np.ndarray, np.ndarray | float]:
            return kv_flow_step(flow, x, g, m_rot, book_energy)

    def slope(p: np.ndarray) -> np.ndarray:
        if velocity_slope is not None:
            return velocity_slope(p)
        d = 1e-6 * np.maximum(np.abs(p), 1e-6)
        return (velocity(p + d) - velocity(p - d)) / (2 * d)

    last: list[np.ndarray] = []  # [p1, H_p(p1)] of the previous damping half-step

    def damp(p: np.ndarray) -> tuple[np.ndarray, float]:
        # two damping half-steps meet between steps: the second's H_p(p1) is the next one's v0
        v0 = last[1] if last and last[0] is p else velocity(p)
        sl = slope(p) * zeta
        small = np.abs(sl * h) < 1e-12
        fac = np.where(small, zeta * h, -np.expm1(-sl * h) / np.where(small, 1.0, sl) * zeta)
        dp = fac * v0 * damped
        p1 = p - dp
        v1 = velocity(p1)
        # the energy the zeta flow removes, int H_p . dp along it (trapezoid in p: exact for an affine H_p)
        lost = 0.5 * (wds[:, None] * (v0 + v1) * dp).sum(axis=(-2, -1))
        last[:] = [p1, v1]
        return p1, lost

    if inverse_mass is not None:
        step = _linear_damping(inverse_mass, damped, zeta, h, wds, book_energy)
    elif momentum_maps is not None:
        step = momentum_maps.damping(damped, zeta, h, wds)
    else:
        step = damp
    return run_verlet(q0, p0, lambda q, p: force(q), lambda q, p: velocity(p), free, dt, n_steps,
                      every, damp=step, length=length, what=what, port=port, port_weight=wds,
                      book_force=book_energy, rot_flow=rot_flow)


def _linear_damping(inverse_mass: np.ndarray, free: np.ndarray, zeta: float, h: float, wds: np.ndarray,
                    book_energy: bool = True
                    ) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray | float]]:
    """``run_hamiltonian``'s damping half-step for a linear momentum map (its ``inverse_mass``)
    on the entries ``free`` marks; without ``book_energy`` the energy it removes is not computed
    (returned as 0)."""
    m = np.broadcast_to(np.asarray(inverse_mass, dtype=float), free.shape) * free
    decay = np.exp(-zeta * m * h)  # the exact zeta flow (1 on the clamped entries)
    half_w = 0.5 * wds[:, None] * m

    def damp(p: np.ndarray) -> tuple[np.ndarray, np.ndarray | float]:
        p1 = p * decay
        if not book_energy:
            return p1, 0.0
        return p1, (half_w * (p * p - p1 * p1)).sum(axis=(-2, -1))

    return damp
