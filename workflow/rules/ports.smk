# The actuated study (docs/ports.md, beyond the paper): records of the rod driven by named input
# sequences (ports.signals), CR-GPR learned from one of them with its inputs (crgpr learn --inputs;
# full state and 1 mm camera positions; the paper's features; the black-box GP baseline given the
# inputs), scored under sequences it never saw against the nominal physics prior with E off
# (results/tables/actuated_accuracy.csv, in `all`).

PORTS_STUDY = config["ports"]["study"]
PORTS_TRAIN = PORTS_STUDY["train_signal"]
PORTS_SIGNALS = [PORTS_TRAIN] + [s for s in PORTS_STUDY["test_signals"] if s != PORTS_TRAIN]
PORTS_MODELS = ["objective", "camera", "paper", "blackbox"]
_PORTS_GRID = ("simulation.dt_s", "simulation.record_every", "simulation.scheme")  # t_end: ports.study
_PORTS_REC = ("rod", *_PORTS_GRID, "ports.tendon_offset_m", "ports.study.theta0_deg", "ports.study.t_end_s")


rule actuated_data:
    input:
        code=code_closure("actuated_data.py"),
    output:
        traj=f"{RESULTS}/actuated/data/{{signal}}.parquet",
        energy=f"{RESULTS}/actuated/data/{{signal}}_energy.parquet",
        inputs=f"{RESULTS}/actuated/data/{{signal}}_inputs.parquet",
    wildcard_constraints:
        signal=_one_of(PORTS_SIGNALS),
    params:
        cfg=lambda wc: cfg_params(*_PORTS_REC, f"ports.signals.{wc.signal}"),
    log:
        "logs/actuated/data_{signal}.log",
    benchmark:
        "benchmarks/actuated/data_{signal}.tsv"
    threads: 1
    resources:
        mem_mb=750,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/actuated_data.py"


rule actuated_camera:
    input:
        code=code_closure("actuated_camera.py"),
        record=f"{RESULTS}/actuated/data/{PORTS_TRAIN}.parquet",
    output:
        f"{RESULTS}/actuated/data/{PORTS_TRAIN}_camera.parquet",
    params:
        cfg=cfg_params("seed", "ports.study.camera_rate_hz", "ports.study.camera_noise_m"),
    log:
        "logs/actuated/camera.log",
    benchmark:
        "benchmarks/actuated/camera.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/actuated_camera.py"


rule actuated_learn:
    input:
        code=code_closure("actuated_learn.py"),
        measured=lambda wc: f"{RESULTS}/actuated/data/{PORTS_TRAIN}"
        + ("_camera" if wc.model == "camera" else "") + ".parquet",
        inputs=f"{RESULTS}/actuated/data/{PORTS_TRAIN}_inputs.parquet",
    output:
        directory(f"{RESULTS}/actuated/models/{{model}}"),
    wildcard_constraints:
        model=_one_of(PORTS_MODELS),
    params:
        cfg=cfg_params("seed", "rod", "discovery.min_rate_hz", "discovery.min_samples", "discovery.outlier_k",
                       "discovery.outlier_min_m", "discovery.geometry_tol", "gradient_models", "camera.learn",
                       "simulation.dt_s", "simulation.record_every", "simulation.scheme",
                       "prefilter", "ports.tendon_offset_m", "ports.study.prefilter",
                       "ports.study.camera_prefilter", "ports.study.camera_n_t_out", "ports.study.n_train_max",
                       "ports.study.n_hyper_max", "ports.study.blackbox_n_train", "ports.study.blackbox_n_hyper",
                       "ports.study.nominal_laws",
                       "baselines.blackbox_gp"),
    log:
        "logs/actuated/learn_{model}.log",
    benchmark:
        "benchmarks/actuated/learn_{model}.tsv"
    threads: 1
    resources:
        mem_mb=4000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/actuated_learn.py"


rule actuated_accuracy:
    input:
        code=code_closure("actuated_accuracy.py"),
        records=expand(f"{RESULTS}/actuated/data/{{signal}}.parquet", signal=PORTS_SIGNALS),
        inputs=expand(f"{RESULTS}/actuated/data/{{signal}}_inputs.parquet", signal=PORTS_SIGNALS),
        models=expand(f"{RESULTS}/actuated/models/{{model}}", model=PORTS_MODELS),
    output:
        table=f"{RESULTS}/tables/actuated_accuracy.csv",
        figure=f"{RESULTS}/figures/actuated_tip.png",
    params:
        cfg=cfg_params("rod", *_PORTS_GRID, "ports.tendon_offset_m", "ports.study"),
        signals=PORTS_SIGNALS,
        models=PORTS_MODELS,
    log:
        "logs/actuated/accuracy.log",
    benchmark:
        "benchmarks/actuated/accuracy.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/actuated_accuracy.py"


ALL_TARGETS.extend([f"{RESULTS}/tables/actuated_accuracy.csv", f"{RESULTS}/figures/actuated_tip.png"])


# The learned models' trajectory bands under every sequence (posterior samples of their learned
# force laws through the one UQ path; docs/ports.md, "Uncertainty under inputs").
PORTS_UQ_MODELS = ["objective", "camera"]


rule actuated_uq:
    input:
        code=code_closure("actuated_uq.py"),
        records=expand(f"{RESULTS}/actuated/data/{{signal}}.parquet", signal=PORTS_SIGNALS),
        inputs=expand(f"{RESULTS}/actuated/data/{{signal}}_inputs.parquet", signal=PORTS_SIGNALS),
        models=expand(f"{RESULTS}/actuated/models/{{model}}", model=PORTS_UQ_MODELS),
    output:
        table=f"{RESULTS}/tables/actuated_uq.csv",
        figure=f"{RESULTS}/figures/actuated_uq.png",
    params:
        cfg=cfg_params("seed", "rod", *_PORTS_GRID, "ports.tendon_offset_m", "ports.study.theta0_deg",
                       "ports.study.t_end_s", "ports.uq", "uq"),
        signals=PORTS_SIGNALS,
        models=PORTS_UQ_MODELS,
    log:
        "logs/actuated/uq.log",
    benchmark:
        "benchmarks/actuated/uq.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/actuated_uq.py"


# In `sweeps` (Snakefile): beyond the run-time budget of `all` (docs/performance.md).
SWEEP_TARGETS.extend([f"{RESULTS}/tables/actuated_uq.csv", f"{RESULTS}/figures/actuated_uq.png"])
