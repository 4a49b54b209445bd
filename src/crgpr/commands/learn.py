"""``crgpr learn``: CR-GPR gradient models from a user's trajectory file (positions only or full state).

Input: the measured-data format of ``crgpr discover`` (Parquet or CSV by extension, one row
per (t, marker): ``t``, ``node`` or ``s``, ``x``, ``y``; validated by ``crgpr.measured``), or a
full-state file with ``theta, p_x, p_y, p_theta`` as well. Positions only: theta, momenta and
derivatives by ``crgpr.learning.camera`` (paper Sec. III-B Remark); full state: the stage-1 prefilter
(``crgpr.learning.prefilter``). The gradient GPs are then fitted by
``gradient_models.train_model_arrays``, exactly as in stage 2. The model's rod is the nominal
``rod`` of the config on the measured node grid (N = measured segments). The command takes
its configuration as ``crgpr simulate`` takes the rod (``crgpr.config.cli_config``: the
paper's rod by default, ``--config``, ``--set``).

Grey box (objective features, ``camera.learn.nominal_laws``): the stretch and shear laws n1, n2
that the positions cannot resolve come from the nominal rod (``learning.nominal.NominalLaw``)
and only the bending moment m (and the momentum maps) are learned; with ``auto`` the choice is
made from the strain signal-to-noise ratios and, for n1, n2 and m, from held-out time blocks
(``learning.law_choice``: the nominal law is kept unless a learned one predicts them
consistently better), which the manifest records with the decision (``law_choice``). Where the
data show the bending law varying along the rod (``camera.learn.bending_arclength``), m takes
the segment's arclength s as an input (manifest ``bending_arclength``).

MODEL_DIR holds one ``.npz`` + ``.json`` per gradient model and ``manifest.json`` (written
last; its presence marks a complete directory): features, prefilter, input kind, source file,
rod parameters, the configuration values used (``config``: its source, the ``--set`` overrides
and the sections read), the derived-state report (estimated noise level, frames used), the laws
taken from the nominal rod (``nominal_laws``, ``strain_snr``; ``models`` lists the learned ones)
and the seeds, so that ``crgpr rollout --models MODEL_DIR`` needs no method entry in the config.

The bending law's rest curvature and symmetry (``camera.learn.bending_symmetry: auto``) are
estimated from the data (``learning.laws``; manifest ``rest_state``, ``bending_odd_about``), and
the learned laws are shown as ``laws.parquet`` / ``laws.png`` (``learning.law_tables``,
``report.laws``; manifest ``law_inputs_covered``, ``law_table``, ``law_figure``). Beyond its
covered curvatures the bending law is the GP's mean while its band stays narrow, then its mirror
image about its rest curvature and its tangent (``camera.learn.extrapolation``,
``learning.extrapolation``; manifest ``bending_extrapolation``).

A passive bending damping m_d = c dkappa/dt, c >= 0 (a viscoelastic rod's), is fitted jointly
with an elastic law on the bending samples and kept only where held-out time blocks support it
(``camera.learn.bending_damping``, ``learning.damping``); the elastic laws are then learned
without it and the learned rod's R applies it (manifest ``bending_damping``).

The learned rod is then fitted to its own record by output error (``camera.learn.record_fit``,
``learning.record_fit``): from positions the record's start, from the full state its recorded
start as it is; the size of a kept damping (which the regression underestimates, and which a
bending law left nominal biases); and a warp of the bending law, kept only where it forecasts
the record's held-out last part better, with as many terms as that part supports (manifest
``record_fit``, ``bending_damping.coefficient``; every loader of the directory applies a kept
warp and the fitted c; ``laws.parquet`` shows the warped law, with the warp's coefficient
covariance in its band, also where the bending law itself is the nominal one). Where the laws
are learned or nominal as the data decide (``nominal_laws: auto``), the rod with every law
nominal forecasts the same held-out part too; where it does so consistently better, every law
is taken nominal (the learned ones listed in the manifest's ``models_refused``). Where a damping
is kept and the bending law learned, the nominal bending law with its own warp is fitted too and
taken where it follows the record better (``record_fit.bending_nominal``; ``obj_m`` refused).
"""

from __future__ import annotations

