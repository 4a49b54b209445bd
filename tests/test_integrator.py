"""crgpr.physics.integrator: one Stormer-Verlet scheme, one divergence policy, every path alike."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from paper_rod import paper_rod

from crgpr.gp.evaluators import Table1D
from crgpr.physics.dissipation import kelvin_voigt_flow
from crgpr.physics.integrator import (
    MAX_SPEED,
    REACH,
    SimulationDiverged,
    diverged_nodes,
    run_generic,
    run_hamiltonian,
    run_verlet,
)
from crgpr.physics.momentum_maps import MomentumMaps
from crgpr.physics.params import SimSettings
from crgpr.physics.rod import free_mask, internal_forces, masses, node_weights, straight_rod
from crgpr.physics.simulate import dissipation_coefficients, kelvin_voigt_kick, simulate

P = paper_rod(N=8)
S = SimSettings(dt=1e-4, t_end=0.1, record_every=5, scheme="variational")


def _analytic():
    wds = node_weights(P.N) * P.ds
    mass = np.array([P.rhoA, P.rhoA, P.rhoI])
    gu = np.array([0.0, -P.rhoA * P.g, 0.0])
    return wds, mass, gu


@pytest.mark.parametrize("c", [0.0, 2e-4])
def test_generic_and_hamiltonian_forms_reproduce_the_compiled_rod_to_round_off(c):
    """The analytic rod by the compiled kernel (ground truth), by run_generic (velocities) and by
    run_hamiltonian (momenta per length, learned-H_z path) agree to round-off, with and without
    a Kelvin-Voigt bending damping c (then the rotational half-kicks are its exact flow in all
    three)."""
    rod = P.replace(internal_damping=c)
    ref = simulate(125.0, rod, S)
    m_t, m_r = masses(P)
    lam_t, lam_r, _ = dissipation_coefficients(P)

    def force(q):
        F, _ = internal_forces(q, P)
        F[:, 1] -= m_t * P.g
        return F

    gen = run_generic(ref.q[0], np.zeros_like(ref.q[0]), force, free_mask(P), m_t, m_r, lam_t, lam_r,
                      S.dt, S.n_steps, S.record_every, kv=kelvin_voigt_kick(rod, m_r, lam_r, S.dt))
    wds, mass, gu = _analytic()
    ham = run_hamiltonian(ref.q[0], np.zeros_like(ref.q[0]),
                          lambda q: internal_forces(q, P)[0] / wds[:, None] + gu, lambda p: p / mass,
                          free_mask(P), P.zeta, S.dt, S.n_steps, S.record_every, wds,
                          bending=(c, P.ds, 1.0 / P.rhoI) if c else None)
    scale_q = np.abs(ref.q).max()
    scale_p = np.abs(ref.p).max()
    assert np.abs(gen.q - ref.q).max() <= 1e-12 * scale_q
    assert np.abs(ham.q - ref.q).max() <= 1e-12 * scale_q
    assert np.abs(ham.v - ref.p).max() <= 1e-10 * scale_p
    assert np.abs(gen.dissipated - ref.dissipated).max() <= 1e-12 * max(ref.dissipated[-1], 1e-300)


def test_kelvin_voigt_flow_is_the_exact_affine_flow():
    """[P, Phi, Psi] of ``kelvin_voigt_flow`` are the exact solution of d omega/dt = a - A omega
    (a frozen) and its time integral, from the matrix exponential of the augmented system; the
    clamped base rate stays 0."""
    from scipy.linalg import expm

    m_t, m_r = masses(P)
    _, lam_r, _ = dissipation_coefficients(P)
    free = free_mask(P)[:, 2]
    c, h = 3e-4, 5e-5
    flow = kelvin_voigt_flow(c, P.ds, m_r, lam_r, free, h)
    n = m_r.size
    f = np.nonzero(free)[0]
    D = np.diff(np.eye(n), axis=0)
    A = ((c / P.ds) * D.T @ D / m_r[:, None] + np.diag(lam_r))[np.ix_(f, f)]
    k = f.size
    rng = np.random.default_rng(0)
    w0, a = rng.normal(size=k), rng.normal(size=k)
    # state (omega, integral of omega, 1): d/dt = (a - A omega, omega, 0)
    M = np.zeros((2 * k + 1, 2 * k + 1))
    M[:k, :k], M[:k, -1], M[k:2 * k, :k] = -A, a, np.eye(k)
    x = expm(M * h) @ np.r_[w0, np.zeros(k), 1.0]
    W0, Aa = np.zeros(n), np.zeros(n)
    W0[f], Aa[f] = w0, a
    np.testing.assert_allclose((flow[0] @ W0 + flow[1] @ Aa)[f], x[:k], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose((flow[1] @ W0 + flow[2] @ Aa)[f], x[k:2 * k], rtol=1e-9, atol=1e-16)
    assert np.all(flow[:, 0, :] == 0) and np.all(flow[:, :, 0] == 0)


def test_a_kelvin_voigt_rod_converges_at_second_order_in_the_step():
    """With the rotational half-kick as the exact affine flow, halving dt cuts the error against a
    16 times finer step by about four (a Strang split of so stiff a damping around the kick is
    first order: ``benchmarks/kv_step_convergence.csv``)."""
    rod = P.replace(internal_damping=2e-4)
    ref = simulate(85.0, rod, SimSettings(dt=S.dt / 16, t_end=0.3, record_every=80, scheme="variational"))
    err = []
    for k in (1, 2):
        st_k = SimSettings(dt=S.dt / k, t_end=0.3, record_every=5 * k, scheme="variational")
        tr = simulate(85.0, rod, st_k)
        err.append(np.abs(tr.q[..., 2] - ref.q[..., 2]).max())
    assert err[0] < 1e-3 and 3.0 < err[0] / err[1] < 5.0


def _two_releases(wds: np.ndarray, c: float) -> tuple[np.ndarray, np.ndarray, tuple | None]:
    """The free mask, two straight rods at 60 and 125 deg, and a Kelvin-Voigt bending damping c
    over half a step (None for c = 0)."""
    free = free_mask(P)
    q0 = np.stack([straight_rod(math.radians(a), P) for a in (60.0, 125.0)])
    if not c:
        return free, q0, None
    return free, q0, (c, P.ds, 1.0 / P.rhoI)


@pytest.mark.parametrize("c", [0.0, 2e-4])
def test_linear_momentum_map_damping_is_the_generic_flow(c):
    """run_hamiltonian with ``inverse_mass`` (the damping half-step as one precomputed linear map)
    gives the generic path's trajectory and dissipated energy to round-off, with and without a
    Kelvin-Voigt bending damping, for a batch of rods."""
    wds, mass, gu = _analytic()
    free, q0, bending = _two_releases(wds, c)

    def force(q):
        return np.stack([internal_forces(r, P)[0] for r in q]) / wds[:, None] + gu

    runs = [run_hamiltonian(q0, np.zeros_like(q0), force, lambda p: p / mass, free, 5 * P.zeta, S.dt,
                            S.n_steps, S.record_every, wds, bending=bending, inverse_mass=inv)
            for inv in (None, 1.0 / mass)]
    assert runs[0].dissipated[-1].min() > 0
    np.testing.assert_allclose(runs[1].q, runs[0].q, rtol=0, atol=1e-12 * np.abs(runs[0].q).max())
    np.testing.assert_allclose(runs[1].v, runs[0].v, rtol=0, atol=1e-10 * np.abs(runs[0].v).max())
    np.testing.assert_allclose(runs[1].dissipated, runs[0].dissipated, rtol=1e-9, atol=1e-18)


def _softening_map(stiffness: float, knee: float, span: float) -> Table1D:
    """A tabulated momentum map on [-span, span], nonlinear: stiffness x knee tanh(p / knee)."""
    x = np.linspace(-span, span, 41)
    return Table1D(x, stiffness * knee * np.tanh(x / knee))


@settings(max_examples=40, deadline=None)
@given(x=st.lists(st.floats(-3.0, 3.0, allow_nan=False), min_size=1, max_size=30))
def test_compiled_momentum_maps_are_the_tables_and_the_nominal_maps(x):
    """``MomentumMaps`` gives the values of ``Table1D`` (``np.interp``, 0 outside) and its slopes
    bit for bit, at the knots, between them and outside, and the nominal maps' products."""
    table = _softening_map(2.0, 1.0, 2.0)
    knots = np.r_[table.tx, np.asarray(x)]
    maps = MomentumMaps([3.0, (table.tx, table.ty), 0.5])
    p = np.stack([knots, knots, knots], axis=-1)[None]
    v = maps.velocity(p)
    assert np.array_equal(v[0, :, 1], table(knots))
    assert np.array_equal(v[0, :, 0], 3.0 * knots) and np.array_equal(v[0, :, 2], 0.5 * knots)
    from crgpr.physics.momentum_maps import _slope
    slopes = np.array([_slope(k, maps.xs, maps.ys, maps.offsets[1], maps.offsets[2], False, 0.0)
                       for k in knots])
    assert np.array_equal(slopes, table.slope(knots))


