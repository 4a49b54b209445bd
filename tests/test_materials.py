"""Material laws of the ground-truth rod (crgpr.physics.material, docs/materials.md): every law
is an energy whose forces are -grad V, whose tangent is the forces' derivative, which conserves
energy without damping and tends to the linear rod; the default material is today's rod to the
last bit; bad material config is one line naming the key, exit code 2."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit
from paper_rod import paper_rod, paper_sim

from crgpr.cli import main
from crgpr.config import ConfigError, load_config
from crgpr.physics.kernels import _force_tangent
from crgpr.physics.material import Material
from crgpr.physics.params import RodParams
from crgpr.physics.rod import (
    internal_forces,
    segment_EI,
    segment_rest_curvature,
    straight_rod,
    strains,
)
from crgpr.physics.simulate import energy, simulate

CONFIG = Path(__file__).resolve().parents[1] / "config.yaml"

# One material per law (moderate for this rod: EI = 1.5e-3 N m^2, curvatures up to ~10 1/m,
# axial strains ~1e-3 under its weight).
LAWS: dict[str, Material] = {
    "exponential": Material(bending_law="exponential", bending_beta=0.1),
    "saturating": Material(bending_law="saturating", saturation_moment=0.01),
    "cubic_stretch": Material(stretch_law="cubic", stretch_stiffening=1.0e4),
    "graded": Material(stiffness_profile=((0.0, 2.0), (0.5, 1.0), (1.0, 0.5))),
    "defect": Material(defect_start=0.4, defect_end=0.6, defect_factor=0.3, defect_edge=0.02),
    "rest_curvature": Material(rest_curvature_profile=((0.0, 4.0), (1.0, -1.0))),
    "all": Material(bending_law="saturating", saturation_moment=0.01, stretch_law="cubic",
                    stretch_stiffening=1.0e4, stiffness_profile=((0.0, 1.5), (1.0, 0.8)),
                    rest_curvature_profile=((0.0, 2.0), (1.0, 0.0)), defect_start=0.2,
                    defect_end=0.3, defect_factor=0.5, defect_edge=0.02),
}


def _rod(name: str, **changes) -> RodParams:
    return paper_rod(material=LAWS[name], **changes)


def _random_state(p: RodParams, rng: np.random.Generator, theta: float, stretch: float,
                  shear: float, curv: float) -> np.ndarray:
    """A configuration with strains nu1 = stretch, nu2 = shear, kappa = curv, plus node noise."""
    th = theta + curv * p.s
    tb = 0.5 * (th[1:] + th[:-1])
    x = np.r_[0.0, np.cumsum(p.ds * (stretch * np.cos(tb) - shear * np.sin(tb)))]
    y = np.r_[0.0, np.cumsum(p.ds * (stretch * np.sin(tb) + shear * np.cos(tb)))]
    return np.stack([x, y, th], axis=1) + 1e-3 * rng.standard_normal((p.N + 1, 3))


# --- the default material is today's linear rod, to the last bit --------------------------------
@njit(cache=True)
def _linear_reference(q, ds, EA, GA, EI_seg, kappa0, nu1_0, nu2_0, b_nl, F):
    """The linear rod's force kernel as it was before material laws existed (reference)."""
    n = q.shape[0] - 1
    F[:] = 0.0
    V = 0.0
    for j in range(n):
        ex = (q[j + 1, 0] - q[j, 0]) / ds
        ey = (q[j + 1, 1] - q[j, 1]) / ds
        tb = 0.5 * (q[j, 2] + q[j + 1, 2])
        c = math.cos(tb)
        s = math.sin(tb)
        nu1 = c * ex + s * ey
        nu2 = -s * ex + c * ey
        dk = (q[j + 1, 2] - q[j, 2]) / ds - kappa0
        n1 = EA * (nu1 - nu1_0)
        n2 = GA * (nu2 - nu2_0)
        mb = EI_seg[j] * dk * (1.0 + b_nl * dk * dk)
        qx = n1 * c - n2 * s
        qy = n1 * s + n2 * c
        F[j, 0] += qx
        F[j + 1, 0] -= qx
        F[j, 1] += qy
        F[j + 1, 1] -= qy
        tq = 0.5 * ds * (n1 * nu2 - n2 * nu1)
        F[j, 2] -= tq - mb
        F[j + 1, 2] -= tq + mb
        V += ds * (0.5 * EA * (nu1 - nu1_0) ** 2 + 0.5 * GA * (nu2 - nu2_0) ** 2
                   + EI_seg[j] * (0.5 * dk * dk + 0.25 * b_nl * dk**4))
    return V


