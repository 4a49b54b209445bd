# The materials study (docs/materials.md, "The materials study"; beyond the paper): for each case of
# `materials_study.cases` (a rod.material overlay of the true rod), crgpr learn on its full state and on
# 1 mm camera positions of its release at theta0_deg, the learned and the nominal rod rolled out at the
# test angles against the true rod, and the learned bending law against the true one
# (results/tables/material_laws.csv and results/figures/material_<case>.png, in `all`), the models
# learned under the study's run-time caps; the camera records learned with crgpr learn's own settings
# instead (source camera_defaults): results/tables/material_laws_camera_defaults.csv, in `sweeps`.

MATERIAL_CASES = list(config["materials_study"]["cases"])
MATERIAL_INPUTS = ["full_state", "camera"]
MATERIAL_SOURCES = [*MATERIAL_INPUTS, "camera_defaults"]
_MATERIAL_SIM = ("simulation.dt_s", "simulation.record_every", "materials_study.scheme")
_MATERIAL_REC = ("seed", "rod", *_MATERIAL_SIM, "materials_study.theta0_deg", "materials_study.t_end_s",
                 "materials_study.test_deg", "materials_study.rollout_t_end_s", "materials_study.camera_rate_hz",
                 "materials_study.camera_noise_m")


rule material_data:
    input:
        code=code_closure("material_data.py"),
    output:
        train=f"{RESULTS}/materials/{{case}}/train.parquet",
        camera=f"{RESULTS}/materials/{{case}}/camera.parquet",
        test=f"{RESULTS}/materials/{{case}}/test.parquet",
    wildcard_constraints:
        case=_one_of(MATERIAL_CASES),
    params:
        cfg=lambda wc: cfg_params(*_MATERIAL_REC, f"materials_study.cases.{wc.case}"),
    log:
        "logs/materials/data_{case}.log",
    benchmark:
        "benchmarks/materials/data_{case}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/material_data.py"


rule material_learn:
    input:
        code=code_closure("material_learn.py"),
        measured=lambda wc: f"{RESULTS}/materials/{wc.case}/"
        + ("train" if wc.source == "full_state" else "camera") + ".parquet",
    output:
        directory(f"{RESULTS}/materials/{{case}}/models/{{source}}"),
    wildcard_constraints:
        case=_one_of(MATERIAL_CASES),
        source=_one_of(MATERIAL_SOURCES),
    params:
        cfg=cfg_params("seed", "rod", "discovery.min_rate_hz", "discovery.min_samples", "discovery.outlier_k",
                       "discovery.outlier_min_m", "discovery.geometry_tol", "gradient_models", "camera.learn",
                       "simulation.dt_s", "simulation.record_every", "simulation.scheme",
                       "prefilter", "materials_study.prefilter", "materials_study.camera_prefilter",
                       "materials_study.camera_n_t_out", "materials_study.n_train_max",
                       "materials_study.n_hyper_max"),
    log:
        "logs/materials/learn_{case}_{source}.log",
    benchmark:
        "benchmarks/materials/learn_{case}_{source}.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/material_learn.py"


rule material_score:
    input:
        code=code_closure("material_score.py"),
        model=f"{RESULTS}/materials/{{case}}/models/{{source}}",
        train=f"{RESULTS}/materials/{{case}}/train.parquet",
        test=f"{RESULTS}/materials/{{case}}/test.parquet",
    output:
        scores=f"{RESULTS}/materials/{{case}}/scores_{{source}}.parquet",
        tips=f"{RESULTS}/materials/{{case}}/tips_{{source}}.parquet",
    wildcard_constraints:
        case=_one_of(MATERIAL_CASES),
        source=_one_of(MATERIAL_SOURCES),
    params:
        cfg=lambda wc: cfg_params("seed", "rod", *_MATERIAL_SIM, "camera.learn.law_table",
                                  "materials_study.test_deg", "materials_study.rollout_t_end_s",
                                  f"materials_study.cases.{wc.case}"),
    log:
        "logs/materials/score_{case}_{source}.log",
    benchmark:
        "benchmarks/materials/score_{case}_{source}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/material_score.py"


rule material_laws:
    input:
        code=code_closure("material_laws.py"),
        scores=expand(f"{RESULTS}/materials/{{case}}/scores_{{source}}.parquet", case=MATERIAL_CASES,
                      source=MATERIAL_INPUTS),
        tips=expand(f"{RESULTS}/materials/{{case}}/tips_{{source}}.parquet", case=MATERIAL_CASES,
                    source=MATERIAL_INPUTS),
        models=expand(f"{RESULTS}/materials/{{case}}/models/{{source}}", case=MATERIAL_CASES,
                      source=MATERIAL_INPUTS),
        trains=expand(f"{RESULTS}/materials/{{case}}/train.parquet", case=MATERIAL_CASES),
    output:
        table=report(f"{RESULTS}/tables/material_laws.csv", caption="../report/material_laws.rst",
                     category="Materials study"),
        figures=[report(f, caption="../report/material_laws.rst", category="Materials study")
                 for f in expand(f"{RESULTS}/figures/material_{{case}}.png", case=MATERIAL_CASES)],
    params:
        cfg=cfg_params("rod", "materials_study.cases"),
        cases=MATERIAL_CASES,
    log:
        "logs/materials/laws.log",
    benchmark:
        "benchmarks/materials/laws.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/material_laws.py"


rule material_laws_defaults:
    input:
        code=code_closure("material_laws_defaults.py"),
        scores=expand(f"{RESULTS}/materials/{{case}}/scores_camera_defaults.parquet", case=MATERIAL_CASES),
    output:
        table=f"{RESULTS}/tables/material_laws_camera_defaults.csv",
    log:
        "logs/materials/laws_camera_defaults.log",
    benchmark:
        "benchmarks/materials/laws_camera_defaults.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/material_laws_defaults.py"


SWEEP_TARGETS.append(f"{RESULTS}/tables/material_laws_camera_defaults.csv")
ALL_TARGETS.extend([f"{RESULTS}/tables/material_laws.csv",
                    *expand(f"{RESULTS}/figures/material_{{case}}.png", case=MATERIAL_CASES)])