@pytest.mark.parametrize("c", [0.0, 2e-4])
def test_tabulated_momentum_map_damping_is_the_generic_flow(c):
    """run_hamiltonian with ``momentum_maps`` (the damping half-step in one compiled pass) gives the
    generic path's trajectory and dissipated energy to round-off for a tabulated, nonlinear
    momentum map of p_theta, with and without a Kelvin-Voigt bending damping, for a batch of
    rods."""
    wds, mass, gu = _analytic()
    free, q0, bending = _two_releases(wds, c)
    knee = 5e-7  # |p_theta| of these releases: up to about 2e-6 undamped, 6e-7 with the bending damping
    table = _softening_map(1.0 / P.rhoI, knee, 10 * knee)

    inv = 1.0 / mass  # the nominal maps as NominalLaw evaluates them: stiffness x p

    def velocity(p):
        return np.stack([inv[0] * p[..., 0], inv[1] * p[..., 1], table(p[..., 2])], axis=-1)

    def slope(p):
        return np.stack([np.full(p.shape[:-1], inv[0]), np.full(p.shape[:-1], inv[1]),
                         table.slope(p[..., 2])], axis=-1)

    def force(q):
        return np.stack([internal_forces(r, P)[0] for r in q]) / wds[:, None] + gu

    maps = MomentumMaps([inv[0], inv[1], (table.tx, table.ty)])
    assert np.array_equal(maps.velocity(q0), velocity(q0))
    runs = [run_hamiltonian(q0, np.zeros_like(q0), force, velocity, free, 5 * P.zeta, S.dt, S.n_steps,
                            S.record_every, wds, velocity_slope=slope, bending=bending, momentum_maps=m)
            for m in (None, maps)]
    assert runs[0].dissipated[-1].min() > 0 and np.abs(runs[0].v[..., 2]).max() > 0.5 * knee  # nonlinear
    np.testing.assert_allclose(runs[1].q, runs[0].q, rtol=0, atol=1e-12 * np.abs(runs[0].q).max())
    np.testing.assert_allclose(runs[1].v, runs[0].v, rtol=0, atol=1e-10 * np.abs(runs[0].v).max())
    np.testing.assert_allclose(runs[1].dissipated, runs[0].dissipated, rtol=1e-9, atol=1e-18)


