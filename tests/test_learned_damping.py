"""A learned passive bending damping m_d = c dkappa/dt, c >= 0 (crgpr.learning.damping): the
fit and its held-out decision, R >= 0 for every state, the learned rollout's exact flow and the
learned model's energy balance (paper eqs. (7)-(9): dz/dt = (J - R) dH/dz + G u)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from paper_rod import paper_rod

from crgpr.learning import features as ft
from crgpr.learning.damping import (
    curvature_rates,
    damping_torques,
    fit_bending_damping,
    golden_log_search,
    learn_bending_damping,
    refine_by_rollout,
)
from crgpr.learning.learned import LearnedRod, learned_energy, rollout
from crgpr.learning.nominal import NominalLaw
from crgpr.learning.oracle import oracle_components
from crgpr.physics.dissipation import bending_power, kelvin_voigt_flow, kv_flow_step
from crgpr.physics.params import SimSettings
from crgpr.physics.ports import Ports
from crgpr.physics.rod import free_mask, node_weights
from crgpr.physics.signals import SignalInputs
from crgpr.physics.simulate import simulate

C_KV = 5.0e-5  # [N m^2 s]: c / EI = 0.034 s for the paper's rod
GRID = SimSettings(dt=1.0e-4, t_end=0.5, record_every=5, scheme="variational")


class _Bending:
    """The exact linear bending law m = EI (kappa - kappa0) at objective m features."""

    def __init__(self, params):
        self.EI, self.k0 = params.EI, params.kappa0

    def __call__(self, X):
        return self.EI * (np.asarray(X)[..., 0] - self.k0)


def exact_rod(params, damping: float = 0.0) -> LearnedRod:
    """The paper's linear rod written as a learned rod (objective features, exact laws)."""
    comps = {"obj_n1": NominalLaw("n1", params), "obj_n2": NominalLaw("n2", params),
             "obj_m": _Bending(params)}
    comps.update({m: c for m, c in oracle_components(params).items() if m.startswith("dH_dp")})
    return LearnedRod(comps, "objective", params, damping=damping)


def _law_samples(c: float, n_t: int = 400, n_seg: int = 8, noise: float = 2e-5, seed: int = 0):
    """Time-major samples of m = EI kappa (1 + 0.2 kappa^2) + c dkappa/dt of a decaying oscillation
    (several cycles, a different amplitude and phase per segment) with Gaussian target noise."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n_t)[:, None]
    amp, ph = rng.uniform(1.0, 3.0, n_seg), rng.uniform(0, 2 * np.pi, n_seg)
    w, lam = 2 * np.pi * 2.5, 0.8
    kappa = amp * np.exp(-lam * t) * np.cos(w * t + ph)
    kdot = amp * np.exp(-lam * t) * (-lam * np.cos(w * t + ph) - w * np.sin(w * t + ph))
    EI = 1.47e-3
    m = EI * kappa * (1 + 0.2 * kappa**2) + c * kdot + noise * rng.standard_normal(kappa.shape)
    seg = np.broadcast_to(np.arange(n_seg), kappa.shape)
    return kappa.ravel(), kdot.ravel(), m.ravel(), seg.ravel()


# --- the fit and the decision --------------------------------------------------------------------
def test_damping_of_a_viscoelastic_law_is_kept_and_recovered_within_its_band():
    fit = fit_bending_damping(*_law_samples(C_KV), degree=3, blocks=10)
    assert fit.kept and fit.coefficient == fit.c_fit
    assert fit.band_lo <= C_KV <= fit.band_hi
    assert fit.heldout_mse_damped < fit.heldout_mse_elastic


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_an_elastic_law_drops_the_damping(seed):
    """No material damping: the term is not kept and the learned rod's c is 0."""
    fit = fit_bending_damping(*_law_samples(0.0, seed=seed), degree=3, blocks=10)
    assert not fit.kept and fit.coefficient == 0.0


def test_an_active_law_is_not_learned_as_negative_damping():
    """m = EI kappa - c dkappa/dt (energy input): c >= 0 by construction gives c = 0, dropped."""
    fit = fit_bending_damping(*_law_samples(-C_KV), degree=3, blocks=10)
    assert fit.c_fit == 0.0 and not fit.kept and fit.coefficient == 0.0


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), scale=st.floats(1e-6, 1e2))
def test_the_learned_coefficient_is_non_negative_for_any_data(seed, scale):
    rng = np.random.default_rng(seed)
    n = 600
    kappa, kdot, m = (scale * rng.standard_normal(n) for _ in range(3))
    fit = fit_bending_damping(kappa, kdot, m, rng.integers(0, 4, n), degree=2, blocks=5)
    assert fit.c_fit >= 0 and fit.coefficient >= 0


