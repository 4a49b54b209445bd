"""Which constitutive laws the data support: learned or nominal, and uniform or varying along s.

The paper's premise (Sec. II) is that a soft rod's laws are unknown, nonlinear and may vary
along the body; a learned law is only worth its freedom where the data pin it down. Both
decisions here compare a simpler law with a richer one by how well each predicts *held-out
contiguous time blocks* of the law's own training samples (n1, n2, m of eq. (10), from the
force and moment balance of eq. (13)), the principle ``learning.laws`` uses for the symmetry:

* the samples, in time order (rows as ``gradient_models.training_data`` returns them), are cut
  into ``blocks`` contiguous blocks; each law is fitted without one block and predicts it;
* per block, d_b = log(simple law's squared error / richer law's squared error); the richer law
  is chosen only if it predicts the held-out blocks *consistently* better: mean(d) > 1.96 se(d)
  (blocks as independent units; the samples of one trajectory are correlated in time, so a
  per-sample criterion would take any systematic error of one record for a law). Where the
  data cannot tell them apart, the simpler law is kept, and so it is where its held-out error
  is at round-off (below sqrt(machine epsilon) x the targets' rms: nothing left to learn), and
  where the record has too few samples to fit the richer law on all blocks but one.
* learned or nominal for the bending law m is decided on the *total* held-out error as well
  (``laws.pooled_gain``: log(sum_b e_simple / sum_b e_richer) above 1.96 of its delete-a-block
  jackknife se): a nonlinear law departs from the nominal one only at large curvatures, which a
  decaying release reaches in its first blocks only; per-block log ratios weigh the many
  small-amplitude blocks, where the two laws agree, as much as those (measured on the materials
  study's exponential and saturating rods from the full state: per-block 3.1 +- 1.9 and
  1.0 +- 1.7, nominal kept). Either rule suffices: a departure present in every block (a rest
  curvature, a scaled stiffness) whose total is dominated by one block's larger target errors
  is seen per block (a pre-curved rod's full state from a twice finer simulator, whose
  moment-balance targets carry the coarser grid's error, largest in the first blocks: pooled
  0.50 +- 2.81, per block 3.35 +- 0.39; ``benchmarks/materials_unseen.py --truth-refine 2``).
  The stretch and shear laws keep the per-block rule alone: their targets carry systematic
  errors of the prefilter or of the position reconstruction that one block can concentrate
  (the smoke rod's noise-free positions: n2 at 0.62 +- 0.09 pooled, -0.08 +- 0.51 per block;
  learned, it made the rollout diverge).

The two comparisons (``learned_or_nominal``, ``arclength_dependence``) differ only in the laws:

* learned or nominal (n1, n2, m): the nominal law (n1 = EA (nu1 - nu1_0), n2 = GA (nu2 - nu2_0),
  m = EI (kappa - kappa0); no free parameter) against the nominal law plus a polynomial of total
  degree D in the law's inputs, the smooth stand-in of what a GP can learn from the same samples;
* uniform or along s (m): a cubic regression spline in kappa (``spline_basis``: degree D, K
  knots at quantiles of kappa) against the same spline whose coefficients are polynomials of
  degree L = ``s_degree`` in s (a law varying smoothly along the rod). The uniform law must be
  flexible enough that s cannot stand in for its misfit: segments near the clamp see larger
  curvatures, so a too-rigid m(kappa) (a plain cubic for a saturating law) fits better per
  region of the rod, and s would look informative on a uniform rod.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace
from itertools import combinations_with_replacement
from typing import Any

import numpy as np

from crgpr.learning.features import OBJ_M_FEATURES, segment_arclength
from crgpr.learning.gradient_models import inner_segments, training_data
from crgpr.learning.laws import consistent_gain, heldout_blocks, log_error_ratio, pooled_gain
from crgpr.learning.nominal import (
    MOMENTUM_LAWS,
    NOMINAL_LAWS,
    NominalLaw,
    choose_nominal,
    position_noise_std,
    strain_snr,
)
from crgpr.learning.stiffness import strain_law_columns
from crgpr.physics.params import RodParams


@dataclass(frozen=True)
class HeldoutChoice:
    """A held-out-block comparison of a simpler and a richer law (JSON-able)."""

    richer: bool  # the richer law predicts the held-out blocks consistently better: it is used
    heldout_mse_simple: float  # mean squared held-out error of the simpler law [target units^2]
    heldout_mse_richer: float  # ... of the richer law
    heldout_log_ratio: float  # mean over blocks of log(simpler / richer held-out squared error) [-]
    heldout_log_ratio_se: float  # its standard error over the blocks [-]
    blocks: int
    degree: int
    # a law of one input: the richer law's departure from the simpler one fitted on every block,
    # sum_d b_d u^d, u = (x - center) / scale (``standin_departure``); None otherwise
    standin: list[float] | None = None
    standin_center: float | None = None
    standin_scale: float | None = None
    # where decided on the total held-out error (``pooled``): the per-block rule's mean log ratio
    # and its se (with ``either`` it can decide too); None otherwise
    perblock_log_ratio: float | None = None
    perblock_log_ratio_se: float | None = None

    def to_dict(self) -> dict:
        return asdict(self)


def standin_departure(x: np.ndarray, choice: dict[str, Any] | None) -> np.ndarray:
    """|sum_d b_d u^d|, u = (x - center) / scale, at the inputs x: how far the richer stand-in of
    a law that was kept nominal (``choice``: its ``HeldoutChoice`` as a dict, fitted on all the
    samples) departs from the nominal law; zeros without a stand-in or where the richer law was
    chosen. Where the held-out blocks could not tell the two apart, this is the departure the
    data did not rule out: the band of a nominal law the data chose (``learning.law_tables``)."""
    x = np.asarray(x, dtype=float)
    if not choice or choice.get("standin") is None or choice.get("richer"):
        return np.zeros_like(x)
    u = (x - float(choice["standin_center"])) / float(choice["standin_scale"])
    return np.abs(sum(float(b) * u**d for d, b in enumerate(choice["standin"])))


def poly_design(Z: np.ndarray, degree: int) -> np.ndarray:
    """All monomials of total degree <= ``degree`` (constant included) of the columns of Z (n, k),
    each column standardised over the rows first."""
    Z = np.asarray(Z, dtype=float)
    if Z.ndim == 1:
        Z = Z[:, None]
    sd = Z.std(0)
    U = (Z - Z.mean(0)) / np.where(sd > 0, sd, 1.0)
    cols = [np.ones(U.shape[0])]
    for d in range(1, degree + 1):
        cols += [np.prod(U[:, list(c)], axis=1) for c in combinations_with_replacement(range(U.shape[1]), d)]
    return np.stack(cols, axis=1)


def spline_basis(x: np.ndarray, degree: int, knots: int) -> np.ndarray:
    """Regression spline of ``degree`` in x (n,): the monomials of ``poly_design`` and truncated
    powers max(0, (x - c_i) / sd(x))^degree at ``knots`` interior quantiles c_i of x."""
    x = np.asarray(x, dtype=float).ravel()
    A = poly_design(x, degree)
    if knots <= 0:
        return A
    sd = float(x.std()) or 1.0
    c = np.quantile(x, np.linspace(0.0, 1.0, knots + 2)[1:-1])
    return np.column_stack([A, *(np.maximum(0.0, (x - ci) / sd) ** degree for ci in c)])


def compare_heldout(y: np.ndarray, A_simple: np.ndarray, A_richer: np.ndarray, blocks: int,
                    degree: int, offset: np.ndarray | None = None, pooled: bool = False,
                    either: bool = False) -> HeldoutChoice:
    """Held-out-block comparison (module docstring) of two laws linear in their coefficients:
    y ~ offset + A_simple a and y ~ offset + A_richer b (least squares on the blocks kept);
    ``A_simple`` may have no columns (the law is ``offset`` alone, e.g. the nominal law).
    ``pooled``: decide on the total held-out errors (``laws.pooled_gain``) instead of the
    per-block log ratios (``laws.consistent_gain``), or with ``either`` on whichever of the two
    shows a gain (module docstring); ``heldout_log_ratio`` is then the log of the totals' ratio
    and its se the jackknife's, the per-block statistics in ``perblock_log_ratio(_se)``."""
    y = np.asarray(y, dtype=float).ravel()
    r = y if offset is None else y - np.asarray(offset, dtype=float).ravel()
    n = y.size
    if blocks < 2:
        raise ValueError(f"held-out blocks: {blocks} blocks; at least 2 are needed")
    if n < blocks * (A_richer.shape[1] + 1):
        # too few samples to fit the richer law without a block: the data cannot show that it
        # predicts better, so the simpler law is kept (its statistics NaN)
        nan = float("nan")
        return HeldoutChoice(richer=False, heldout_mse_simple=nan, heldout_mse_richer=nan,
                             heldout_log_ratio=nan, heldout_log_ratio_se=nan, blocks=int(blocks),
                             degree=int(degree), perblock_log_ratio=nan if pooled else None,
                             perblock_log_ratio_se=nan if pooled else None)
    e_s = e_r = 0.0
    d, per_s, per_r = [], [], []
    for test in heldout_blocks(n, blocks):
        errs = []
        for A in (A_simple, A_richer):
            if A.shape[1] == 0:
                pred = np.zeros(int(test.sum()))
            else:
                coef, *_ = np.linalg.lstsq(A[~test], r[~test], rcond=None)
                pred = A[test] @ coef
            errs.append(float(np.sum((r[test] - pred) ** 2)))
        e_s, e_r = e_s + errs[0], e_r + errs[1]
        per_s.append(errs[0])
        per_r.append(errs[1])
        d.append(log_error_ratio(errs[0], errs[1]))
    per_block = consistent_gain(np.array(d))
    mean, se, gain = pooled_gain(np.array(per_s), np.array(per_r)) if pooled else per_block
    gain = gain or (pooled and either and per_block[2])
    # a simpler law exact to round-off (held-out rms error below sqrt(machine epsilon) x the
    # targets' rms: e.g. H_p = p / (rho A) of momenta derived from positions) leaves the richer
    # law nothing but round-off to fit, however consistently
    exact = math.sqrt(e_s / n) <= math.sqrt(np.finfo(float).eps) * float(np.sqrt(np.mean(y**2)))
    return HeldoutChoice(richer=bool(gain and not exact), heldout_mse_simple=e_s / n,
                         heldout_mse_richer=e_r / n, heldout_log_ratio=mean,
                         heldout_log_ratio_se=se, blocks=int(blocks), degree=int(degree),
                         perblock_log_ratio=per_block[0] if pooled else None,
                         perblock_log_ratio_se=per_block[1] if pooled else None)