def test_generic_form_without_pm_structure_is_the_same_scheme():
    """run_verlet with dq/dt = V(q, p), dp/dt = F(q, p) (the black box's form) gives exactly
    run_hamiltonian's trajectory when V happens to be p / m (no damping)."""
    wds, mass, gu = _analytic()
    q0 = straight_rod(math.radians(60.0), P)
    free = free_mask(P)

    def force(q):
        return internal_forces(q, P)[0] / wds[:, None] + gu

    ham = run_hamiltonian(q0, np.zeros_like(q0), force, lambda p: p / mass, free, 0.0, S.dt,
                          S.n_steps, S.record_every, wds)
    gen = run_verlet(q0, np.zeros_like(q0), lambda q, p: force(q), lambda q, p: p / mass, free,
                     S.dt, S.n_steps, S.record_every)
    np.testing.assert_array_equal(gen.q, ham.q)
    np.testing.assert_array_equal(gen.v, ham.v)


def test_policy_flags_non_finite_fast_and_far_nodes():
    q = straight_rod(0.0, P)
    v = np.zeros_like(q)
    base = q[0, :2]
    assert not diverged_nodes(q, v, base, REACH * P.L0).any()
    v[2, 2] = MAX_SPEED
    q[4, 1] = np.nan
    q[6, 0] = REACH * P.L0 * 1.0001
    assert np.nonzero(diverged_nodes(q, v, base, REACH * P.L0))[0].tolist() == [2, 4, 6]


