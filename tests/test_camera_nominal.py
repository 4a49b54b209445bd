"""Grey-box camera learning: stretch and shear laws from the nominal rod, bending learned."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from paper_rod import paper_rod

from crgpr.cli import main
from crgpr.commands.camera import camera_frame
from crgpr.commands.learn import learn, load_learned, read_manifest
from crgpr.config import ConfigError, load_config, rod_params, validate_schema
from crgpr.gp.evaluators import load_model
from crgpr.io import write_parquet
from crgpr.learning.learned import LearnedRod, rollout
from crgpr.learning.nominal import NominalLaw, choose_nominal, position_noise_std, strain_snr
from crgpr.physics.params import SimSettings
from crgpr.physics.rod import free_mask, internal_forces, node_weights, segment_EI, straight_rod
from crgpr.physics.simulate import simulate, trajectory_frame
from crgpr.report.metrics import accuracy

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
SMOKE = ROOT / "tests" / "smoke_config.yaml"


class _Linear:
    def __init__(self, k: float):
        self.k = k

    def __call__(self, X):
        return np.asarray(X) * self.k

    def slope(self, X):
        return np.full(np.shape(X), self.k)


def test_nominal_laws_with_the_true_bending_law_are_the_simulators_rod():
    """A LearnedRod whose n1, n2 are NominalLaw and whose m is EI kappa exerts the simulator's
    nodal forces (physics.rod.internal_forces) on a bent, stretched, sheared state."""
    P = paper_rod()
    rng = np.random.default_rng(0)
    q = straight_rod(1.2, P)
    q[1:, :2] += 2e-3 * rng.standard_normal((P.N, 2))
    q[1:, 2] += 0.3 * np.sin(np.linspace(0, 3, P.N))
    EI = segment_EI(P)
    comps = {"obj_n1": NominalLaw("n1", P), "obj_n2": NominalLaw("n2", P),
             "obj_m": lambda X: EI * (X[..., 0] - P.kappa0),
             "dH_dp_x": _Linear(1 / P.rhoA), "dH_dp_y": _Linear(1 / P.rhoA),
             "dH_dp_theta": _Linear(1 / P.rhoI)}
    model = LearnedRod(comps, "objective", P)
    F, _ = internal_forces(q, P)
    got = model.internal(q) * (node_weights(P.N) * P.ds)[:, None]
    free = free_mask(P) > 0
    assert np.allclose(got[free], F[free], rtol=1e-10, atol=1e-9 * np.abs(F).max())


def test_position_noise_is_estimated_from_raw_positions():
    P = paper_rod()
    tr = simulate(85.0, P, SimSettings(dt=1e-4, t_end=0.6, record_every=40, scheme="variational"))
    for sigma in (0.0, 5e-4, 2e-3):
        df = camera_frame(tr.t, tr.q, sigma, np.random.default_rng(1))
        xy = df[["x", "y"]].to_numpy().reshape(tr.t.size, P.N + 1, 2)
        est = position_noise_std(np.concatenate([xy[..., 0], xy[..., 1]], axis=1))
        if sigma == 0.0:
            assert est < 2e-5, est  # the smooth motion's own fourth differences at 250 Hz
        else:
            assert est == pytest.approx(sigma, rel=0.1)


def test_auto_takes_a_law_from_the_nominal_rod_only_below_the_snr_threshold():
    P = paper_rod()
    res = {"n1": np.full(10, 1e-3 * P.EA), "n2": np.full(10, 5e-3 * P.GA), "m": np.full(10, 20 * P.EI)}
    # 1 mm on 2 cm segments: strain noise 0.07 -> n1, n2 unresolvable, kappa resolvable
    snr = strain_snr(res, P, 1e-3)
    assert snr["n1"]["snr"] < 0.1 and snr["n2"]["snr"] < 0.1 and snr["m"]["snr"] > 1
    assert choose_nominal("auto", snr, 1.0) == ["n1", "n2"]
    assert choose_nominal("auto", strain_snr(res, P, 0.0), 1.0) == []
    assert choose_nominal(["n2"], snr, 1.0) == ["n2"]
    assert choose_nominal(["m", "n1"], snr, 1.0) == ["n1", "m"]
    with pytest.raises(ValueError, match="nominal_laws"):
        choose_nominal(["kappa"], snr, 1.0)


def test_schema_rejects_an_unknown_nominal_law():
    cfg = copy.deepcopy(load_config(SMOKE))
    cfg["camera"]["learn"]["nominal_laws"] = ["n3"]
    with pytest.raises(ConfigError, match="nominal_laws"):
        validate_schema(cfg)


@pytest.fixture(scope="module")
def noisy_models(tmp_path_factory, smoke_training_run):
    """Smoke-sized models from 1 mm camera positions: the laws chosen by the data (auto), the
    grey box with only n1, n2 nominal, and the fully learned one."""
    cfg, tr = smoke_training_run
    d = tmp_path_factory.mktemp("grey")
    df = camera_frame(tr.t, tr.q, 1e-3, np.random.default_rng(5))
    write_parquet(df, d / "cam.parquet")
    learn(d / "cam.parquet", d / "auto", cfg, "objective", "gp")
    grey = copy.deepcopy(cfg)
    grey["camera"]["learn"]["nominal_laws"] = ["n1", "n2"]  # the bending law and momentum maps learned
    grey["camera"]["learn"]["bending_arclength"] = "never"  # m(kappa), odd about its rest curvature
    learn(d / "cam.parquet", d / "grey", grey, "objective", "gp")
    white = copy.deepcopy(cfg)
    white["camera"]["learn"]["nominal_laws"] = []
    learn(d / "cam.parquet", d / "all", white, "objective", "gp")
    return cfg, d


def test_manifest_records_the_grey_box_decision(noisy_models):
    cfg, d = noisy_models
    man = read_manifest(d / "auto")
    assert {"n1", "n2"} <= set(man["nominal_laws"]) and man["nominal_laws_setting"] == "auto"
    assert "obj_n1" not in man["models"] and not (d / "auto" / "obj_n1.json").exists()
    assert man["strain_snr"]["m"]["snr"] > 1 > man["strain_snr"]["n1"]["snr"]
    assert man["position_noise_std_m_differences"] == pytest.approx(1e-3, rel=0.15)
    # from positions the momenta are p = rho A v by construction: a learned velocity map cannot
    # predict held-out blocks better than the nominal one, which is kept
    for k in ("p_x", "p_y", "p_theta"):
        assert k in man["nominal_laws"] and not man["law_choice"][k]["richer"], man["law_choice"][k]
    # every law is learned or nominal as its held-out comparison says (n1, n2: nominal by SNR anyway)
    assert all((k in man["nominal_laws"]) == (not c["richer"]) for k, c in man["law_choice"].items()
               if k not in ("n1", "n2"))
    model, _ = load_learned(d / "auto")
    assert isinstance(model.components["obj_n1"], NominalLaw)
    man = read_manifest(d / "grey")
    assert man["nominal_laws"] == ["n1", "n2"] and "obj_m" in man["models"]
    model, _ = load_learned(d / "grey")
    # the bending law m(kappa), odd about its rest curvature: the estimate's band contains the
    # straight rod's nominal 0, so the samples are mirrored about the nominal 0; it bends both ways
    # alike, although the 85 deg record curves the rod mostly one way
    rest = man["rest_state"]
    assert man["bending_inputs"] == ["kappa"] and man["bending_symmetry"] == "auto" and rest["symmetric"]
    assert rest["band_lo"] <= 0.0 <= rest["band_hi"] and man["bending_odd_about"] == 0.0, rest
    c = man["bending_odd_about"]
    arrays, _ = load_model(d / "grey" / "obj_m")
    k = 0.5 * float(np.abs(arrays["X"] - c).max())  # inside the (mirrored) training range
    X = np.zeros((2, 5))
    X[:, 0] = [c - k, c + k]
    m = model.components["obj_m"](X)
    P = rod_params(cfg)
    assert m[1] == pytest.approx(-m[0], rel=0.1) and m[1] == pytest.approx(k * P.EI, rel=0.3), (k, m)
    assert read_manifest(d / "all")["nominal_laws"] == []


def test_grey_box_model_holds_together_where_the_fully_learned_one_does_not(noisy_models):
    """1 mm noise: the grey-box rollout at an unseen angle tracks the ground truth (RMSE(theta)
    < 0.15 rad over 0.2 s); the model that learns n1, n2 from the noise is worse."""
    cfg, d = noisy_models
    st = SimSettings(dt=1e-4, t_end=0.2, record_every=5, scheme="variational")
    gt = trajectory_frame(simulate(60.0, rod_params(cfg), st))
    out = {}
    for k in ("auto", "grey", "all"):
        model, _ = load_learned(d / k)
        try:
            tr = rollout(model, 60.0, st)
            out[k] = accuracy(gt, trajectory_frame(tr), 0.5)["rmse_theta"]
        except Exception:  # noqa: BLE001 - a diverged fully learned rod is the worse outcome
            out[k] = np.inf
    assert max(out["auto"], out["grey"]) < 0.15 and max(out["auto"], out["grey"]) < out["all"], out


def test_rollout_cli_rolls_a_grey_box_directory_out(noisy_models, tmp_path):
    cfg, d = noisy_models
    out = tmp_path / "r.parquet"
    assert main(["rollout", "--models", str(d / "auto"), "--theta0", "60", "--out", str(out),
                 "--t-end", "0.05", "--config", str(SMOKE)]) == 0
    assert out.exists()


class _Runaway:
    """A learned stretch law that fits the nominal one plus a departure on its record's strains
    and whose trend runs away beyond them (a GP's basis fitted over one record)."""

    def __init__(self, P):
        self.EA = P.EA

    def __call__(self, X):
        X = np.asarray(X, dtype=float)
        return self.EA * (X[..., 0] - 1.0) + 50.0 * X[..., 2] ** 3


def test_a_learned_stretch_law_is_continued_by_the_nominal_one_beyond_its_covered_strains():
    """Inside the covered box the learned law is as learned; beyond it, its value at the box's
    edge plus the nominal law's increment: continuous at the edge, the nominal stiffness EA
    along nu1, no dependence the record did not show along kappa (the runaway cubic stays at
    its edge value)."""
    from crgpr.learning.nominal import NominalContinuation

    P = paper_rod()
    lo, hi = np.array([0.99, -0.01, -5.0]), np.array([1.01, 0.01, 5.0])
    law = _Runaway(P)
    cont = NominalContinuation(law, "n1", P, lo, hi)
    inside = np.array([[1.005, 0.0, 3.0], [0.995, 0.005, -4.0]])
    np.testing.assert_array_equal(cont(inside), law(inside))
    edge = np.array([1.0, 0.0, 5.0])
    beyond_k = np.array([1.0, 0.0, 40.0])
    assert cont(beyond_k[None])[0] == pytest.approx(law(edge[None])[0], rel=1e-12)
    assert abs(law(beyond_k[None])[0]) > 100 * abs(cont(beyond_k[None])[0])
    a, b = np.array([[1.03, 0.0, 0.0]]), np.array([[1.05, 0.0, 0.0]])
    assert (cont(b) - cont(a))[0] == pytest.approx(P.EA * 0.02, rel=1e-9)
    just = np.array([[1.01 + 1e-9, 0.0, 0.0]])
    assert cont(just)[0] == pytest.approx(law(np.array([[1.01, 0.0, 0.0]]))[0], abs=P.EA * 2e-9)
    with pytest.raises(ValueError, match="only n1, n2"):
        NominalContinuation(law, "m", P, lo, hi)


class _ChordCoupled:
    """A stretch law that depends on the curvature too (n1 + EA kappa^2 ds^2 / 24: a coarse
    grid's chord shorter than the arc), while the bending law does not depend on nu1."""

    def __init__(self, law, P):
        self.law, self.c = law, P.EA * P.ds**2 / 24.0

    def __call__(self, X):
        X = np.asarray(X, dtype=float)
        return self.law(X) + self.c * X[..., 2] ** 2


def test_learned_laws_of_their_own_strains_have_a_symmetric_stiffness(noisy_models, smoke_training_run):
    """Every law learned (n1, n2, m, momentum maps), n1 of nu1 and n2 of nu2 alone
    (camera.learn.strain_law_inputs: own): the learned force field is the gradient of one stored
    energy, so its tangent stiffness is symmetric at the record's states; a stretch law coupled
    to the curvature is not (learning/stiffness.py)."""
    from crgpr.learning.stiffness import reciprocity_gap

    _, d = noisy_models
    _, tr = smoke_training_run
    man = read_manifest(d / "all")
    assert {"obj_n1", "obj_n2", "obj_m"} <= set(man["models"])
    assert man["law_inputs_covered"]["obj_n1"].keys() == {"nu1"}
    assert man["law_inputs_covered"]["obj_n2"].keys() == {"nu2"}
    assert man["stiffness_check"]["reciprocity_gap_max"] == 0.0  # at the record's frames, by crgpr learn
    model, _ = load_learned(d / "all")
    frames = np.linspace(0, tr.t.size - 1, 4).astype(int)[1:]
    assert all(reciprocity_gap(model, tr.q[k]) == 0.0 for k in frames)
    n1 = _ChordCoupled(model.components["obj_n1"], model.params)
    coupled = LearnedRod({**model.components, "obj_n1": n1}, "objective", model.params)
    assert max(reciprocity_gap(coupled, tr.q[k]) for k in frames) > 1e-3


def test_the_nominal_rods_stiffness_is_symmetric_and_a_coupled_law_flutters():
    """The nominal rod (one stored energy) at a bent, stretched, sheared configuration: K
    symmetric to the differences' accuracy, no flutter; with a stretch law that follows the
    curvature (n1 + c kappa, and no nu1 term in m to match it) the stiffness is unsymmetric and
    oscillating modes grow (learning/stiffness.py)."""
    from crgpr.learning.nominal import NOMINAL_LAWS
    from crgpr.learning.stiffness import asymmetry, flutter_rate, reciprocity_gap, stiffness_matrix

    P = paper_rod()
    rng = np.random.default_rng(0)
    q = straight_rod(1.2, P)
    q[1:, :2] += 2e-3 * rng.standard_normal((P.N, 2))
    q[1:, 2] += 0.3 * np.sin(np.linspace(0, 3, P.N))
    nominal = {c: NominalLaw(k, P) for k, c in NOMINAL_LAWS.items()}
    rod = LearnedRod(nominal, "objective", P)
    K = stiffness_matrix(rod, q)
    assert asymmetry(K) < 1e-6 and flutter_rate(rod, K) == 0.0 and reciprocity_gap(rod, q) < 1e-6

    class _Follower:
        def __call__(self, X):
            X = np.asarray(X, dtype=float)
            return P.EA * (X[..., 0] - 1.0) + 50.0 * P.EI / P.ds * X[..., 2]

    coupled = LearnedRod({**nominal, "obj_n1": _Follower()}, "objective", P)
    Kc = stiffness_matrix(coupled, q)
    assert asymmetry(Kc) > 1e-3 and reciprocity_gap(coupled, q) > 1e-3
    assert flutter_rate(coupled, Kc) > 0.0