import copy
import math
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from crgpr.commands.learn_laws import bending_reach, law_outputs
from crgpr.commands.model_dir import (  # noqa: F401  (re-exported: the directory's readers)
    FEATURES,
    MANIFEST,
    learned_components,
    learned_damping,
    learned_models,
    load_learned,
    model_names,
    read_manifest,
)
from crgpr.config import ConfigError, add_config_options, cli_config, rod_params
from crgpr.gp.evaluators import load_evaluator
from crgpr.io import code_version, write_json
from crgpr.learning.camera import (
    PREFILTERS,
    SMOOTHED_WITH_MOMENT_PRIOR,
    LearnSettings,
    check_node_grid,
    curvature_calibration,
    positions_to_state,
)
from crgpr.learning.damping import learn_bending_damping, record_rmse_theta, refine_by_rollout
from crgpr.learning.extrapolation import Reach, TangentContinuation
from crgpr.learning.features import OBJ_M_FEATURES
from crgpr.learning.gradient_models import (
    KAPPA_CALIBRATION,
    MOMENTUM_MODELS,
    inner_segments,
    train_model_arrays,
    training_data,
)
from crgpr.learning.law_choice import bending_arclength, grey_box, nominal_choice
from crgpr.learning.laws import rest_state
from crgpr.learning.learned import LearnedRod
from crgpr.learning.nominal import NOMINAL_LAWS, NominalLaw, segment_curvature_snr
from crgpr.learning.prefilter import PrefilterSettings, prefilter, prefiltered_arrays
from crgpr.learning.record_fit import RecordFit, fit_record, tail_factor
from crgpr.learning.stiffness import stiffness_check, strain_law_columns
from crgpr.learning.warp import BendingWarp, manifest_warp, manifest_warp_cov, manifest_warp_truncation
from crgpr.measured.records import MeasuredDataError, ScreenSettings, read_measured, validate_frame
from crgpr.physics.params import RodParams, SimSettings
from crgpr.physics.ports import Ports, ports_from_config
from crgpr.physics.rod import node_weights
from crgpr.physics.signals import Inputs, read_inputs
from crgpr.physics.simulate import Trajectory

MOMENTUM_COLUMNS = ("p_x", "p_y", "p_theta")


def model_params(table: pd.DataFrame, cfg: dict[str, Any]) -> RodParams:
    """The model's rod: ``rod`` of the config on the node grid of a measured table.

    A table with a ``node`` column puts its markers at s = node * ds with N = its largest
    node (the camera's grid, ds = L0 / N); a table with ``s`` (markers anywhere) keeps the
    config's N, and the state is rebuilt on that grid (``learning.camera``). Values that are
    not numbers are left to the loader, which names them.
    """
    params = rod_params(cfg)
    if "node" not in table.columns:
        return params
    nodes = pd.to_numeric(table["node"], errors="coerce").to_numpy(dtype=float)
    n = int(np.nanmax(nodes)) if nodes.size and np.isfinite(nodes).any() else 0
    return replace(params, N=n) if n >= 1 else params


def full_state_momenta(df: pd.DataFrame, source: str, n_t: int, n_nodes: int
                        ) -> tuple[np.ndarray, np.ndarray] | None:
    """(n_t, N+1) theta and (n_t, N+1, 3) momenta of a full-state table, or None (positions only)."""
    present = [c for c in MOMENTUM_COLUMNS if c in df.columns]
    if not present:
        return None
    if len(present) < 3 or "theta" not in df.columns:
        missing = [c for c in ("theta", *MOMENTUM_COLUMNS) if c not in df.columns]
        raise MeasuredDataError(f"{source}: a full-state file needs theta, p_x, p_y, p_theta; "
                                f"missing {missing}")
    d = df.sort_values(["t", "node"], kind="stable")
    out = np.empty((n_t, n_nodes, 4))
    for k, c in enumerate((*MOMENTUM_COLUMNS, "theta")):
        v = pd.to_numeric(d[c], errors="coerce").to_numpy(dtype=float)
        if not np.all(np.isfinite(v)):
            raise MeasuredDataError(f"{source}: column {c!r} has {int((~np.isfinite(v)).sum())} "
                                    "non-numeric or non-finite value(s)")
        if v.size != n_t * n_nodes:
            raise MeasuredDataError(f"{source}: column {c!r} does not fill the (t, node) grid")
        out[..., k] = v.reshape(n_t, n_nodes)
    return out[..., 3], out[..., :3]