@pytest.mark.parametrize("effects", [{}, {"nonlinear_stiffness": 0.01, "stiffness_gradient": 0.5,
                                          "kappa0": 1.0, "nu1_0": 1.01}])
def test_default_material_is_the_linear_kernel_bit_for_bit(effects):
    """Forces and energy of the default material equal the pre-material kernel exactly, so the
    default config's trajectories are unchanged (same integrator, same forces at every step)."""
    p = paper_rod(**effects)
    assert p.material == Material() and p.material.is_linear
    rng = np.random.default_rng(3)
    for _ in range(20):
        q = _random_state(p, rng, rng.uniform(-3, 3), rng.uniform(0.9, 1.1), rng.uniform(-0.1, 0.1),
                          rng.uniform(-8, 8))
        F, V = internal_forces(q, p)
        F_ref = np.empty_like(q)
        V_ref = _linear_reference(q, p.ds, p.EA, p.GA, segment_EI(p), p.kappa0, p.nu1_0, p.nu2_0,
                                  p.nonlinear_stiffness, F_ref)
        assert np.array_equal(F, F_ref) and V == V_ref


def test_is_linear_means_the_linear_rod():
    assert Material(defect_edge=0.05, defect_start=0.2).is_linear
    assert not any(m.is_linear for m in LAWS.values())


def test_default_config_rod_has_the_linear_material():
    cfg = load_config(CONFIG)
    assert RodParams.from_dict(dict(cfg["rod"])) == paper_rod()
    assert paper_rod().material.is_linear and paper_rod().internal_damping == 0.0


# --- forces = -grad V and the tangent = dF/dq ------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS))
@settings(max_examples=15, deadline=None)
@given(theta=st.floats(-np.pi, np.pi), stretch=st.floats(0.9, 1.1), shear=st.floats(-0.1, 0.1),
       curv=st.floats(-10.0, 10.0), seed=st.integers(0, 2**16))
def test_forces_are_minus_energy_gradient(name, theta, stretch, shear, curv, seed):
    """Property: for every law the nodal forces are -dV/dq (central differences, random states)."""
    p = _rod(name, N=6)
    q = _random_state(p, np.random.default_rng(seed), theta, stretch, shear, curv)
    F, _ = internal_forces(q, p)
    h = 1e-7
    for i in range(1, p.N + 1):
        for k in range(3):
            qp, qm = q.copy(), q.copy()
            qp[i, k] += h
            qm[i, k] -= h
            dV = (internal_forces(qp, p)[1] - internal_forces(qm, p)[1]) / (2 * h)
            assert F[i, k] == pytest.approx(-dV, rel=1e-5, abs=1e-6 * max(1.0, np.abs(F).max()))


