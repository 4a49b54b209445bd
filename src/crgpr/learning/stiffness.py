"""The learned rod's tangent stiffness, and whether its force field is a gradient.

A rod whose resultants derive from one stored energy W(nu1, nu2, kappa) (a hyperelastic rod,
eq. (10) with H = sum ds W + kinetic energy, Sec. II) has a symmetric tangent stiffness
K_ab = -d^2 H / dq_a dq_b: the force at node a per unit displacement of node b equals the force at
b per unit displacement of a (reciprocity). CR-GPR learns each resultant with its own GP
(``learning.learned``), so nothing makes the learned field a gradient: a stretch law n1 that
depends on kappa while the bending law m does not depend on nu1 breaks the symmetry, and an
unsymmetric stiffness may have complex eigenvalues, i.e. oscillations that grow (flutter) where
the true rod only vibrates. With each law a function of its own strain (n1(nu1), n2(nu2), m(kappa)
or m(kappa, s): ``camera.learn.strain_law_inputs: own``) the learned field is the gradient of
W1(nu1) + W2(nu2) + Wb(kappa, s) whatever the GPs learned.

``reciprocity_gap`` measures the symmetry where it is decided, in the laws: the largest
|dr_i/de_j - dr_j/de_i| / sqrt(|dr_i/de_i dr_j/de_j|) over the segments of a configuration, r =
(n1, n2, m) the resultants and e = (nu1, nu2, kappa) the segment's strains (central differences;
0 exactly where each law takes its own strain alone, whatever its values; a bending law of the
neighbours' curvatures too, ``camera.learn.bending_inputs``, couples segments, which this does
not see). ``stiffness_matrix`` is K of a learned rod at one configuration (central differences
of the free nodes' generalised internal forces; a tabulated law's kinks make its differences,
and so its symmetry, accurate to a few 1e-4 only), ``asymmetry`` ||K - K^T|| / ||K|| (Frobenius) and
``flutter_rate`` the largest growth rate of the oscillating modes of the linearised undamped
motion about that configuration, M dq'' = K dq: the eigenvalues lambda of M^-1 K that are complex
(only an unsymmetric K has them) give modes exp(sqrt(lambda) t) that oscillate and grow,
Re sqrt(lambda) > 0; a real lambda (a symmetric K: the true rod's and the nominal one's) gives a
vibration (lambda < 0) or, about a configuration that is not an equilibrium, a divergence that
the rod's own motion has too (lambda > 0), and is left out. 0: no flutter.
"""

from __future__ import annotations

import numpy as np

from crgpr.learning import features as ft
from crgpr.learning.features import OBJ_M_FEATURES, OBJ_N_FEATURES
from crgpr.physics.rod import free_mask

# central-difference steps [m, m, rad]: small against the segment (strain 1e-5), large against round-off
STEP: tuple[float, float, float] = (1e-7, 1e-7, 1e-6)
LAW_STEP: tuple[float, float, float] = (1e-6, 1e-6, 1e-4)  # [-, -, 1/m]: nu1, nu2, kappa
# camera.learn.strain_law_inputs -> the inputs of the learned stretch and shear laws (``all``: every one)
STRAIN_LAW_INPUTS: dict[str, dict[str, tuple[str, ...]]] = {
    "own": {"n1": ("nu1",), "n2": ("nu2",)},
}
M_COLUMNS: tuple[int, int, int] = (OBJ_M_FEATURES.index("nu1"), OBJ_M_FEATURES.index("nu2"),
                                   OBJ_M_FEATURES.index("kappa"))  # the same strains among m's inputs


def strain_law_columns(setting: str, law: str) -> list[int] | None:
    """The columns of the objective n features (``OBJ_N_FEATURES``) a stretch (``law`` n1) or
    shear (n2) law is learned on under ``camera.learn.strain_law_inputs`` ``setting``; None:
    every column (``all``)."""
    if setting == "all":
        return None
    return [OBJ_N_FEATURES.index(e) for e in STRAIN_LAW_INPUTS[setting][law]]


def _free(P) -> np.ndarray:
    """Indices of the free coordinates in a flattened (N+1, 3) configuration."""
    return np.flatnonzero(free_mask(P).astype(bool).ravel())