def learned_or_nominal(X: np.ndarray, y: np.ndarray, nominal: np.ndarray, degree: int, blocks: int,
                       pooled: bool) -> HeldoutChoice:
    """Nominal law (``nominal``: its prediction at the samples) against the nominal law plus a
    polynomial of total degree ``degree`` in the law's inputs X (n, k); ``richer`` = learn it.
    ``pooled``: on the total held-out error or the per-block log ratios, whichever shows a gain
    (the bending law m, which departs from the nominal one at the large curvatures of a
    release's first blocks, or by a rest curvature in every block; module docstring), else on
    the per-block log ratios alone (n1, n2, whose targets carry the prefilter's or the position
    reconstruction's systematic errors, and the momentum maps p / (rho A), p / (rho I))."""
    A = poly_design(X, degree)
    choice = compare_heldout(y, np.zeros((A.shape[0], 0)), A, blocks, degree, offset=nominal, pooled=pooled,
                             either=pooled)
    X = np.asarray(X, dtype=float).reshape(A.shape[0], -1)
    if X.shape[1] != 1:
        return choice
    b, *_ = np.linalg.lstsq(A, np.asarray(y, dtype=float).ravel() - np.asarray(nominal, dtype=float).ravel(),
                            rcond=None)
    sd = float(X[:, 0].std())
    return replace(choice, standin=[float(v) for v in b], standin_center=float(X[:, 0].mean()),
                   standin_scale=sd if sd > 0 else 1.0)