def test_too_few_samples_for_the_blocks_are_refused():
    k, kd, m, seg = _law_samples(C_KV, n_t=5)
    with pytest.raises(ValueError, match="cannot fill"):
        fit_bending_damping(k, kd, m, seg, degree=3, blocks=10)


def test_damping_torques_remove_c_kappa_dot_from_the_moment_targets():
    """Booked as a known force (features.hz_targets), the couples of m_d = c dkappa/dt lower the
    moment targets of the discrete moment balance by exactly m_d on every segment."""
    P = paper_rod(N=6)
    rng = np.random.default_rng(3)
    kdot = rng.standard_normal((4, P.N))
    tau = damping_torques(kdot, C_KV, P)
    m = ft.moments_from_htheta(tau[..., 2], np.zeros((4, P.N)), P)
    np.testing.assert_allclose(m, -C_KV * kdot, rtol=1e-12, atol=1e-18)
    assert np.all(tau[..., :2] == 0.0)


def test_mode_none_leaves_the_training_arrays_untouched():
    P = paper_rod(N=4)
    arr = {"x": np.zeros((50, P.N + 1))}
    out, fit = learn_bending_damping(arr, P, np.ones(P.N, bool), {"mode": "none", "degree": 1, "blocks": 2})
    assert out is arr and fit is None
    with pytest.raises(ValueError, match="camera.learn.bending_damping.mode"):
        learn_bending_damping(arr, P, np.ones(P.N, bool), {"mode": "on", "degree": 1, "blocks": 2})


@settings(max_examples=30, deadline=None)
@given(c_true=st.floats(1e-7, 1e-3), width=st.floats(0.05, 1.0))
def test_golden_search_finds_the_minimum_on_a_log_scale(c_true, width):
    """A unimodal objective in log c: 12 evaluations over [c/4, 4c] (a factor 16) land within
    16^(0.618^10) - 1 = 2.3 % of its minimum."""
    f = lambda c: (math.log(c / c_true) / width) ** 2  # noqa: E731
    lo, hi = c_true / 4 * 1.3, c_true * 4 / 1.1
    best, val, seen = golden_log_search(f, lo, hi, 12)
    assert len(seen) == 12 and val == min(seen.values())
    assert abs(math.log(best / c_true)) < 0.618**10 * math.log(hi / lo) + 1e-12


def test_refinement_only_for_a_kept_damping_and_reproduces_the_record_minimum():
    kept = fit_bending_damping(*_law_samples(C_KV), degree=3, blocks=10)
    dropped = fit_bending_damping(*_law_samples(0.0), degree=3, blocks=10)
    opts = {"refine_factor": 4.0, "refine_evaluations": 12}
    calls: list[float] = []

    def record_rmse(c):
        calls.append(c)
        return abs(math.log(c / (1.7 * kept.c_fit)))

    assert refine_by_rollout(dropped, record_rmse, opts) is dropped and not calls
    assert refine_by_rollout(kept, record_rmse, {**opts, "refine_evaluations": 0}) is kept and not calls
    ref = refine_by_rollout(kept, record_rmse, opts)
    assert ref.coefficient == ref.c_refined and abs(ref.c_refined / (1.7 * kept.c_fit) - 1) < 0.03
    assert ref.fit_rmse_theta == pytest.approx(math.log(1.7)) and ref.refine_rmse_theta < ref.fit_rmse_theta


# --- R >= 0 and the exact flow ------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(omega=arrays(np.float64, (3, 9), elements=st.floats(-50, 50)), c=st.floats(0, 1e-2),
       ds=st.floats(1e-3, 1.0))
def test_learned_bending_dissipation_is_non_negative_for_any_state(omega, c, ds):
    assert np.all(bending_power(omega, c, ds) >= 0)


@settings(max_examples=40, deadline=None)
@given(p=arrays(np.float64, (9, 3), elements=st.floats(-1e-2, 1e-2)), c=st.floats(0, 1e-2))
def test_learned_rods_dissipation_rate_is_non_negative_for_any_momenta(p, c):
    model = exact_rod(paper_rod(N=8), damping=c)
    assert model.dissipation_rate(p) >= 0


@settings(max_examples=40, deadline=None)
@given(p=arrays(np.float64, 9, elements=st.floats(-1e-2, 1e-2)), c=st.floats(0, 1e-2),
       h=st.floats(1e-6, 1.0))
