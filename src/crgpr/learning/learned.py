"""Step 4: the learned CR-GPR model H_z_hat and its rollouts (paper Sec. III-B step 4, eq. (17)).

    dz/dt = (J - R) H_z_hat(z) + G u

integrated with the ground truth's Strang-split Stormer-Verlet scheme and time step
(integrator.run_hamiltonian), clamped base, free tip, released straight at rest.

Methods (config ``rollouts.methods``):
* ``cr_gpr`` / ``cr_gpr_fd``: the paper's six GPs (features 'paper', prefilter gp / fd):
  nodal forces -dH/dx_i = (q_x,i - q_x,i-1) / (w_i ds) from the segment GPs q_x, q_y
  (q_N = 0: free tip), -dH/dtheta_i from GPR 3, dq/dt = H_p(p) from GPR 4-6;
* ``cr_gpr_objective``: local resultants n1, n2, m from frame-indifferent strains, rotated
  back (q_x = n1 cos theta_bar - n2 sin theta_bar, ...), and the discrete moment balance
  -dH/dtheta_i = (m_i - m_{i-1} + ds/2 (c_i + c_{i-1})) / (w_i ds), c = nu1 n2 - nu2 n1.
The GP means are evaluated by the evaluators of the saved models (``crgpr.gp.load_evaluator``:
the exact posterior mean over all n points with truncated kernel sums, or the DTC mean, and the
1-D tables, whose error against the dense exact mean gradient_models.py measured).
``cr_gpr_paper_hyp``: the paper's model with Table II's hyperparameters (``hyperparameters:
paper_table2``, models in ``results/models/{prefilter}_paper_hyp``).

Energy of the learned model: E(t) = H_z_hat^T R H_z_hat = zeta sum_i w_i ds |H_p_hat|^2 (the
dissipated power, paper Fig. 5), plus sum_j ds c (dkappa_j/dt)^2 of a learned bending damping
c >= 0 (``learning.damping``, ``physics.dissipation``; dkappa/dt from H_p_theta). The learned
force field -H_q_hat need not be a gradient (the GPs are independent), so the learned stored
energy is the path integral along the rollout,
H_hat(t) = int H_z_hat . dz, which obeys dH_hat/dt = -E + y^T u exactly because J is skew
(eq. (7)). ``learned_energy`` books it with the integrator's own steps: the work of -H_q_hat +
gravity along every drift (``Integration.force_work``), the kinetic energy int_0^p H_p_hat as a
function of the state, less the scheme's half-step term (h^2 / 2) sum_i w_i ds f . s F (f the
force, F = f + G u, s = dH_p/dp, h = dt/2; what makes the kick-drift-kick update conserve it).
With the damping booked exactly (``run_hamiltonian``), the balance residual
H_hat(t) - H_hat(0) + dissipated(t) - input_work(t) is integrator round-off for an affine
H_p (the tables' pieces), whatever the force field.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from crgpr.config import ConfigError, rod_params, sim_settings
from crgpr.gp.evaluators import load_evaluator
from crgpr.io import write_parquet
from crgpr.learning import features as ft
from crgpr.learning.gradient_models import MOMENTUM_MODELS
from crgpr.learning.nominal import NominalLaw
from crgpr.physics.dissipation import bending_power
from crgpr.physics.integrator import SimulationDiverged, rod_length, run_hamiltonian
from crgpr.physics.momentum_maps import MomentumMaps
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import Ports
from crgpr.physics.rod import free_mask, node_weights, straight_rod
from crgpr.physics.signals import Inputs
from crgpr.physics.simulate import Trajectory, trajectory_frame

log = logging.getLogger(__name__)

PAPER_COMPONENTS = ("q_x", "q_y", "dH_dtheta")
OBJECTIVE_COMPONENTS = ("obj_n1", "obj_n2", "obj_m")


class Component(Protocol):
    """One learned scalar function of a feature matrix (a GP mean, a posterior sample, an oracle).

    ``__call__(X)``: values at feature rows X (..., d) -> (...); momentum components
    (1-D input) also provide ``slope(x)``, dH_p/dp, for the exact damping flow.
    """

    def __call__(self, X: np.ndarray) -> np.ndarray: ...


class LearnedRod:
    """The learned H_z_hat of eq. (17) (paper Sec. III-B, step 4), assembled from components.

    The protocol every learned rod implements, and the only one the integrator sees:
    ``force(q)`` = -H_q_hat + G u and ``velocity(p)`` = H_p_hat per unit length, and
    ``velocity_slope(p)`` = dH_p_hat/dp. ``components`` maps names to evaluators:
    ``q_x, q_y, dH_dtheta`` (features 'paper') or ``obj_n1, obj_n2, obj_m`` (features
    'objective'), plus ``dH_dp_x, dH_dp_y, dH_dp_theta``. Any evaluator works: compiled GP
    means (``from_dir``), posterior samples, analytic oracles. States may carry leading batch
    axes (..., N+1, 3) when the components do. ``damping``: the learned Kelvin-Voigt bending
    damping c >= 0 [N m^2 s] (m_d = c dkappa/dt on every segment, part of R, not of H_z;
    ``learning.damping``); 0: the nominal R = zeta I alone.
    """

    def __init__(self, components: Mapping[str, Component], features: str, params: RodParams,
                 theta_center: float | None = None, damping: float = 0.0):
        names = {"paper": PAPER_COMPONENTS, "objective": OBJECTIVE_COMPONENTS}.get(features)
        if names is None:
            raise ConfigError(f"unknown feature set {features!r}; expected 'paper' or 'objective'")
        missing = [m for m in (*names, *MOMENTUM_MODELS) if m not in components]
        if missing:
            raise ValueError(f"learned rod ({features} features) lacks component(s) {missing}")
        self.features = features
        self.params = params
        self.components = dict(components)
        self.center = theta_center
        self.wds = node_weights(params.N) * params.ds
        self.hp = [self.components[m] for m in MOMENTUM_MODELS]
        # the nominal momentum maps H_p = p / (rho A), p / (rho I) (camera models): one product
        self.inv_mass = (np.array([h.stiffness for h in self.hp])
                         if all(isinstance(h, NominalLaw) for h in self.hp) else None)
        # else, where each map is a table or linear (a learned map tabulated): compiled evaluation
        self.maps = MomentumMaps.of(self.hp) if self.inv_mass is None else None
        self.gu = np.array([0.0, -params.rhoA * params.g, 0.0])
        if not (math.isfinite(damping) and damping >= 0):
            raise ValueError(f"learned bending damping c = {damping!r}: must be finite and >= 0")
        self.damping = float(damping)

    @classmethod
    def from_dir(cls, model_dir: str | Path, features: str, params: RodParams,
                 momentum_dir: str | Path | None = None) -> LearnedRod:
        """The rollout approximations of the models saved in ``model_dir`` (step 3 output)."""
        model_dir = Path(model_dir)
        momentum_dir = Path(momentum_dir) if momentum_dir else model_dir
        names = {"paper": PAPER_COMPONENTS, "objective": OBJECTIVE_COMPONENTS}.get(features)
        if names is None:
            raise ConfigError(f"unknown feature set {features!r}; expected 'paper' or 'objective'")
        comps: dict[str, Component] = {m: load_evaluator(momentum_dir / m) for m in MOMENTUM_MODELS}
        comps.update({m: load_evaluator(model_dir / m) for m in names})
        center = None
        if features == "paper":
            center = comps["q_x"].meta.get("theta_center")
            c2 = comps["dH_dtheta"].meta.get("theta_center")
            if (center is None) != (c2 is None) or (c2 is not None and abs(c2 - center) > 1e-12):
                raise ValueError(f"{model_dir}: q_x and dH_dtheta were trained with different theta windows")
        return cls(comps, features, params, center)

    def internal(self, q: np.ndarray) -> np.ndarray:
        """-H_q_hat per unit length at every node (..., N+1, 3) for configurations q (..., N+1, 3)."""
        P = self.params
        c = self.components
        if self.features == "objective":
            table = ft.segment_table(q, P.ds)
            Xn, Xm = ft.objective_inputs(table)
            n1, n2, m = c["obj_n1"](Xn), c["obj_n2"](Xn), c["obj_m"](Xm)
            return ft.objective_forces(n1, n2, m, table, self.wds, P.ds)
        x, y, th = q[..., 0], q[..., 1], q[..., 2]
        out = np.zeros(q.shape)
        Xq = ft.paper_q_features(x, y, th, P.ds, self.center)
        out[..., 0] = ft.forces_from_q(c["q_x"](Xq), P)
        out[..., 1] = ft.forces_from_q(c["q_y"](Xq), P)
        out[..., 1:, 2] = -c["dH_dtheta"](ft.paper_theta_features(x, y, th, P.ds, self.center))
        return out

    def force(self, q: np.ndarray) -> np.ndarray:
        return self.internal(q) + self.gu

    def velocity(self, p: np.ndarray) -> np.ndarray:
        if self.inv_mass is not None:
            return self.inv_mass * np.asarray(p, dtype=float)
        if self.maps is not None:
            return self.maps.velocity(p)
        out = np.empty(p.shape)
        for k in range(3):
            out[..., k] = self.hp[k](p[..., k])
        return out

    def velocity_slope(self, p: np.ndarray) -> np.ndarray:
        if self.inv_mass is not None:
            return np.broadcast_to(self.inv_mass, p.shape)
        out = np.empty(p.shape)
        for k in range(3):
            out[..., k] = self.hp[k].slope(p[..., k])
        return out

    def bending(self) -> tuple[float, float, float] | None:
        """``run_hamiltonian``'s ``bending`` argument: (c, ds, mu), the learned Kelvin-Voigt c
        for H_p_theta = mu p_theta (mu the rotational map's slope at rest); None without
        learned damping."""
        if self.damping == 0.0:
            return None
        mu = float(np.mean(self.velocity_slope(np.zeros((self.params.N + 1, 3)))[..., 2]))
        return self.damping, self.params.ds, mu

    def dissipation_rate(self, p: np.ndarray) -> np.ndarray:
        """E = H_z^T R H_z (...) [W] at momenta p (..., N+1, 3): zeta sum_i w_i ds |H_p,i|^2 over the
        free degrees of freedom plus the learned bending damping's sum_j ds c (dkappa_j/dt)^2."""
        free = free_mask(self.params)
        hp = self.velocity(p) * free
        rate = self.params.zeta * (self.wds[:, None] * hp**2).sum(axis=(-2, -1))
        if self.damping:
            rate = rate + bending_power(hp[..., 2], self.damping, self.params.ds)
        return rate

    def hz(self, q: np.ndarray, p: np.ndarray) -> np.ndarray:
        """H_z_hat (..., N+1, 6) per unit length."""
        return np.concatenate([-self.internal(q), self.velocity(p)], axis=-1)


def rollout(model: LearnedRod, theta0_deg: float, settings: SimSettings, what: str = "rollout",
            n_batch: int | None = None, inputs: Inputs | None = None, ports: Ports | None = None,
            initial: tuple[np.ndarray, np.ndarray, float] | None = None, book_energy: bool = True
            ) -> Trajectory:
    """Integrate the learned dPHS from the straight rod at rest (same scheme and dt as ground truth).

    ``n_batch``: integrate that many copies at once (a model whose components carry a leading
    batch axis, e.g. posterior samples); q and p are then (n_t, n_batch, N+1, 3).
    ``inputs`` drive the ``ports`` (G(z) u of ``physics.ports``, the simulator's G, added to the
    model's gravity per unit length at every step time); their work is ``input_work``.
    ``initial`` = (q0, p0, t0): start from that state (p per length) at time t0 [s] instead of
    the straight rod at rest (the inputs are then read from t0 on, and t starts at t0); with
    ``n_batch``, q0 and p0 may carry the batch axis (one start per rod). ``book_energy`` False:
    the states only (``run_hamiltonian``: no force work, no dissipation booked for a linear
    momentum map), for fits that compare states.
    """
    P = model.params
    if initial is None:
        q0, p0, t0 = straight_rod(math.radians(theta0_deg), P), None, 0.0
    else:
        q0, p0, t0 = np.array(initial[0], dtype=float), np.array(initial[1], dtype=float), float(initial[2])
    if n_batch is not None and q0.ndim == 2:
        q0 = np.repeat(q0[None], n_batch, axis=0)
        p0 = None if p0 is None else np.repeat(p0[None], n_batch, axis=0)
    port = None
    if inputs is not None:
        if ports is None:
            raise ValueError("inputs need the ports (channels' G) they drive")
        u = inputs.values(t0 + np.arange(settings.n_steps + 1) * settings.dt)
        inv_wds = 1.0 / model.wds[:, None]

        def port(k: int, q: np.ndarray) -> np.ndarray:
            return ports.nodal_forces(q, np.broadcast_to(u[k], (*q.shape[:-2], u.shape[1]))) * inv_wds
    out = run_hamiltonian(q0, np.zeros_like(q0) if p0 is None else p0, model.force, model.velocity,
                          free_mask(P), P.zeta, settings.dt, settings.n_steps, settings.record_every,
                          model.wds, what, velocity_slope=model.velocity_slope, port=port,
                          bending=model.bending(), inverse_mass=model.inv_mass,
                          momentum_maps=model.maps, book_energy=book_energy)
    return Trajectory(float(theta0_deg), out.t + t0, out.q, out.v, P, out.dissipated,
                      input_work=out.input_work,
                      u=None if inputs is None else u[::settings.record_every], ports=ports,
                      force_work=out.force_work)


def record_settings(settings: SimSettings, t: np.ndarray) -> SimSettings:
    """``settings``' step and scheme over a record's frame times t (n_t,): from t[0] to t[-1],
    recording every frame interval (its smallest, in steps)."""
    return replace(settings, t_end=float(t[-1] - t[0]),
                   record_every=max(1, int(round(float(np.min(np.diff(t))) / settings.dt))))


def free_angles_at(tr: Trajectory, t: np.ndarray) -> np.ndarray:
    """theta of the free nodes 1..N of a rollout linearly interpolated to the times t:
    (n_t, ..., N) for states q (n_rec, ..., N+1, 3) (a batch keeps its axis)."""
    th = tr.q[..., 1:, 2]
    flat = th.reshape(th.shape[0], -1)
    out = np.stack([np.interp(t, tr.t, flat[:, j]) for j in range(flat.shape[1])], axis=-1)
    return out.reshape(t.size, *th.shape[1:])


def antiderivative(comp: Component, x: np.ndarray) -> np.ndarray:
    """int_0^x comp(s) ds elementwise: exact for a 1-D table (``tx``, ``ty``: linear
    interpolation, 0 outside the grid), an 8-point Gauss-Legendre rule otherwise."""
    x = np.asarray(x, dtype=float)
    if hasattr(comp, "tx"):
        tx, ty = comp.tx, comp.ty
        F = np.concatenate([[0.0], np.cumsum(0.5 * (ty[1:] + ty[:-1]) * np.diff(tx))])
        slope = np.diff(ty) / np.diff(tx)

        def prim(v: np.ndarray) -> np.ndarray:
            vc = np.clip(v, tx[0], tx[-1])
            i = np.clip(np.searchsorted(tx, vc, side="right") - 1, 0, tx.size - 2)
            d = vc - tx[i]
            return F[i] + d * (ty[i] + 0.5 * d * slope[i])

        return prim(x) - prim(np.zeros_like(x))
    nodes, weights = np.polynomial.legendre.leggauss(8)
    return 0.5 * x * sum(w * comp(0.5 * x * (1.0 + n)) for n, w in zip(nodes, weights, strict=True))


def kinetic_energy(model: LearnedRod, p: np.ndarray) -> np.ndarray:
    """The learned kinetic energy sum_i w_i ds sum_k int_0^p_ik H_p,k (..., N+1, 3) -> (...)."""
    free = free_mask(model.params)
    K = np.stack([antiderivative(model.hp[k], p[..., k]) for k in range(3)], axis=-1)
    return (model.wds[:, None] * K * free).sum(axis=(-2, -1))


def learned_energy(model: LearnedRod, traj: Trajectory, dt: float) -> pd.DataFrame:
    """Dissipated power E(t) = H_z^T R H_z of the learned model and its energy balance (module
    doc): ``H_learned`` = the path energy of the drifts (minus ``traj.force_work``) + the
    kinetic energy - the half-step term; ``dissipated`` and ``input_work`` are the integrator's
    bookings; ``balance_residual`` = H_learned(t) - H_learned(0) + dissipated - input_work.
    ``dt``: the rollout's step [s]."""
    if traj.force_work is None:
        raise ValueError("learned_energy needs the rollout's force work (learning.learned.rollout)")
    P = model.params
    free = free_mask(P)
    q, p = traj.q, traj.p
    rate = model.dissipation_rate(p)
    f = model.force(q) * free
    F = f
    if traj.input_work is not None:
        F = f + traj.ports.nodal_forces(q, traj.u) / model.wds[:, None] * free
    half = 0.125 * dt**2 * (model.wds[:, None] * f * model.velocity_slope(p) * F).sum(axis=(-2, -1))
    kinetic = kinetic_energy(model, p) - half
    U_g = P.rhoA * P.g * (model.wds * q[..., 1]).sum(axis=-1)
    potential = -traj.force_work  # elastic path energy + gravity, relative to t = t0
    total = potential + U_g[0] + kinetic
    work = np.zeros_like(total) if traj.input_work is None else traj.input_work
    df = pd.DataFrame({"t": traj.t, "dissipation_rate": rate, "dissipated": traj.dissipated,
                       "H_learned": total, "stored_learned": potential - (U_g - U_g[0]),
                       "kinetic_learned": kinetic, "gravity": U_g,
                       "balance_residual": total - total[0] + traj.dissipated - work})
    if traj.input_work is not None:  # actuated: the port work of the integrator's kicks [J]
        df["input_work"] = traj.input_work
    return df


def method_spec(cfg: dict[str, Any], method: str) -> dict[str, str]:
    methods = cfg["rollouts"]["methods"]
    if method not in methods:
        raise ConfigError(f"rollouts.methods: unknown method {method!r}; configured: {sorted(methods)}")
    return methods[method]


def model_dir_name(method_cfg: dict[str, str]) -> str:
    """Folder (under results/models) of a method's gradient models: ``{prefilter}`` for fitted
    hyperparameters, ``{prefilter}_paper_hyp`` for the paper's Table II values."""
    hyp = method_cfg["hyperparameters"]
    if hyp == "fitted":
        return method_cfg["prefilter"]
    if hyp == "paper_table2" and method_cfg["features"] == "paper":
        return f"{method_cfg['prefilter']}_paper_hyp"
    raise ConfigError(f"rollouts.methods: hyperparameters {hyp!r} with features "
                      f"{method_cfg['features']!r}; Table II exists for the paper's features only")


def model_files(results: str, method_cfg: dict[str, str]) -> list[str]:
    """Model JSON paths a method needs (for the Snakemake rule)."""
    d = model_dir_name(method_cfg)
    if method_cfg["features"] == "paper":
        names = ["q_x", "q_y", "dH_dtheta", *MOMENTUM_MODELS]
        return [f"{results}/models/{d}/{n}.json" for n in names]
    return ([f"{results}/models/{d}/{n}.json" for n in ("obj_n1", "obj_n2", "obj_m")]
            + [f"{results}/models/{d}/{n}.json" for n in MOMENTUM_MODELS])


def needed_model_jsons(results: str, methods: dict[str, dict[str, str]]) -> list[str]:
    """Model JSON paths used by the configured rollout methods (gp prefilter first, no duplicates)."""
    out: list[str] = []
    for spec in methods.values():
        for f in model_files(results, spec):
            if f not in out:
                out.append(f)
    return sorted(out, key=lambda f: (f.split("/")[-2] != "gp", f))


def frozen_after_divergence(part: Trajectory, settings: SimSettings) -> Trajectory:
    """The rollout's one divergence policy: the records before the divergence, the last of them
    held for the rest of the simulated time (a bounded, conservative error for the metrics)."""
    n_rec = settings.n_steps // settings.record_every + 1
    r = part.q.shape[0]
    t = np.arange(n_rec) * settings.dt * settings.record_every
    q = np.concatenate([part.q, np.repeat(part.q[-1:], n_rec - r, axis=0)])
    p = np.concatenate([part.p, np.repeat(part.p[-1:], n_rec - r, axis=0)])
    return Trajectory(part.theta0_deg, t, q, p, part.params)


@dataclass
class MemberRun:
    """One rod of a batched rollout: its records (t, q, p, integrator's dissipated energy) up to
    the end of the run or, if it left the physical range, up to its last good record
    (``diverged``: t_s, step and node of the integrator's verdict)."""

    t: np.ndarray
    q: np.ndarray
    p: np.ndarray
    dissipated: np.ndarray
    force_work: np.ndarray
    diverged: dict[str, Any] | None = None


def rollout_members(model_for: Callable[[np.ndarray], LearnedRod], q0: np.ndarray, keys: np.ndarray,
                    params: RodParams, settings: SimSettings, what: str, inputs: Inputs | None = None,
                    ports: Ports | None = None) -> list[MemberRun]:
    """Integrate B rods as one batch from rest at the configurations q0 (B, N+1, 3) (eq. (17),
    the ground truth's scheme, dt and boundary conditions); rod b is driven by member b of
    ``model_for(keys[alive])`` (a mean model for every rod, or posterior sample keys[b]). Rods
    are independent: each gets the numbers it gets alone. A rod that leaves the physical range
    is taken out with its records up to the last good one; the others resume from that record
    (the scheme's full state, so bit for bit the uninterrupted run), no restart from t = 0.
    ``inputs`` drive the ``ports`` of every rod alike, as in ``rollout``."""
    P = params
    u = None
    if inputs is not None:
        if ports is None:
            raise ValueError("inputs need the ports (channels' G) they drive")
        u = inputs.values(np.arange(settings.n_steps + 1) * settings.dt)

    def port_from(k0: int) -> Callable[[int, np.ndarray], np.ndarray] | None:
        if u is None:
            return None
        inv_wds = 1.0 / (node_weights(P.N) * P.ds)[:, None]

        def port(k: int, q: np.ndarray) -> np.ndarray:
            return ports.nodal_forces(q, np.broadcast_to(u[k0 + k], (*q.shape[:-2], u.shape[1]))) * inv_wds
        return port
    B = q0.shape[0]
    alive = np.arange(B)
    q, p = np.array(q0, dtype=float), np.zeros_like(q0, dtype=float)
    length = rod_length(q)
    dt, every = settings.dt, settings.record_every
    k0, n_left = 0, settings.n_steps
    diss0 = np.zeros(B)
    work0 = np.zeros(B)
    pieces: list[tuple[np.ndarray, Any]] = []
    div: dict[int, dict[str, Any]] = {}
    while len(alive):
        rod = model_for(keys[alive])
        try:
            out = run_hamiltonian(q, p, rod.force, rod.velocity, free_mask(P), P.zeta, dt, n_left, every,
                                  rod.wds, what, velocity_slope=rod.velocity_slope, length=length,
                                  port=port_from(k0), bending=rod.bending())
        except SimulationDiverged as exc:
            part = exc.partial
            if exc.members is None or len(exc.members) == 0 or part is None or len(part.t) == 0:
                raise
            pieces.append((alive.copy(), part, k0, diss0[alive].copy(), work0[alive].copy()))
            bad = np.unique(exc.members[:, 0])
            for j in bad:
                div[int(alive[j])] = {"t_s": float(exc.t) + k0 * dt, "step": int(exc.step) + k0,
                                      "node": int(exc.node)}
            good = np.setdiff1d(np.arange(len(alive)), bad)
            r = len(part.t) - 1
            q, p = part.q[r][good], part.v[r][good]
            diss0[alive[good]] += part.dissipated[r][good]
            work0[alive[good]] += part.force_work[r][good]
            alive = alive[good]
            k0 += r * every
            n_left -= r * every
            continue
        pieces.append((alive.copy(), out, k0, diss0[alive].copy(), work0[alive].copy()))
        break
    runs = []
    for b in range(B):
        mine = [(int(np.flatnonzero(mem == b)[0]), pc, k, d0, w0)
                for mem, pc, k, d0, w0 in pieces if b in mem]
        # a resume record is the next piece's first: every piece but the member's last loses it
        cuts = [len(pc.t) - 1 for _, pc, _, _, _ in mine[:-1]] + [len(mine[-1][1].t)]
        parts = list(zip(mine, cuts, strict=True))
        runs.append(MemberRun(
            t=np.concatenate([pc.t[:c] + k * dt for (_, pc, k, _, _), c in parts]),
            q=np.concatenate([pc.q[:c, j] for (j, pc, _, _, _), c in parts]),
            p=np.concatenate([pc.v[:c, j] for (j, pc, _, _, _), c in parts]),
            dissipated=np.concatenate([pc.dissipated[:c, j] + d0[j] for (j, pc, _, d0, _), c in parts]),
            force_work=np.concatenate([pc.force_work[:c, j] + w0[j] for (j, pc, _, _, w0), c in parts]),
            diverged=div.get(b)))
    return runs


def run_rollout(cfg: dict[str, Any], method: str, angle: float, model_dir: str | Path, out: str | Path,
                energy_out: str | Path | None = None) -> Trajectory:
    """``run_rollouts`` at one angle; returns the written trajectory."""
    return run_rollouts(cfg, method, [angle], model_dir, [out], [energy_out])[0]


def run_rollouts(cfg: dict[str, Any], method: str, angles: Sequence[float], model_dir: str | Path,
                 outs: Sequence[str | Path], energy_outs: Sequence[str | Path | None]) -> list[Trajectory]:
    """Roll one method out at every angle (eq. (17)), all angles as one batch
    (``rollout_members``), and write one file per angle; returns the written trajectories.

    A rollout that diverges (``SimulationDiverged``, the integrator's plausibility check) is a
    result, not an error: the file holds ``frozen_after_divergence`` of it, with ``diverged``,
    ``t_diverged``, ``node_diverged`` and ``step_diverged`` in its metadata (the metrics report
    them), and the energy file covers the records before the divergence.
    """
    spec = method_spec(cfg, method)
    params, settings = rod_params(cfg), sim_settings(cfg)
    model = LearnedRod.from_dir(model_dir, spec["features"], params)
    t0 = time.perf_counter()
    q0 = np.stack([straight_rod(math.radians(a), params) for a in angles])
    what = f"{method} rollout at theta0 = {', '.join(f'{a:g}' for a in angles)} deg"
    runs = rollout_members(lambda keys: model, q0, np.arange(len(angles)), params, settings, what)
    secs = time.perf_counter() - t0
    trajs = []
    for angle, run, out, energy_out in zip(angles, runs, outs, energy_outs, strict=True):
        meta: dict[str, Any] = {"kind": "rollout", "method": method, "theta0_deg": angle,
                                "features": spec["features"], "prefilter": spec["prefilter"],
                                "model_dir": str(model_dir), "rod": params.to_dict(),
                                "simulation": settings.to_dict(), "diverged": False,
                                "seconds": secs / len(angles), "seconds_batch": secs,
                                "batch_angles": [float(a) for a in angles]}
        traj = before = Trajectory(float(angle), run.t, run.q, run.p, params, run.dissipated,
                                   force_work=run.force_work)
        if run.diverged is not None:
            log.warning("%s at %g deg left the physical range at t = %.4g s (node %d)", method, angle,
                        run.diverged["t_s"], run.diverged["node"])
            traj = frozen_after_divergence(before, settings)
            meta.update(diverged=True, t_diverged=run.diverged["t_s"], node_diverged=run.diverged["node"],
                        step_diverged=run.diverged["step"])
        log.info("%s at %g deg%s", method, angle,
                 f", diverged at t = {meta['t_diverged']:.4g} s" if meta["diverged"] else "")
        write_parquet(trajectory_frame(traj), out, meta)
        if energy_out is not None:
            write_parquet(learned_energy(model, before, settings.dt), energy_out,
                          {**meta, "kind": "rollout_energy"})
        trajs.append(traj)
    log.info("%s: %d angles in %.1f s", method, len(angles), secs)
    return trajs