def segment_weights(s: np.ndarray, m: np.ndarray) -> np.ndarray:
    """Weight of every sample: 1 / rms of the moment targets of its segment (the samples of one
    segment share their arclength s), so that each segment's error counts alike in the held-out
    comparison, not in proportion to its moments (largest at the clamp)."""
    s, m = np.asarray(s, dtype=float).ravel(), np.asarray(m, dtype=float).ravel()
    _, seg = np.unique(s, return_inverse=True)
    ms = np.bincount(seg, weights=m**2) / np.bincount(seg)
    rms = np.sqrt(ms)
    w = np.zeros_like(rms)
    w[rms > 0] = 1.0 / rms[rms > 0]
    return w[seg]


def arclength_dependence(kappa: np.ndarray, s: np.ndarray, m: np.ndarray, degree: int, knots: int,
                         s_degree: int, blocks: int, weights: str) -> HeldoutChoice:
    """A uniform bending law m(kappa) (``spline_basis(kappa, degree, knots)``) against one whose
    spline coefficients are polynomials of degree ``s_degree`` in the arclength s; ``richer`` =
    give the law s as an input. ``weights``: ``segment`` (weighted least squares and errors with
    ``segment_weights``: a law varying near the free tip, whose moments are small, is seen as one
    varying near the clamp is) or ``none``."""
    K = spline_basis(kappa, degree, knots)
    S = poly_design(s, s_degree)
    KS = np.einsum("ni,nj->nij", K, S).reshape(K.shape[0], -1)
    if weights == "none":
        return compare_heldout(m, K, KS, blocks, degree)
    if weights != "segment":
        raise ValueError(f"arclength weights {weights!r}: expected segment or none")
    w = segment_weights(s, m)
    y = np.asarray(m, dtype=float).ravel() * w
    return compare_heldout(y, K * w[:, None], KS * w[:, None], blocks, degree)