@pytest.mark.parametrize("name", list(LAWS))
def test_force_tangent_matches_finite_differences(name):
    """The tangent-linear kernel (the discovery workflow's Jacobians) is dF/dq of every law."""
    p = _rod(name, N=6)
    rng = np.random.default_rng(11)
    q = _random_state(p, rng, 0.7, 1.02, 0.03, 6.0)
    dq = rng.standard_normal((3, p.N + 1, 3))
    dF = np.empty_like(dq)
    _force_tangent(q, dq, p.ds, p.EA, p.GA, segment_EI(p), segment_rest_curvature(p),
                   p.material.law_vector(), p.kappa0, p.nu1_0, p.nu2_0, p.nonlinear_stiffness,
                   p.base_spring, np.zeros(3), dF)
    h = 1e-6
    for a in range(3):
        fd = (internal_forces(q + h * dq[a], p)[0] - internal_forces(q - h * dq[a], p)[0]) / (2 * h)
        np.testing.assert_allclose(dF[a], fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


# --- limits ----------------------------------------------------------------------------------------
@pytest.mark.parametrize(("material", "rtol"), [
    (Material(bending_law="exponential", bending_beta=1e-6), 1e-9),
    (Material(bending_law="saturating", saturation_moment=1e6), 1e-9),
    (Material(stretch_law="cubic", stretch_stiffening=1e-9), 1e-9),
    (Material(stiffness_profile=((0.0, 1.0), (1.0, 1.0))), 0.0),
    (Material(rest_curvature_profile=((0.0, 0.0), (1.0, 0.0))), 0.0),
    (Material(defect_start=0.3, defect_end=0.6, defect_factor=1.0 + 1e-12), 1e-9),
])
def test_laws_tend_to_the_linear_rod(material, rtol):
    """Parameters -> their linear values: the forces tend to the linear rod's (beta, a -> 0,
    m_s -> infinity, unit profiles and defect factor)."""
    p_lin = paper_rod(N=8, nonlinear_stiffness=0.002)
    p = p_lin.replace(material=material)
    q = _random_state(p, np.random.default_rng(5), 1.0, 1.05, 0.05, 8.0)
    F, V = internal_forces(q, p)
    F0, V0 = internal_forces(q, p_lin)
    np.testing.assert_allclose(F, F0, rtol=rtol, atol=rtol * np.abs(F0).max())
    assert V == pytest.approx(V0, rel=rtol, abs=0.0)
    # and the law differs from the linear one at finite parameters (the test can fail)
    if material.bending_law == "exponential":
        F1, _ = internal_forces(q, p.replace(material=Material(bending_law="exponential", bending_beta=0.1)))
        assert not np.allclose(F1, F0, rtol=1e-3)


def test_graded_and_defect_profiles_of_EI():
    """EI(s) follows the knots (piecewise linear) and the defect factor inside its interval."""
    p = _rod("graded", N=20)
    s_rel = (np.arange(20) + 0.5) / 20
    np.testing.assert_allclose(segment_EI(p) / p.EI, np.interp(s_rel, [0, 0.5, 1], [2, 1, 0.5]))
    p = _rod("defect", N=50)
    f = segment_EI(p) / p.EI
    s_rel = (np.arange(50) + 0.5) / 50
    assert np.allclose(f[(s_rel > 0.45) & (s_rel < 0.55)], 0.3, rtol=0.01)  # 2.5 edge widths in
    assert np.allclose(f[(s_rel < 0.35) | (s_rel > 0.65)], 1.0, rtol=0.01)
    assert f.min() < 0.31
    # the stable step accounts for the stiffest point of EI(s)
    assert _rod("graded").dt_stable() < paper_rod().dt_stable()


# --- energy balance -------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(LAWS))
def test_energy_conserved_without_damping(name):
    """zeta = 0, no Kelvin-Voigt: the total energy H (kinetic + elastic + gravity) stays within
    1e-4 of H(0) over 0.5 s (Stormer-Verlet at dt = 1e-4 s; measured 5e-8 to 6e-6) while the
    rod moves (kinetic energy reaches 2 % of H(0) or more)."""
    tr = simulate(85.0, _rod(name, zeta=0.0), paper_sim(t_end=0.5))
    e = energy(tr)
    drift = np.abs(e["H"] - e["H"][0]).max() / abs(e["H"][0])
    assert drift < 1.0e-4
    assert e["kinetic"].max() > 0.02 * abs(e["H"][0])


@pytest.mark.parametrize("name", ["saturating", "exponential", "all"])
def test_energy_error_is_the_integrators_second_order(name):
    """The energy error is Stormer-Verlet's own: halving dt divides the largest drift of H over
    0.5 s by 4 (3.5 to 4.5; measured 3.87 to 4.12), so no law leaks or injects energy."""
    drift = []
    for dt in (1.0e-4, 5.0e-5):
        sim = paper_sim(dt=dt, t_end=0.5, record_every=int(round(5e-4 / dt)))
        tr = simulate(85.0, _rod(name, zeta=0.0), sim)
        e = energy(tr)
        drift.append(np.abs(e["H"] - e["H"][0]).max())
    assert 3.5 < drift[0] / drift[1] < 4.5


@pytest.mark.parametrize("name", ["saturating", "rest_curvature", "all"])
def test_kelvin_voigt_dissipation_closes_the_energy_balance(name):
    """Kelvin-Voigt damping only: H(t) - H(0) = -dissipated(t) (the energy the exact damping
    flow removed) to 1 % of the dissipated energy (measured <= 0.12 %), which is not small."""
    p = _rod(name, zeta=0.0, internal_damping=2.0e-5)
    tr = simulate(85.0, p, paper_sim(t_end=0.5))
    e = energy(tr)
    drop = e["H"][0] - e["H"]
    assert tr.dissipated[-1] > 1.0e-3 * abs(e["H"][0])
    assert np.abs(drop - tr.dissipated).max() < 0.01 * tr.dissipated[-1]
    assert np.all(np.diff(tr.dissipated) >= 0.0)


def test_kelvin_voigt_is_part_of_the_material_config():
    rod = dict(load_config(CONFIG)["rod"])
    rod["material"] = {**rod["material"], "kelvin_voigt": 3.0e-5}
    p = RodParams.from_dict(rod)
    assert p.internal_damping == 3.0e-5
    assert RodParams.from_dict(p.to_dict()) == p
    # kelvin_voigt: 0 leaves the internal_damping effect as given (crgpr simulate --set, discovery)
    rod["material"]["kelvin_voigt"] = 0.0
    assert RodParams.from_dict({**rod, "internal_damping": 2.0e-5}).internal_damping == 2.0e-5
    rod["material"]["kelvin_voigt"] = 3.0e-5
    with pytest.raises(ValueError, match="rod.material.kelvin_voigt"):
        RodParams.from_dict({**rod, "internal_damping": 2.0e-5})


# --- boundary conditions and statics --------------------------------------------------------------
@pytest.mark.parametrize("name", ["saturating", "cubic_stretch", "defect"])
def test_free_tip_resultants_vanish(name):
    """Free tip: n = m = 0 is natural; the last segment's resultants, extrapolated to s = L0,
    are small and shrink under refinement (the rod at t = 0.5 s after release at 85 deg)."""
    tips = []
    for N in (20, 40):
        p = _rod(name, N=N)
        tr = simulate(85.0, p, paper_sim(dt=2.0e-5, t_end=0.5, record_every=25000))
        st_ = strains(tr.q[-1], p)
        n = np.hypot(st_["n1"], st_["n2"])
        m = np.abs(st_["m"])
        tips.append((abs(1.5 * n[-1] - 0.5 * n[-2]) / n.max(), abs(1.5 * m[-1] - 0.5 * m[-2]) / m.max()))
    assert max(tips[1]) < 0.1
    assert tips[1][0] < tips[0][0] and tips[1][1] < tips[0][1]


def test_rest_curvature_profile_is_the_unloaded_shape():
    """The rod bent to kappa(s) = kappa0 + k(s), unstretched and unsheared, carries no internal
    force (round-off); the straight rod does, so the profile is felt."""
    p = _rod("rest_curvature", N=20, kappa0=0.5)
    th = 0.3 + np.r_[0.0, np.cumsum(p.ds * (p.kappa0 + segment_rest_curvature(p)))]
    tb = 0.5 * (th[1:] + th[:-1])
    q = np.stack([np.r_[0.0, np.cumsum(p.ds * np.cos(tb))], np.r_[0.0, np.cumsum(p.ds * np.sin(tb))], th],
                 axis=1)
    F, V = internal_forces(q, p)
    assert np.abs(F).max() < 1e-12 * p.EA and V < 1e-20
    F_straight, _ = internal_forces(straight_rod(0.3, p), p)
    assert np.abs(F_straight[:, 2]).max() > 0.5 * p.EI * 4.0 * p.ds


def test_saturating_moment_is_bounded():
    """The saturating law's moment never exceeds m_s (plus the cubic term, here 0)."""
    p = _rod("saturating", N=8)
    q = straight_rod(0.3, p)
    q[:, 2] += 40.0 * p.s  # far beyond the saturation curvature m_s / EI = 6.8 1/m
    m = strains(q, p)["m"]
    assert np.all(np.abs(m) <= 0.01) and np.all(np.abs(m) > 0.0099)


# --- configuration: one line naming the key, exit code 2 -----------------------------------------
@pytest.mark.parametrize(("material", "key"), [
    ({"bending_law": "quadratic"}, "rod.material.bending_law"),
    ({"bending_law": "exponential"}, "rod.material.bending_beta"),
    ({"bending_law": "saturating", "saturation_moment": 0.0}, "rod.material.saturation_moment"),
    ({"stretch_law": "cubic", "stretch_stiffening": -1.0}, "rod.material.stretch_stiffening"),
    ({"stiffness_profile": [[0.0, 1.0], [0.5, 2.0]]}, "rod.material.stiffness_profile"),
    ({"stiffness_profile": [[0.0, 1.0], [1.0, -2.0]]}, "rod.material.stiffness_profile"),
    ({"rest_curvature_profile": [[0.0, 1.0, 2.0]]}, "rod.material.rest_curvature_profile"),
    ({"defect_factor": 0.5, "defect_start": 0.6, "defect_end": 0.4}, "rod.material.defect_start"),
    ({"stiffness": 2.0}, "rod.material.stiffness"),
    ({"kelvin_voigt": -1.0}, "rod.material.kelvin_voigt"),
    ({"bending_beta": 0.1}, "rod.material.bending_beta"),  # a parameter of a law not selected
    ({"bending_law": "exponential", "bending_beta": 0.1, "saturation_moment": 1.0},
     "rod.material.saturation_moment"),
    ({"stretch_stiffening": 10.0}, "rod.material.stretch_stiffening"),
])
def test_bad_material_config_names_the_key(material, key):
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")) as exc:
        load_config(CONFIG, {"rod": {"material": material}})
    assert "\n" not in str(exc.value)


def test_collocated_scheme_refuses_nonlinear_laws_and_takes_EI_profiles():
    """The collocated schemes refuse nonlinear laws and curvature profiles (one line naming
    rod.material) and take EI(s) profiles and the defect (segment stiffnesses)."""
    with pytest.raises(ConfigError, match=r"rod\.material: the 'collocated' scheme"):
        load_config(CONFIG, {"rod": {"material": {"bending_law": "saturating", "saturation_moment": 1.0}},
                             "simulation": {"scheme": "collocated"}})
    for name in ("exponential", "cubic_stretch", "rest_curvature"):
        with pytest.raises(ValueError, match="linear laws and a uniform rest curvature only"):
            simulate(85.0, _rod(name), paper_sim(t_end=0.01, scheme="collocated_nodal"))
    sim = paper_sim(t_end=0.5, scheme="collocated")
    uniform = simulate(85.0, paper_rod(), sim)
    graded = simulate(85.0, _rod("graded"), sim)
    assert np.abs(graded.q[..., 2] - uniform.q[..., 2]).max() > 0.01  # the profile is felt [rad]


def test_cli_bad_material_is_one_line_exit_2(tmp_path, capsys):
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg["rod"]["material"]["bending_law"] = "softening"
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "x.parquet"
    assert main(["simulate", "--theta0", "85", "--out", str(out), "--t-end", "0.01",
                 "--config", str(path)]) == 2
    err = capsys.readouterr().err
    assert "rod.material.bending_law" in err and "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()


def test_cli_simulates_a_material_and_records_it(tmp_path):
    cfg = yaml.safe_load(CONFIG.read_text())
    cfg["rod"]["material"].update(bending_law="exponential", bending_beta=0.1,
                                  stiffness_profile=[[0.0, 1.5], [1.0, 1.0]])
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "x.parquet"
    assert main(["simulate", "--theta0", "85", "--out", str(out), "--t-end", "0.01",
                 "--config", str(path)]) == 0
    from crgpr.io import read_metadata

    meta = read_metadata(out)
    assert meta["rod"]["material"]["bending_law"] == "exponential"
    assert RodParams.from_dict(meta["rod"]).material == Material(
        bending_law="exponential", bending_beta=0.1, stiffness_profile=((0.0, 1.5), (1.0, 1.0)))


def test_cli_sets_a_material_key_as_it_sets_a_rod_parameter(tmp_path, capsys):
    """``--set material.KEY=VALUE`` (or ``rod.material.KEY``) reaches the material section, its
    value read as YAML, validated by the same rules as the config file."""
    out = tmp_path / "x.parquet"
    assert main(["simulate", "--theta0", "85", "--out", str(out), "--t-end", "0.01",
                 "--set", "material.bending_law=exponential", "--set", "rod.material.bending_beta=0.1",
                 "--set", "material.stiffness_profile=[[0, 1.5], [1, 1.0]]"]) == 0
    from crgpr.io import read_metadata

    mat = read_metadata(out)["rod"]["material"]
    assert mat["bending_law"] == "exponential" and mat["bending_beta"] == 0.1
    assert mat["stiffness_profile"] == [[0, 1.5], [1, 1.0]]
    bad = tmp_path / "y.parquet"
    assert main(["simulate", "--theta0", "85", "--out", str(bad), "--t-end", "0.01",
                 "--set", "material.bending_beta=0.1"]) == 2
    err = capsys.readouterr().err
    assert "rod.material.bending_beta" in err and err.count("\n") == 1 and not bad.exists()