@pytest.mark.parametrize("path", ["compiled", "hamiltonian", "verlet"])
def test_every_path_stops_at_the_same_bound_and_keeps_the_good_records(path):
    """A rod whose tip is pushed away: each path raises SimulationDiverged at the first record
    beyond the reach bound, reports the tip, and hands back the records before it."""
    wds, mass, gu = _analytic()
    q0 = straight_rod(0.0, P)
    free = free_mask(P)
    push = np.zeros((P.N + 1, 3))
    push[-1, 0] = 200.0  # [N/m] per length at the tip only: pulls it off, speed stays < MAX_SPEED
    n_steps = 40000
    with pytest.raises(SimulationDiverged) as info:
        if path == "compiled":  # a very soft rod whose tip is thrown outwards at 30 m/s
            v0 = np.zeros_like(q0)
            v0[-1, 0] = 30.0
            simulate(0.0, paper_rod(N=8, E=1.0, zeta=0.0), SimSettings(dt=1e-4, t_end=n_steps * 1e-4,
                                                                       record_every=5, scheme="variational"),
                     v0=v0)
        elif path == "hamiltonian":
            run_hamiltonian(q0, np.zeros_like(q0), lambda q: push + gu * 0.0, lambda p: p / mass, free,
                            0.0, 1e-4, n_steps, 5, wds)
        else:
            run_verlet(q0, np.zeros_like(q0), lambda q, p: push, lambda q, p: p / mass, free, 1e-4,
                       n_steps, 5)
    exc = info.value
    assert exc.node == P.N and 0 < exc.t < n_steps * 1e-4
    part = exc.partial
    assert part is not None and part.q.shape[0] == exc.step // 5
    reach = np.hypot(part.q[..., 0] - q0[0, 0], part.q[..., 1] - q0[0, 1])
    assert reach.max() <= REACH * P.L0 * (1 + 1e-12) and np.isfinite(part.q).all()


# --------------------------------------------------------------------------------------------
# tangent-linear records (the discovery fits' exact initial-state sensitivities)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("effects", [
    {}, {"viscous_drag": 0.04, "air_drag": 0.04}, {"internal_damping": 5e-5, "tip_mass": 0.01},
    {"nonlinear_stiffness": 0.01, "kappa0": 1.0, "stiffness_gradient": 0.5, "base_spring": 0.5},
])
def test_tangent_records_are_the_derivative_of_the_discrete_rollout(effects):
    """run_rod's tangent directions are the exact derivative of the discrete trajectory with
    respect to the initial state (central differences agree to ~1e-7, i.e. to their own
    truncation error, for every dissipative and conservative term: the exact flows of viscous,
    quadratic and Kelvin-Voigt damping, a tip mass, a base spring whose rest angle is the
    initial base angle), and the rollout itself is the same to the last bit with or without
    them."""
    pr = P.replace(**effects)
    st = SimSettings(dt=1e-4, t_end=0.2, record_every=20, scheme="variational")
    q0 = straight_rod(math.radians(85.0), pr)
    v0 = np.zeros_like(q0)
    v0[:, 2] = 0.5 * pr.s / pr.L0
    v0[1:, 0] = -0.3 * pr.s[1:]
    rng = np.random.default_rng(3)
    dq = 1e-2 * rng.standard_normal((3, pr.N + 1, 3))
    dq[:, 0, :2] = 0.0
    dv = 1e-1 * rng.standard_normal((3, pr.N + 1, 3))
    tr = simulate(85.0, pr, st, q0=q0, v0=v0, dq0=dq, dv0=dv)
    plain = simulate(85.0, pr, st, q0=q0, v0=v0)
    assert np.array_equal(tr.q, plain.q) and np.array_equal(tr.p, plain.p)
    assert tr.dq.shape == (tr.q.shape[0], 3, pr.N + 1, 3) and plain.dq is None
    eps = 1e-6
    for a in range(3):
        fp = simulate(85.0, pr, st, q0=q0 + eps * dq[a], v0=v0 + eps * dv[a]).q
        fm = simulate(85.0, pr, st, q0=q0 - eps * dq[a], v0=v0 - eps * dv[a]).q
        fd = (fp - fm) / (2 * eps)
        assert np.abs(fd - tr.dq[:, a]).max() <= 1e-6 * np.abs(fd).max()


def test_tangent_directions_need_the_variational_scheme():
    st = SimSettings(dt=1e-4, t_end=0.01, record_every=10, scheme="collocated")
    with pytest.raises(ValueError, match="variational"):
        simulate(85.0, P, st, dq0=np.zeros((1, P.N + 1, 3)))