def test_the_damping_flow_only_removes_kinetic_energy(p, c, h):
    """P(h) is a contraction in the kinetic-energy norm for any step (passive, unconditionally stable)."""
    P = paper_rod(N=8)
    m_r = P.rhoI * node_weights(P.N) * P.ds
    free = free_mask(P)[:, 2]
    Pm = kelvin_voigt_flow(c, P.ds, m_r, 0.0, free, h)[0] if c > 0 else np.diag(free)
    p = p * free
    ke = lambda x: 0.5 * np.sum(m_r * (x / P.rhoI) ** 2)  # noqa: E731
    assert ke(Pm @ p) <= ke(p) * (1 + 1e-12) + 1e-300


@settings(max_examples=60, deadline=None)
@given(w=arrays(np.float64, 9, elements=st.floats(-10.0, 10.0)),
       a=arrays(np.float64, 9, elements=st.floats(-1e4, 1e4)),
       c=st.floats(1e-7, 1e-2), h=st.floats(1e-6, 1e-2))
def test_the_rotational_flow_books_a_non_negative_dissipation(w, a, c, h):
    """The rotational half-kick flow with a Kelvin-Voigt damping (any state, any frozen couples,
    any step) books a dissipation >= 0: the frozen couples' work less the kinetic-energy gain is
    the integral of omega^T (K + M lam) omega (to round-off of the energies involved)."""
    P = paper_rod(N=8)
    m_r = P.rhoI * node_weights(P.N) * P.ds
    free = free_mask(P)[:, 2]
    flow = kelvin_voigt_flow(c, P.ds, m_r, P.zeta / P.rhoI, free, h)
    w1, lost = kv_flow_step(flow, w * free, a * free, m_r)
    scale = np.sum(m_r * (w**2 + w1**2)) + h * np.sum(m_r * np.abs(a) * (np.abs(w) + np.abs(w1)))
    assert lost >= -1e-12 * scale


def test_negative_damping_is_refused():
    with pytest.raises(ValueError, match=">= 0"):
        exact_rod(paper_rod(N=4), damping=-1e-6)