def stiffness_matrix(model, q: np.ndarray) -> np.ndarray:
    """K_ab = d f_a / d q_b (f: the nodal internal forces w_i ds (-H_q) of ``model.internal``) over
    the free coordinates a, b of configuration q (N+1, 3), by central differences (``STEP``)."""
    P = model.params
    q = np.asarray(q, dtype=float)
    idx = _free(P)
    h = np.tile(np.asarray(STEP), P.N + 1)[idx]
    flat = np.repeat(q.reshape(1, -1), 2 * idx.size, axis=0)
    rows = np.arange(idx.size)
    flat[2 * rows, idx] += h
    flat[2 * rows + 1, idx] -= h
    f = (model.internal(flat.reshape(-1, *q.shape)) * model.wds[:, None]).reshape(2 * idx.size, -1)[:, idx]
    return ((f[0::2] - f[1::2]) / (2.0 * h[:, None])).T


def asymmetry(K: np.ndarray) -> float:
    """||K - K^T||_F / ||K||_F: 0 for a stiffness that derives from a stored energy."""
    return float(np.linalg.norm(K - K.T) / np.linalg.norm(K))


def flutter_rate(model, K: np.ndarray) -> float:
    """Largest growth rate [1/s] of the oscillating modes of M dq'' = K dq (M: the free nodes'
    lumped masses rho A w ds, rho I w ds): max Re sqrt(lambda) over the eigenvalues lambda of
    M^-1 K whose imaginary part exceeds 1e-6 of the largest |lambda| (module docstring); 0 if none."""
    P = model.params
    idx = _free(P)
    mass = (np.array([P.rhoA, P.rhoA, P.rhoI])[None, :] * model.wds[:, None]).ravel()[idx]
    lam = np.linalg.eigvals(K / mass[:, None])
    lam = lam[np.abs(lam.imag) > 1e-6 * np.abs(lam).max()]
    return float(np.max(np.sqrt(lam).real)) if lam.size else 0.0


def law_jacobian(model, q: np.ndarray) -> np.ndarray:
    """d(n1, n2, m)/d(nu1, nu2, kappa) of every segment of configuration q (N+1, 3) -> (N, 3, 3),
    by central differences (``LAW_STEP``; each strain moved in the n rows and in m's rows alike)."""
    Xn, Xm = (np.array(a) for a in ft.objective_inputs(ft.segment_table(np.asarray(q, dtype=float),
                                                                          model.params.ds)))
    c = model.components
    J = np.zeros((Xn.shape[0], 3, 3))
    for j, (h, cm) in enumerate(zip(LAW_STEP, M_COLUMNS, strict=True)):
        out = []
        for sign in (1.0, -1.0):
            Yn, Ym = Xn.copy(), Xm.copy()
            Yn[:, j] += sign * h
            Ym[:, cm] += sign * h
            out.append(np.stack([c["obj_n1"](Yn), c["obj_n2"](Yn), c["obj_m"](Ym)], axis=-1))
        J[:, :, j] = (out[0] - out[1]) / (2.0 * h)
    return J


def reciprocity_gap(model, q: np.ndarray) -> float:
    """The largest reciprocity gap of the objective laws over the segments of configuration q
    (N+1, 3) (module docstring; ``law_jacobian``)."""
    J = law_jacobian(model, q)
    gap = 0.0
    for i, j in ((0, 1), (0, 2), (1, 2)):
        scale = np.sqrt(np.abs(J[:, i, i] * J[:, j, j]))
        d = np.abs(J[:, i, j] - J[:, j, i])
        rel = np.divide(d, scale, out=np.where(d > 0, np.inf, 0.0), where=scale > 0)  # no scale: 0 or inf
        gap = max(gap, float(rel.max()))
    return gap


def stiffness_check(model, q: np.ndarray, frames: int) -> dict[str, float | int]:
    """The largest ``reciprocity_gap`` and ``flutter_rate`` of a learned rod over ``frames`` evenly
    spaced configurations of its record q (n_t, N+1, 3) (``crgpr learn``'s manifest
    ``stiffness_check``)."""
    ks = np.unique(np.linspace(0, q.shape[0] - 1, max(int(frames), 1)).round().astype(int))
    return {"frames": int(ks.size), "reciprocity_gap_max": max(reciprocity_gap(model, q[k]) for k in ks),
            "flutter_rate_max_per_s": max(flutter_rate(model, stiffness_matrix(model, q[k])) for k in ks)}

