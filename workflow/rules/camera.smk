# Learning CR-GPR from camera data (beyond the paper): the camera version of the
# training trajectory (positions only, noise, the camera's frame rate), `crgpr learn` on it,
# method cr_gpr_objective_camera on the test angles (in `all`), and the noise ablation the paper
# claims (target `sweeps`, not in `all`).

import copy

CAM = config["camera"]
CAM_ABL = CAM["ablation"]
CAM_TRAIN = config["angles"]["train_deg"]
CAM_NOISE = f"{CAM['data']['noise_std_m'] * 1e3:g}"
from crgpr.config import CAMERA_METHOD as CAM_METHOD

ROLLOUT_METHODS.append(CAM_METHOD)
CAM_MODEL_DIR = f"{RESULTS}/camera/models/main/{CAM_NOISE}mm_{CAM['method']['prefilter']}_{CAM['method']['features']}"
LEARNED_MODEL_DIRS[CAM_METHOD] = CAM_MODEL_DIR  # a `crgpr learn` directory: uq.smk samples it as a whole
_CAM_CELLS = [(f"{n:g}", p, f) for n in CAM_ABL["noise_mm"] for p in CAM_ABL["prefilters"]
              for f in CAM_ABL["features"]]
# the config values `crgpr learn` reads (nominal rod, loader limits, gradient GPs, camera.learn, and the
# integrator settings of a learned damping's rollouts);
# the ablation cells train on fewer frames and points (camera.ablation.n_t_out, n_train_max, n_hyper_max) and
# take their grey-box choice from camera.ablation.nominal_laws (one model class for every noise level)
_LEARN_CFG = {
    "main": {"seed": config["seed"], "rod": config["rod"],
             "discovery": {k: config["discovery"][k] for k in ("min_rate_hz", "min_samples", "outlier_k",
                                                          "outlier_min_m", "geometry_tol")},
             "gradient_models": config["gradient_models"], "camera": {"learn": CAM["learn"]},
             "simulation": {k: config["simulation"][k] for k in ("dt_s", "record_every", "scheme")}},
}
_LEARN_CFG["main"] = copy.deepcopy(_LEARN_CFG["main"])
_LEARN_CFG["main"]["camera"]["learn"]["nominal_laws"] = CAM["method"]["nominal_laws"]
_LEARN_CFG["ablation"] = copy.deepcopy(_LEARN_CFG["main"])
_LEARN_CFG["ablation"]["camera"]["learn"]["n_t_out"] = CAM_ABL["n_t_out"]
_LEARN_CFG["ablation"]["camera"]["learn"]["nominal_laws"] = CAM_ABL["nominal_laws"]
_LEARN_CFG["ablation"]["gradient_models"]["n_hyper"] = min(config["gradient_models"]["n_hyper"], CAM_ABL["n_hyper_max"])
for _group in ("models", "objective_models"):
    for _spec in _LEARN_CFG["ablation"]["gradient_models"][_group].values():
        _spec["n_train"] = min(_spec["n_train"], CAM_ABL["n_train_max"])


rule camera_data:
    input:
        code=code_closure("camera_data.py"),
        gt=f"{RESULTS}/ground_truth/{CAM_TRAIN}.parquet",
    output:
        f"{RESULTS}/camera/data/{CAM_TRAIN}_{{noise}}mm.parquet",
    wildcard_constraints:
        noise=r"[0-9.]+",
    params:
        sample_rate_hz=CAM["data"]["sample_rate_hz"],
        seed=config["seed"],
    log:
        "logs/camera/data_{noise}mm.log",
    benchmark:
        "benchmarks/camera/data_{noise}mm.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/camera_data.py"