def port_inputs_per_length(arr: dict[str, np.ndarray], params: RodParams, inputs: Inputs, ports: Ports
                           ) -> np.ndarray:
    """G(z) u per unit length (n_t, N+1, 3) at the training frames ``arr`` (eq. (13)'s input term
    of the actuation channels), u interpolated to the frames' times."""
    q = np.stack([arr["x"], arr["y"], arr["theta"]], axis=-1)
    wds = node_weights(params.N) * params.ds
    return ports.nodal_forces(q, inputs.values(arr["t"])) / wds[:, None]


def used_config(cfg: dict[str, Any], kind: str) -> dict[str, Any]:
    """The configuration values ``learn`` reads for an input of ``kind`` (for the manifest)."""
    used = {"seed": cfg["seed"], "rod": cfg["rod"],
            "discovery": {k: cfg["discovery"][k] for k in ScreenSettings.config_keys()},
            "camera": {"learn": cfg["camera"]["learn"]}, "gradient_models": cfg["gradient_models"]}
    return {**used, "prefilter": cfg["prefilter"]} if kind == "full_state" else used


def capped_config(cfg: dict[str, Any], n_train_max: int, n_hyper_max: int, n_t_out: int) -> dict[str, Any]:
    """A copy of ``cfg`` for a study's ``learn`` calls (run-time budget): every gradient GP capped
    at ``n_train_max`` points and ``n_hyper_max`` for the likelihood search, camera models on
    ``n_t_out`` frames (``camera.learn.n_t_out``)."""
    out = copy.deepcopy(cfg)
    gm = out["gradient_models"]
    gm["n_hyper"] = min(int(gm["n_hyper"]), int(n_hyper_max))
    for group in ("models", "objective_models"):
        for spec in gm[group].values():
            spec["n_train"] = min(int(spec["n_train"]), int(n_train_max))
    out["camera"]["learn"]["n_t_out"] = int(n_t_out)
    return out