def bending_arclength(arr: dict[str, np.ndarray], params: RodParams, cam: dict[str, Any],
                      segments: np.ndarray | None, applicable: bool, from_positions: bool,
                      shown: bool = False) -> dict[str, Any]:
    """Whether the learned bending law m takes the arclength s as an input (manifest
    ``bending_arclength``): ``camera.learn.bending_arclength`` always / never, or with auto where
    the law's samples vary along the rod by the held-out time blocks
    (``arclength_dependence``: a regression spline in kappa against the same spline
    with coefficients polynomial in s). Only for the local law m(kappa) (``bending_inputs`` a
    subset without all five inputs) of a learned obj_m. ``shown``: the law was learned because a
    stand-in varying along the rod predicted the held-out blocks better than the nominal law
    (``grey_box``, ``law_choice.m.decided_by``): the data have shown it varies along s, and with
    auto it takes s. The comparisons are ``camera.learn.choice_s_tests`` of the record's kind
    (positions or full state), each ``[s_degree, weights]``; s is taken where any of them shows the
    law varying along s (``choice``: the first that does, else the first; ``choices``: all)."""
    setting = str(cam["bending_arclength"])
    if not applicable:
        return {"setting": setting, "used": False, "choice": None}
    choice, choices = None, []
    if setting == "auto":
        X, m = training_data(arr, params, "obj_m", None, segments)
        S = sample_arclength(params, segments, arr["x"].shape[0])
        for s_degree, weights in cam["choice_s_tests"]["positions" if from_positions else "full_state"]:
            c = arclength_dependence(X[:, 0], S, m, int(cam["choice_degree"]), int(cam["choice_knots"]),
                                     int(s_degree), int(cam["choice_blocks"]), str(weights)).to_dict()
            choices.append({**c, "s_degree": int(s_degree), "weights": str(weights)})
        choice = next((c for c in choices if c["richer"]), choices[0])
    used = setting == "always" or (setting == "auto" and (shown or (choice is not None and choice["richer"])))
    return {"setting": setting, "used": bool(used), "choice": choice, "choices": choices,
            "from_law_choice": bool(shown)}


def sample_arclength(params: RodParams, segments: np.ndarray | None, n_t: int) -> np.ndarray:
    """The arclength s of every sample of a segment law (``training_data``'s rows: time-major over
    the ``segments`` kept, all where None) of a record of ``n_t`` frames."""
    s = segment_arclength(params.N, params.ds)
    return np.tile(s if segments is None else s[segments], n_t)


def _may_take_s(cam: dict[str, Any]) -> bool:
    """Whether the bending law may take the arclength s as an input: the local law (``bending_inputs``
    not all five inputs) and ``bending_arclength`` not ``never``."""
    return str(cam["bending_arclength"]) != "never" and list(cam["bending_inputs"]) != list(OBJ_M_FEATURES)


def nominal_choice(man: dict[str, Any]) -> dict[str, Any] | None:
    """The ``law_choice`` entry of the bending law m where the data chose its nominal law (a
    manifest, or ``grey_box``'s result: ``nominal_laws`` holds m and ``law_choice`` decided), else
    None: the band of that nominal law (``standin_departure``)."""
    choice = (man.get("law_choice") or {}).get("m")
    return choice if choice and "m" in (man.get("nominal_laws") or []) and not choice["richer"] else None