def test_learned_rod_with_the_true_damping_reproduces_the_viscoelastic_simulator():
    """The exact laws plus c = the simulator's Kelvin-Voigt c: the learned rollout (its damping
    flow in run_hamiltonian) is the viscoelastic simulator's trajectory to round-off; without
    the learned damping it is not."""
    P = replace(paper_rod(N=10), internal_damping=C_KV)
    ref = simulate(125.0, P, GRID)
    nominal = replace(P, internal_damping=0.0)
    roll = rollout(exact_rod(nominal, damping=C_KV), 125.0, GRID)
    np.testing.assert_allclose(roll.q, ref.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(roll.p, ref.p, rtol=0, atol=1e-9)
    np.testing.assert_allclose(roll.dissipated[-1], ref.dissipated[-1], rtol=1e-2)
    undamped = rollout(exact_rod(nominal), 125.0, GRID)
    assert np.abs(undamped.q[..., 2] - ref.q[..., 2]).max() > 1e-2


def _signal_inputs():
    return SignalInputs({"tip_moment": {"kind": "sine", "amplitude": 0.005, "frequency_hz": 3.0,
                                        "phase_rad": 0.0, "offset": 0.0},
                         "tip_force_y": {"kind": "step", "value": -0.1, "t_s": 0.2}})


@pytest.mark.parametrize("actuated", [False, True])
def test_energy_balance_of_a_learned_viscoelastic_rollout(actuated):
    """H(T) - H(0) = -dissipated + port work for the learned rod with its learned damping: the
    integrator books the energy the zeta flow and the rotational Kelvin-Voigt flow dissipate
    (exactly, for the exact laws: an affine H_p), and the balance closes to the scheme's O(dt^2)
    energy error: small, and about four times smaller at half the step. The bending damping's
    share is real: the zeta part of the dissipation rate alone falls well short of the booked
    energy; and the booking is the rate's integral: the rate's trapezoid over the records is the
    booked energy to 1e-3."""
    P = paper_rod(N=10)
    model = exact_rod(P, damping=C_KV)
    kw = {"inputs": _signal_inputs(), "ports": Ports(0.005)} if actuated else {}
    roll = rollout(model, 125.0, GRID, **kw)
    en = learned_energy(model, roll, GRID.dt)
    diss = en["dissipated"].to_numpy()
    residual = np.abs(en["balance_residual"]).max()
    assert residual < 1e-3 * diss[-1]
    fine = replace(GRID, dt=GRID.dt / 2, record_every=2 * GRID.record_every)
    half = np.abs(learned_energy(model, rollout(model, 125.0, fine, **kw), fine.dt)["balance_residual"]).max()
    assert half < residual / 3
    if actuated:
        assert np.abs(roll.input_work).max() > 0.1 * diss[-1]  # the inputs do work
    rate = en["dissipation_rate"].to_numpy()
    trapezoid = float(np.sum(0.5 * (rate[1:] + rate[:-1]) * np.diff(roll.t)))
    assert abs(trapezoid - diss[-1]) < 1e-3 * diss[-1]
    zeta_rate = exact_rod(P).dissipation_rate(roll.p)  # the same trajectory, R = zeta I only
    zeta_part = float(np.sum(0.5 * (zeta_rate[1:] + zeta_rate[:-1]) * np.diff(roll.t)))
    assert zeta_part < 0.9 * trapezoid


def test_curvature_rates_are_the_segment_differences_of_the_angular_rates():
    omega = np.array([[0.0, 1.0, 3.0, 6.0]])
    np.testing.assert_allclose(curvature_rates(omega, 0.5), [[2.0, 4.0, 6.0]])
    assert math.isclose(float(bending_power(omega[0], 2.0, 0.5)), 2.0 / 0.5 * (1 + 4 + 9))


# --- end to end: crgpr learn on the smoke rod ----------------------------------------------------
@pytest.fixture(scope="module")
def learned_smoke(tmp_path_factory):
    """The smoke rod with and without Kelvin-Voigt damping, 1.5 s of its 85 deg release recorded
    at 250 Hz (the noise-free full state: the damping shows over several swings), learned."""
    from crgpr.commands.learn import learn
    from crgpr.config import load_config, rod_params
    from crgpr.io import write_parquet
    from crgpr.physics.simulate import trajectory_frame

    cfg = load_config("tests/smoke_config.yaml")
    rec = SimSettings(dt=1e-4, t_end=1.5, record_every=40, scheme="variational")
    d = tmp_path_factory.mktemp("damping")
    out = {}
    for name, c in (("elastic", 0.0), ("viscoelastic", C_KV)):
        tr = simulate(85.0, replace(rod_params(cfg), internal_damping=c), rec)
        write_parquet(trajectory_frame(tr), d / f"{name}.parquet")
        out[name] = (learn(d / f"{name}.parquet", d / name, cfg), d / name)
    return cfg, out


def test_learn_keeps_a_viscoelastic_rods_damping_and_sizes_it_on_the_record(learned_smoke):
    """The damping is kept by its held-out blocks; the record fit (learning/record_fit.py) sizes
    c by output error from the recorded start: the rod with the fitted c reproduces its record
    better than with the regression's c, and both are within 10 % of the truth."""
    _, out = learned_smoke
    man = out["viscoelastic"][0]
    fit, rf = man["bending_damping"], man["record_fit"]
    assert fit["kept"] and fit["coefficient"] == fit["c_record_fit"] == rf["damping"] > 0
    assert rf["damping_before"] == fit["c_fit"] and fit["c_refined"] is None
    assert fit["heldout_log_ratio"] > 1.96 * fit["heldout_log_ratio_se"]
    assert rf["rmse_start_only"] < rf["rmse_learned"]
    assert abs(math.log(fit["coefficient"] / C_KV)) < 0.1 and abs(math.log(fit["c_fit"] / C_KV)) < 0.1


def test_without_the_record_fit_the_damping_is_refined_by_the_rollout(tmp_path):
    """``record_fit: none``: the kept c is refined by the golden-section rollout search instead;
    it lowers the rollout's error, and c stays within 10 % of the truth."""
    from crgpr.commands.learn import learn
    from crgpr.config import load_config, rod_params
    from crgpr.io import write_parquet
    from crgpr.physics.simulate import trajectory_frame

    cfg = load_config("tests/smoke_config.yaml")
    cfg["camera"]["learn"]["record_fit"]["mode"] = "none"
    rec = SimSettings(dt=1e-4, t_end=1.5, record_every=40, scheme="variational")
    tr = simulate(85.0, replace(rod_params(cfg), internal_damping=C_KV), rec)
    write_parquet(trajectory_frame(tr), tmp_path / "visco.parquet")
    man = learn(tmp_path / "visco.parquet", tmp_path / "m", cfg)
    fit = man["bending_damping"]
    assert man["record_fit"] is None and fit["kept"] and fit["coefficient"] == fit["c_refined"] > 0
    assert fit["refine_rmse_theta"] < fit["fit_rmse_theta"]
    assert abs(math.log(fit["c_refined"] / C_KV)) < 0.1 and abs(math.log(fit["c_fit"] / C_KV)) < 0.1


def test_learn_drops_the_damping_of_an_elastic_rod(learned_smoke):
    from crgpr.commands.learn import load_learned

    _, out = learned_smoke
    man, d = out["elastic"]
    assert not man["bending_damping"]["kept"] and man["bending_damping"]["coefficient"] == 0.0
    assert load_learned(d)[0].damping == 0.0
    visco, d_visco = out["viscoelastic"]
    assert load_learned(d_visco)[0].damping == visco["bending_damping"]["coefficient"] > 0