def learn(measured: str | Path, out_dir: str | Path, cfg: dict[str, Any], features: str = "objective",
          prefilter_method: str = "gp", inputs_file: str | Path | None = None,
          provenance: dict[str, Any] | None = None) -> dict[str, Any]:
    """Train the gradient models of ``features`` from a trajectory file (``.parquet`` or ``.csv``)
    into ``out_dir``.

    ``inputs_file``: the actuation inputs that drove the record (``physics.signals.read_inputs``:
    ``t`` and one column per channel, covering the record's time range); the targets subtract
    their G(z) u as eq. (13) does (``ports`` of the config: the G used is in the manifest).
    ``provenance`` (where ``cfg`` came from, ``cli_config``) goes to the manifest with the values
    used."""
    t_start = time.perf_counter()
    names = model_names(features)
    if prefilter_method not in PREFILTERS:
        raise ConfigError(f"unknown prefilter {prefilter_method!r}; expected one of {PREFILTERS}")
    if "camera" not in cfg:
        raise ConfigError("config: missing section 'camera'")
    cam = cfg["camera"]["learn"]
    st = LearnSettings.from_config(cam)
    if st.bending_targets == "smoothed" and st.moment_prior.passes > 0 and prefilter_method == "gp":
        raise ConfigError(SMOOTHED_WITH_MOMENT_PRIOR)
    disc = cfg["discovery"]
    table = read_measured(measured)
    params = model_params(table, cfg)
    meas = validate_frame(table, str(measured), params.L0, params.ds, ScreenSettings.from_config(disc))
    inputs = None if inputs_file is None else read_inputs(inputs_file, float(meas.t[-1]), float(meas.t[0]))
    ports = None if inputs is None else ports_from_config(cfg)
    seed = int(cfg["seed"]) + 3000
    full = full_state_momenta(table, str(measured), meas.t.size, meas.x.shape[1])
    if full is None:
        def add_inputs(a: dict[str, np.ndarray]) -> None:
            a["G_u"] = port_inputs_per_length(a, params, inputs, ports)

        arr, state_report = positions_to_state(meas, params, prefilter_method, st, seed, moment_prior=True,
                                               add_inputs=None if inputs is None else add_inputs)
        kind = "positions"
    else:
        check_node_grid(meas, params)
        theta, p = full
        traj = Trajectory(math.nan, meas.t, np.stack([meas.x, meas.y, theta], axis=-1), p, params)
        df, pmeta = prefilter(traj, prefilter_method, PrefilterSettings.from_config(cfg), seed)
        arr = prefiltered_arrays(df)
        state_report = {"prefilter": prefilter_method, "n_frames": int(meas.t.size),
                        "n_frames_used": int(arr["t"].size), "rate_hz": meas.rate_hz,
                        "n_nodes": int(meas.x.shape[1]), "prefilter_meta": pmeta}
        kind = "full_state"
    if inputs is not None:
        arr["G_u"] = port_inputs_per_length(arr, params, inputs, ports)
    # positions only: H_p = p / m holds exactly by construction, a noise floor keeps the 1D GPs
    # well conditioned (camera.learn.momentum_sigma_n_min, output units)
    cfg_m = copy.deepcopy(cfg)
    for m in MOMENTUM_MODELS:
        spec = cfg_m["gradient_models"]["models"][m]
        spec["sigma_n_min"] = max(float(spec["sigma_n_min"]), float(cam["momentum_sigma_n_min"]))
    trim = int(cam["trim_ends"]) if kind == "positions" else 0
    # the bending law's inputs (objective features): camera.learn.bending_inputs; the end segments
    # (trim_ends) are left out of the laws whose inputs hold the derived shear nu2, which the
    # extrapolated end angles corrupt (learning/camera.py)
    bend = [str(f) for f in cam["bending_inputs"]]
    if "kappa" not in bend or any(f not in OBJ_M_FEATURES for f in bend):
        raise ConfigError(f"camera.learn.bending_inputs: {bend}; expected kappa and a subset of "
                          f"{OBJ_M_FEATURES}")
    m_cols = None if features != "objective" or bend == list(OBJ_M_FEATURES) else [
        OBJ_M_FEATURES.index(f) for f in OBJ_M_FEATURES if f in bend]
    # the stretch and shear laws of their own strains (camera.learn.strain_law_inputs: own): with the
    # bending law of kappa, the learned laws are the gradient of one stored energy (learning/stiffness.py)
    n_cols = {f"obj_{k}": strain_law_columns(cam["strain_law_inputs"], k) if features == "objective" else None
              for k in ("n1", "n2")}
    if int(cam["rest_degree_max"]) < int(cam["rest_degree"]):
        raise ConfigError(f"camera.learn.rest_degree_max: {cam['rest_degree_max']} is below "
                          f"camera.learn.rest_degree ({cam['rest_degree']})")
    odd, sym = None, cam["bending_symmetry"]
    if sym in ("odd", "auto") and features == "objective" and bend != ["kappa"]:
        raise ConfigError(f"camera.learn.bending_symmetry: {sym} needs camera.learn.bending_inputs: [kappa]")
    if sym == "odd" and features == "objective":
        odd = float(params.kappa0)  # symmetric section: m(2 kappa0 - kappa) = -m(kappa)
    local_m = m_cols is not None and "nu2" not in bend
    if m_cols is not None and full is not None:  # the local law m(kappa[, s]) of a full state: its own floor
        cfg_m["gradient_models"]["objective_models"]["m"]["sigma_n_min"] = float(cam["bending_sigma_n_min"])
    m_mask = inner_segments(params.N, 0 if local_m else trim)
    keep_m, snr_m = None, None
    noise = state_report.get("kappa_noise_per_segment")
    if local_m and noise is not None:
        # the clamped angle fit knows each segment's curvature noise: the bending law keeps the
        # segments whose curvature SNR reaches camera.learn.snr_min (the tip's extrapolated ones do not)
        X_all, m_all = training_data(arr, params, "obj_m", None)
        shape = (arr["x"].shape[0], params.N)
        noise_sd = np.array(noise, dtype=float)
        snr_m = segment_curvature_snr(m_all.reshape(shape), params.EI, noise_sd)
        keep_m = snr_m >= float(cam["snr_min"])
        m_mask = keep_m
        if cam["curvature_calibration"] == "regression":
            # errors in variables: every use of the law's curvature samples (damping, law choice, rest
            # state, the GP, the record fit's reach) sees E[kappa | kappa_hat] per segment
            arr[KAPPA_CALIBRATION] = curvature_calibration(X_all[:, 0].reshape(shape), noise_sd)
    damping = None
    if features == "objective" and m_mask.sum() >= 2:
        # a passive bending damping c dkappa/dt from the bending law's samples (learning/damping.py),
        # decided before the laws are: where kept, every law (and its learned-or-nominal choice) is
        # learned from targets without it
        arr, damping = learn_bending_damping(arr, params, m_mask, cam["bending_damping"])
    grey = grey_box(arr, params, meas.x, meas.y, features, cam, trim, kind == "positions")
    trained = [n for n in names if n not in {NOMINAL_LAWS[k] for k in grey["nominal_laws"]}]
    trims = {n: trim for n in trained}
    masks = {n: inner_segments(params.N, trim) for n in trained}
    if local_m and "obj_m" in trained:
        trims["obj_m"] = 0
        masks["obj_m"] = m_mask
        if keep_m is not None and keep_m.sum() < 2:
            raise ValueError(f"{measured}: the positions resolve the curvature of {int(keep_m.sum())} "
                             f"segment(s) (SNR >= camera.learn.snr_min = {cam['snr_min']}); "
                             "too noisy to learn a bending law")
    along_s = bending_arclength(arr, params, cam, masks.get("obj_m"),
                                features == "objective" and "obj_m" in trained and m_cols is not None,
                                kind == "positions",
                                ((grey["law_choice"] or {}).get("m") or {}).get("decided_by") == "along_s")
    rest = None
    if sym == "auto" and features == "objective" and "obj_m" in trained:
        # the rest curvature and the symmetry from the data (learning/laws.py), on the law's own samples;
        # a law that varies along s: each segment's law has coefficients of its own about one rest
        # curvature, and is mirrored only about the nominal kappa0, where the data cannot tell it from c (a
        # rest curvature other than the declared one may vary along s, which one c cannot represent)
        Xm, ym = training_data(arr, params, "obj_m", None, masks["obj_m"])
        n_seg = int(np.count_nonzero(masks["obj_m"]))
        groups = np.tile(np.arange(n_seg), Xm.shape[0] // n_seg) if along_s["used"] else None
        rest = rest_state(Xm[:, 0], ym, int(cam["rest_degree"]), int(cam["rest_blocks"]), groups,
                          float(params.kappa0), int(cam["rest_degree_max"]))
        odd = rest.mirror_about(float(params.kappa0), estimate=not along_s["used"])
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {out}: exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    (out / MANIFEST).unlink(missing_ok=True)
    reports = {}
    for name in trained:
        meta = train_model_arrays(cfg_m, name, arr, params, out / name, str(measured), prefilter_method,
                                  extra={"input": kind}, segments=masks[name],
                                  columns=m_cols if name == "obj_m" else n_cols.get(name),
                                  odd_about=odd if name == "obj_m" else None,
                                  arclength=name == "obj_m" and along_s["used"])
        reports[name] = {k: meta[k] for k in ("n", "seconds", "approx_error_vs_exact") if k in meta}
    record_fit = features == "objective" and cam["record_fit"]["mode"] == "auto"
    if damping is not None and damping.kept and not record_fit:  # else the record fit sizes c (with the law)
        rmse = _record_rmse(cfg, out, arr, params, features, grey["nominal_laws"], trained, inputs, ports)
        damping = refine_by_rollout(damping, rmse, cam["bending_damping"])
    fit, refused, reach = None, [], None
    rest_c = odd if odd is not None else (None if rest is None else rest.kappa_rest)
    if record_fit:
        center = float(params.kappa0) if rest_c is None else rest_c
        if "obj_m" in trained:  # the law beyond its reach as the rollouts will integrate it
            reach = bending_reach(out, params, cam, seed, rest_c)
        kappa = training_data(arr, params, "obj_m", None, masks.get("obj_m", m_mask))[0][:, 0]
        learned_any = bool(trained) or (damping is not None and damping.kept)  # else: the nominal rod
        auto = cam["nominal_laws"] == "auto"
        # a damped rod's learned bending law against the nominal one, warped (learning/record_fit.py)
        bending_scale = (float(np.max(np.abs(kappa - params.kappa0))) if auto and "obj_m" in trained
                         and damping is not None and damping.kept else None)

        def fit_with(nominal: list[str], laws: list[str]) -> RecordFit:
            return _record_fit(cfg, out, arr, params, nominal, laws, inputs, ports, center,
                               float(np.max(np.abs(kappa - center))),
                               0.0 if damping is None else damping.coefficient, kind == "full_state",
                               auto and learned_any, bending_scale,
                               _profile_terms(cfg, "obj_m" in laws and kind != "full_state", along_s["used"],
                                              odd is not None and odd != float(params.kappa0)), reach)
        fit = fit_with(grey["nominal_laws"], trained)
        grey = {**grey, "strain_laws_nominal_by_record_fit": False}
        strain = [m for m in trained if m in ("obj_n1", "obj_n2")]
        if fit.nominal_fallback and strain and auto:
            # the learned rod follows its record worse than the nominal one: the stretch and shear
            # laws (whose targets the prefilter smooths most) are taken nominal first, the rest kept
            # where that rod no longer falls back (docs/learned-laws.md, "Learned or nominal")
            nominal = [k for k in NOMINAL_LAWS if k in {*grey["nominal_laws"], "n1", "n2"}]
            retry = fit_with(nominal, [m for m in trained if m not in strain])
            if not retry.nominal_fallback:
                fit, refused, trained = retry, strain, [m for m in trained if m not in strain]
                grey = {**grey, "nominal_laws": nominal, "strain_laws_nominal_by_record_fit": True}
        if damping is not None and damping.kept:
            damping = replace(damping, coefficient=fit.damping, c_record_fit=fit.damping)
        if reach is not None:  # the tangent's tail factor the fit sized (1 where no warp was kept)
            reach = replace(reach, slope_factor=math.exp(fit.tail_log_factor))
        if fit.bending_nominal:  # the nominal bending law, warped, follows the record better
            refused, trained = [*refused, "obj_m"], [m for m in trained if m != "obj_m"]
            grey = {**grey, "nominal_laws": [k for k in NOMINAL_LAWS if k in {*grey["nominal_laws"], "m"}]}
        if fit.nominal_fallback:  # the learned laws forecast the record worse than the nominal rod
            refused, trained = [*refused, *trained], []
            grey = {**grey, "nominal_laws": list(NOMINAL_LAWS)}
            if damping is not None:
                damping = replace(damping, kept=False, coefficient=0.0)
    laws = law_outputs(out, trained, params, cam["law_table"], seed,
                       None if fit is None else manifest_warp(fit.to_dict()),
                       None if fit is None else manifest_warp_cov(fit.to_dict()), cam["extrapolation"],
                       rest_c, reach if "obj_m" in trained else None,
                       None if fit is None else manifest_warp_truncation(fit.to_dict()),
                       nominal_choice(grey))
    manifest = {"kind": "crgpr_models", "features": features, "prefilter": prefilter_method, "input": kind,
                "source": str(measured), "rod": params.to_dict(),
                "config": {**(provenance or {}), **used_config(cfg, kind)}, "state": state_report,
                "trim_ends": trim, "trim_ends_per_model": trims,
                "bending_segments_kept": None if keep_m is None else np.flatnonzero(keep_m).tolist(),
                "bending_segment_snr": None if snr_m is None else [round(float(v), 3) for v in snr_m],
                "curvature_calibration": None if KAPPA_CALIBRATION not in arr else
                {"setting": cam["curvature_calibration"],
                 "lambda": [round(float(v), 5) for v in np.asarray(arr[KAPPA_CALIBRATION])[1]]},
                "bending_inputs": bend if features == "objective" else None, "bending_odd_about": odd,
                "bending_symmetry": sym if features == "objective" else None,
                "rest_state": None if rest is None else rest.to_dict(), "bending_arclength": along_s,
                "bending_damping": None if damping is None else damping.to_dict(),
                "record_fit": None if fit is None else fit.to_dict(),
                "models": trained, "models_refused": refused, **grey, **laws,
                "inputs": None if inputs is None else inputs.describe(),
                "ports": None if ports is None else ports.to_dict(),
                "model_reports": reports, "seed": seed}
    if features == "objective":  # is the learned force field a gradient (learning/stiffness.py)
        comps, _ = learned_components(out, manifest, lambda m: load_evaluator(out / m))
        rod = LearnedRod(comps, features, params, None, learned_damping(manifest))
        q = np.stack([arr["x"], arr["y"], arr["theta"]], axis=-1)
        manifest["stiffness_check"] = stiffness_check(rod, q, int(cam["stiffness_frames"]))
    manifest.update(seconds=time.perf_counter() - t_start, code_version=code_version())
    write_json(manifest, out / MANIFEST)
    return manifest


def _record_rmse(cfg: dict[str, Any], out: Path, arr: dict[str, np.ndarray], params: RodParams,
                 features: str, nominal: list[str], trained: list[str], inputs: Inputs | None,
                 ports: Ports | None) -> Callable[[float], float]:
    """c -> RMSE of theta of the models just written to ``out`` with bending damping c over the
    training record (``learning.damping.record_rmse_theta``)."""
    man = {"rod": params.to_dict(), "features": features, "nominal_laws": nominal, "models": trained}
    comps, center = learned_components(out, man, lambda m: load_evaluator(out / m))
    return record_rmse_theta(comps, features, params, center, _record_settings(cfg, arr, params), arr,
                             inputs, ports)


def _record_fit(cfg: dict[str, Any], out: Path, arr: dict[str, np.ndarray], params: RodParams,
                nominal: list[str], trained: list[str], inputs: Inputs | None, ports: Ports | None,
                center: float, kappa_scale: float, damping: float, exact_start: bool,
                against_nominal: bool, bending_scale: float | None = None,
                profile_terms: tuple[int, int, bool] = (0, 0, True), reach: Reach | None = None) -> RecordFit:
    """``learning.record_fit.fit_record`` of the objective models just written to ``out`` (with
    the kept bending damping c, whose size it fits too) on the training record ``arr`` (the
    full state: ``exact_start``); with ``against_nominal`` (the laws learned or nominal as the
    data decide, ``nominal_laws: auto``, and some law or a damping learned) the learned rod is
    also compared with the nominal one; with ``bending_scale`` (a damped rod's learned bending
    law) with the rod whose bending law is the nominal one, warped about kappa0 on that scale;
    with ``profile_terms`` (S, R, level) a profile along s is offered too (``_profile_terms``); with
    ``reach`` the warped law is continued beyond it (``learning.extrapolation``) in every
    rollout of the fit, as the model's rollouts will continue it."""
    man = {"rod": params.to_dict(), "features": "objective", "nominal_laws": nominal, "models": trained}
    comps, _ = learned_components(out, man, lambda m: load_evaluator(out / m))
    rf = cfg["camera"]["learn"]["record_fit"]
    K = max(int(k) for k in rf["warp_terms"])
    S, R, level = profile_terms

    def law_rod(W: np.ndarray, c: float) -> LearnedRod:
        m = BendingWarp(comps["obj_m"], center, kappa_scale, W[:, :K], W[:, K:K + S], W[:, K + S:K + S + R])
        if reach is not None:  # the law beyond its reach with each row's tail factor
            m = TangentContinuation(m, reach, tail_factor(W[:, K + S + R]))
        return LearnedRod({**comps, "obj_m": m}, "objective", params, None, c)
    nominal = (LearnedRod({c: NominalLaw(k, params) for k, c in NOMINAL_LAWS.items()}, "objective", params,
                          None, 0.0) if against_nominal else None)
    bending = None
    if bending_scale is not None:
        m0 = NominalLaw("m", params)

        def nominal_bending(W: np.ndarray, c: float) -> LearnedRod:
            m = BendingWarp(m0, float(params.kappa0), bending_scale, W[:, :K])
            return LearnedRod({**comps, "obj_m": m}, "objective", params, None, c)
        bending = (nominal_bending, float(params.kappa0), bending_scale)
    return fit_record(law_rod, arr, params, _record_settings(cfg, arr, params), center, kappa_scale,
                      rf, inputs, ports, damping, exact_start, nominal, bending, (S, R), reach is not None,
                      rest_level=level)


def _profile_terms(cfg: dict[str, Any], from_positions: bool, along_s: bool,
                   estimated_rest: bool) -> tuple[int, int, bool]:
    """(S, R, level) of the profile along s the record fit offers
    (``camera.learn.record_fit.profile``; ``learning.record_fit.fit_record``'s ``profile_terms``
    and ``rest_level``) to a bending law learned from positions: to a law along s (the arclength
    test) the stiffness factor and the rest shift with its level (their curvature reconstruction
    smooths the law along s); to a law without s mirrored about a rest curvature the data
    estimated (``estimated_rest``, not the nominal kappa0) the rest shift's variation along s
    alone, ``estimated_rest_terms`` Legendre terms P_1.. (the level stays the estimate: one c
    cannot hold a rest curvature that varies along the rod, and the arclength test has little
    power for it, a rest curvature shifting the moment by EI dkappa only); else none."""
    p = cfg["camera"]["learn"]["record_fit"]["profile"]
    along = int(p["estimated_rest_terms"])
    if from_positions and along_s:
        return int(p["stiffness_terms"]), int(p["rest_terms"]), True
    if from_positions and estimated_rest and along:
        return 0, along + 1, False
    return 0, 0, True


def _record_settings(cfg: dict[str, Any], arr: dict[str, np.ndarray], params: RodParams) -> SimSettings:
    """The config's step and scheme (the keys the rules pass: ``dt_s``, ``record_every``,
    ``scheme``) over the training record, checked for the model's rod (the rollouts over the
    record set its frames: ``learned.record_settings``)."""
    sim = cfg["simulation"]
    return checked_step(SimSettings(dt=float(sim["dt_s"]), t_end=float(arr["t"][-1] - arr["t"][0]),
                                    record_every=int(sim["record_every"]), scheme=str(sim["scheme"])), params)


def checked_step(st: SimSettings, params: RodParams) -> SimSettings:
    """``st`` if its step is stable for the model's rod, else a one-line ConfigError."""
    if st.dt >= params.dt_stable():
        raise ConfigError(f"simulation.dt_s = {st.dt:g} s is too large for the model's rod (N = {params.N}): "
                          f"need < {params.dt_stable():.3g} s")
    return st


def add_cli(sub: Any) -> None:
    p = sub.add_parser("learn", help="train CR-GPR gradient models from a trajectory file",
                       description="Train the gradient GPs of CR-GPR from measured positions "
                                   "(t, node or s, x, y) or a full-state file (t, node, x, y, theta, p_x, "
                                   "p_y, p_theta); theta and momenta are derived from positions "
                                   "with the nominal rod's mass distribution.")
    p.add_argument("--measured", required=True,
                   help="Parquet or CSV file, by extension (the format of crgpr discover)")
    p.add_argument("--out", required=True, help="model directory to write (npz/json + manifest.json)")
    p.add_argument("--features", choices=FEATURES, default="objective")
    p.add_argument("--prefilter", choices=PREFILTERS, default="gp")
    p.add_argument("--inputs", help="actuation inputs that drove the record: Parquet or CSV with t [s] "
                   "and one column per channel (tip_force_x, tip_force_y, tip_moment, tendon_tension); "
                   "docs/ports.md")
    add_config_options(p, "the nominal rod, camera.learn, gradient_models")
    p.set_defaults(func=_cli)


def _cli(args: Any) -> None:
    cfg, provenance = cli_config(args.config, args.set)
    man = learn(args.measured, args.out, cfg, args.features, args.prefilter, args.inputs, provenance)
    noise = man["state"].get("noise_std_m_estimated")
    print(f"learned {man['features']} models ({man['prefilter']} prefilter, {man['input']} input, "
          f"N = {man['rod']['N']}" + (f", noise {noise * 1e3:.3g} mm" if noise else "") +
          f") in {man['seconds']:.1f} s; written to {args.out}")
    tangent = man.get("bending_tangent")
    if tangent and tangent["min_over_EI"] < 0:  # a passive elastic law is monotone (docs/learned-laws.md)
        print(f"warning: the bending law's tangent stiffness is negative inside its covered range "
              f"({tangent['min_over_EI']:.3g} EI at kappa = {tangent['at_kappa']:.3g} 1/m, segment "
              f"{tangent['segment']}; manifest bending_tangent)", file=sys.stderr)


__all__ = ["learn", "load_learned", "learned_components", "learned_damping", "learned_models",
           "read_manifest", "model_names"]