def grey_box(arr: dict[str, np.ndarray], params: RodParams, x: np.ndarray, y: np.ndarray, features: str,
             cam: dict[str, Any], trim: int, from_positions: bool) -> dict[str, Any]:
    """Which constitutive laws come from the nominal rod (``learning.nominal``) and why.

    The strain SNR is measured (and recorded) for every input; the laws ``camera.learn.nominal_laws``
    names (or, with ``auto``, n1 / n2 where the strain SNR is below ``camera.learn.snr_min``, and
    n1 / n2 / m and the momentum maps where a learned law does not predict held-out time blocks
    consistently better than the nominal one: ``law_choice.learned_or_nominal``, recorded as
    ``law_choice``) replace the objective features' GPs. The paper's features have no separate
    stretch and shear law (q_x, q_y mix all three), so they are always learned in full.
    """
    sigma = position_noise_std(np.concatenate([x, y], axis=1))
    res = {k: training_data(arr, params, f"obj_{k}", None, inner_segments(params.N, trim))[1]
           for k in ("n1", "n2", "m")}
    snr = strain_snr(res, params, sigma)
    setting = cam["nominal_laws"]
    heldout = None
    if setting == "auto" and features == "objective":
        heldout = {}
        inner = inner_segments(params.N, trim)
        for k, (col, stiff, ref) in {"n1": (0, params.EA, params.nu1_0), "n2": (1, params.GA, params.nu2_0),
                                     "m": (0, params.EI, params.kappa0)}.items():
            X, y = training_data(arr, params, f"obj_{k}", None, inner)
            # the local bending law m(kappa); the stretch and shear laws of the strains they will be
            # learned from (camera.learn.strain_law_inputs)
            cols = [0] if k == "m" else strain_law_columns(cam["strain_law_inputs"], k)
            Xl = X if cols is None else X[:, cols]
            nominal = stiff * (X[:, col] - ref)
            heldout[k] = learned_or_nominal(Xl, y, nominal, int(cam["choice_degree"]),
                                            int(cam["choice_blocks"]), pooled=k == "m").to_dict()
            if k == "m":
                kappa_m, y_m, nominal_m = X[:, 0], y, nominal
        if not heldout["m"]["richer"] and _may_take_s(cam):
            # the nominal law is uniform along the rod: one that varies along it (a local defect
            # away from the clamp, whose curvatures a uniform stand-in averages away) is not it either
            s = sample_arclength(params, inner, arr["x"].shape[0])
            along = learned_or_nominal(np.c_[kappa_m, s], y_m, nominal_m, int(cam["choice_degree"]),
                                       int(cam["choice_blocks"]), pooled=True)
            heldout["m"] = {**heldout["m"], "along_s": along.to_dict(), "richer": bool(along.richer),
                            "decided_by": "along_s" if along.richer else "uniform"}
        for k in MOMENTUM_LAWS:  # the velocity maps H_p(p): nominal p / (rho A), p / (rho I)
            X, y = training_data(arr, params, NOMINAL_LAWS[k], None)
            heldout[k] = learned_or_nominal(X, y, NominalLaw(k, params)(X[:, 0]), int(cam["choice_degree"]),
                                            int(cam["choice_blocks"]), pooled=False).to_dict()
    chosen = choose_nominal(setting, snr, float(cam["snr_min"]), heldout)
    if setting == "auto" and from_positions:
        # positions rebuild the state without shear (learning/camera.py): the stretch and shear
        # strains, hence the n1 / n2 samples, are the reconstruction's, not the rod's, so those
        # laws are not learned from them whatever their SNR or held-out blocks say
        chosen = [k for k in NOMINAL_LAWS if k in chosen or k in ("n1", "n2")]
    if features != "objective":
        chosen = []
    return {"nominal_laws": chosen, "nominal_laws_setting": setting, "snr_min": float(cam["snr_min"]),
            "strains_from_positions": bool(from_positions),
            "law_choice": heldout, "position_noise_std_m_differences": sigma, "strain_snr": snr,
            "nominal_stiffness": {"EA": params.EA, "GA": params.GA, "nu1_0": params.nu1_0,
                                  "nu2_0": params.nu2_0}}