rule camera_learn:
    input:
        code=code_closure("camera_learn.py"),
        measured=f"{RESULTS}/camera/data/{CAM_TRAIN}_{{noise}}mm.parquet",
    output:
        directory(f"{RESULTS}/camera/models/{{set}}/{{noise}}mm_{{prefilter}}_{{features}}"),
    wildcard_constraints:
        set="main|ablation",
        noise=r"[0-9.]+",
        prefilter="gp|fd",
        features="paper|objective",
    params:
        cfg=lambda wc: _LEARN_CFG[wc.set],
    log:
        "logs/camera/learn_{set}_{noise}mm_{prefilter}_{features}.log",
    benchmark:
        "benchmarks/camera/learn_{set}_{noise}mm_{prefilter}_{features}.tsv"
    priority: 10  # long and ready early: started first, so short jobs fill the end of the run
    threads: 1
    resources:
        mem_mb=4750,
        runtime=15,
    conda:
        ENV
    script:
        "../scripts/camera_learn.py"


rule camera_rollout:
    input:
        code=code_closure("camera_rollout.py"),
        models=CAM_MODEL_DIR,
    output:
        # all test angles in one job
        traj=expand(f"{RESULTS}/rollouts/{CAM_METHOD}/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
        energy=expand(f"{RESULTS}/rollouts/{CAM_METHOD}/{{angle}}_energy.parquet",
                      angle=config["angles"]["test_deg"]),
    params:
        cfg={"simulation": config["simulation"]},
        angles=config["angles"]["test_deg"],
    log:
        f"logs/rollouts/{CAM_METHOD}.log",
    benchmark:
        "benchmarks/rollouts/cr_gpr_objective_camera.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/camera_rollout.py"


rule camera_ablation_cell:
    input:
        code=code_closure("camera_ablation_cell.py"),
        models=f"{RESULTS}/camera/models/ablation/{{noise}}mm_{{prefilter}}_{{features}}",
        gts=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=CAM_ABL["angles_deg"]),
    output:
        f"{RESULTS}/camera/ablation/{{noise}}mm_{{prefilter}}_{{features}}.json",
    wildcard_constraints:
        noise=r"[0-9.]+",
        prefilter="gp|fd",
        features="paper|objective",
    params:
        cfg={"simulation": config["simulation"]},
        angles=CAM_ABL["angles_deg"],
        t_end=lambda wc: CAM_ABL["t_end_s"][wc.features],
    log:
        "logs/camera/ablation_{noise}mm_{prefilter}_{features}.log",
    benchmark:
        "benchmarks/camera/ablation_{noise}mm_{prefilter}_{features}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=20,
    conda:
        ENV
    script:
        "../scripts/camera_ablation_cell.py"


rule camera_ablation:
    input:
        code=code_closure("camera_ablation.py"),
        cells=[f"{RESULTS}/camera/ablation/{n}mm_{p}_{f}.json" for n, p, f in _CAM_CELLS],
    output:
        table=report(
            f"{RESULTS}/tables/noise_ablation.csv",
            caption="../report/noise_ablation.rst",
            category="Camera data",
        ),
        figure=report(
            f"{RESULTS}/figures/noise_ablation.png",
            caption="../report/noise_ablation.rst",
            category="Camera data",
        ),
    params:
        noise_mm=CAM_ABL["noise_mm"],
        prefilters=CAM_ABL["prefilters"],
        features=CAM_ABL["features"],
    log:
        "logs/camera/ablation.log",
    benchmark:
        "benchmarks/camera/ablation.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/camera_ablation.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/rollouts/{CAM_METHOD}/{{angle}}.parquet", angle=config["angles"]["test_deg"])
)


# The noise ablation (len(noise_mm) x len(prefilters) x len(features) trainings) does not fit
# the time budget of `all`: it is part of the named target `snakemake sweeps` (Snakefile). Rule
# paper_tables does not read its table (the claims on it are left out of paper_claims.csv in
# `all`, report.paper.sweep_claims); after `snakemake sweeps`, `crgpr paper-tables` adds them.
SWEEP_TARGETS.extend(rules.camera_ablation.output)

