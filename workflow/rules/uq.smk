# Trajectory-level UQ (paper Sec. III-B "Uncertainty Quantification via RFF Sampling", Sec. V
# "Uncertainty Quantification Results"), for every method in uq.methods: S joint posterior
# samples of each of its gradient GPs, the sampled models through the same rollout as the mean
# models, band coverage at several levels (uq_coverage.csv), a reliability diagram, band figures.

UQ = config["uq"]
UQ_METHODS = list(UQ["methods"])
# methods of rollouts.methods: one job per gradient GP; `crgpr learn` directories (the camera
# method): one job for the directory's learned GPs (which ones is known once it is trained)
UQ_DIR_METHODS = [m for m in UQ_METHODS if m in LEARNED_MODEL_DIRS]
UQ_CFG_METHODS = [m for m in UQ_METHODS if m not in LEARNED_MODEL_DIRS]
UQ_METHOD_CFG = {m: config["rollouts"]["methods"][m] for m in UQ_CFG_METHODS}


rule uq_samples:
    input:
        code=code_closure("uq_samples.py"),
        model=_uq_model_of,
        meta=lambda wc: _uq_model_of(wc).removesuffix(".npz") + ".json",
    output:
        samples=f"{RESULTS}/uq/{{method}}/samples/{{model}}.npz",
        diagnostics=f"{RESULTS}/uq/{{method}}/samples/{{model}}.json",
    wildcard_constraints:
        method=_one_of(UQ_CFG_METHODS),
    params:
        cfg=cfg_params("seed", "uq"),
    log:
        "logs/uq/{method}/samples/{model}.log",
    benchmark:
        "benchmarks/uq/{method}/samples/{model}.tsv"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/uq_samples.py"


rule uq_rollout:
    input:
        code=code_closure("uq_rollout.py"),
        samples=lambda wc: _uq_sample_files(wc.method),
        models=lambda wc: [f"{s}.json" for s in _uq_models(wc.method)],
    output:
        # all angles of one method in one batch of S x A rods (crgpr.uq.rollout)
        expand(f"{RESULTS}/uq/{{{{method}}}}/{{angle}}.parquet", angle=UQ["angles_deg"]),
    wildcard_constraints:
        method=_one_of(UQ_CFG_METHODS),
    params:
        cfg=cfg_params("uq", "rod", "simulation"),
        method_cfg=lambda wc: UQ_METHOD_CFG[wc.method],
        angles=UQ["angles_deg"],
    log:
        "logs/uq/{method}/rollout.log",
    benchmark:
        "benchmarks/uq/{method}/rollout.tsv"
    threads: 1
    resources:
        mem_mb=3000,  # S x A = 96 rods: trajectories (4001, 96, N+1, 3) x 2 plus the stored tables
        runtime=30,
    conda:
        ENV
    script:
        "../scripts/uq_rollout.py"


rule uq_samples_learned:
    input:
        code=code_closure("uq_samples_learned.py"),
        models=lambda wc: LEARNED_MODEL_DIRS[wc.method],
    output:
        directory(f"{RESULTS}/uq/{{method}}/learned_samples"),
    wildcard_constraints:
        method=_one_of(UQ_DIR_METHODS),
    params:
        cfg=cfg_params("seed", "uq"),
    log:
        "logs/uq/{method}/learned_samples.log",
    benchmark:
        "benchmarks/uq/{method}/learned_samples.tsv"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=15,
    conda:
        ENV
    script:
        "../scripts/uq_samples_learned.py"


rule uq_rollout_learned:
    input:
        code=code_closure("uq_rollout_learned.py"),
        samples=f"{RESULTS}/uq/{{method}}/learned_samples",
        models=lambda wc: LEARNED_MODEL_DIRS[wc.method],
    output:
        expand(f"{RESULTS}/uq/{{{{method}}}}/{{angle}}.parquet", angle=UQ["angles_deg"]),
    wildcard_constraints:
        method=_one_of(UQ_DIR_METHODS),
    params:
        cfg=cfg_params("uq", "simulation"),
        angles=UQ["angles_deg"],
    log:
        "logs/uq/{method}/learned_rollout.log",
    benchmark:
        "benchmarks/uq/{method}/learned_rollout.tsv"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=30,
    conda:
        ENV
    script:
        "../scripts/uq_rollout_learned.py"


rule uq_coverage:
    input:
        code=code_closure("uq_coverage.py"),
        uq=expand(f"{RESULTS}/uq/{{method}}/{{angle}}.parquet", method=UQ_METHODS, angle=UQ["angles_deg"]),
        ground_truth=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=UQ["angles_deg"]),
        mean_models=expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet", method=UQ_METHODS,
                           angle=UQ["angles_deg"]),
    output:
        coverage=f"{RESULTS}/uq/coverage.parquet",
        table=report(
            f"{RESULTS}/tables/uq_coverage.csv",
            caption="../report/uq_coverage.rst",
            category="Uncertainty (RFF)",
        ),
    params:
        cfg=cfg_params("uq"),
    log:
        "logs/uq/coverage.log",
    benchmark:
        "benchmarks/uq/coverage.tsv"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/uq_coverage.py"


rule uq_calibration:
    input:
        code=code_closure("uq_calibration.py"),
        models=sorted({f"{s}.npz" for m in UQ_CFG_METHODS for s in _uq_models(m)}),
        meta=sorted({f"{s}.json" for m in UQ_CFG_METHODS for s in _uq_models(m)}),
        ground_truth=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=UQ["angles_deg"]),
    output:
        report(
            f"{RESULTS}/tables/uq_function_calibration.csv",
            caption="../report/uq_calibration.rst",
            category="Uncertainty (RFF)",
        ),
    params:
        cfg=cfg_params("rod"),
    log:
        "logs/uq/calibration.log",
    benchmark:
        "benchmarks/uq/calibration.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=15,
    conda:
        ENV
    script:
        "../scripts/uq_calibration.py"


rule uq_figure:
    input:
        code=code_closure("uq_figure.py"),
        uq=f"{RESULTS}/uq/{{method}}/{{angle}}.parquet",
        ground_truth=f"{RESULTS}/ground_truth/{{angle}}.parquet",
        mean_model=f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet",
    output:
        report(
            f"{RESULTS}/figures/uq_band_{{method}}_{{angle}}.png",
            caption="../report/uq_band.rst",
            category="Uncertainty (RFF)",
        ),
    wildcard_constraints:
        method=_one_of(UQ_METHODS),
        angle=r"-?\d+",
    params:
        cfg=cfg_params("uq"),
    log:
        "logs/uq/figure/{method}_{angle}.log",
    benchmark:
        "benchmarks/uq/figure/{method}_{angle}.tsv"
    threads: 1
    resources:
        mem_mb=750,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/uq_figure.py"


rule uq_reliability:
    input:
        code=code_closure("uq_reliability.py"),
        coverage=f"{RESULTS}/uq/coverage.parquet",
    output:
        report(
            f"{RESULTS}/figures/uq_reliability.png",
            caption="../report/uq_reliability.rst",
            category="Uncertainty (RFF)",
        ),
    log:
        "logs/uq/reliability.log",
    benchmark:
        "benchmarks/uq/reliability.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/uq_reliability.py"


ALL_TARGETS.extend(
    [
        f"{RESULTS}/tables/uq_coverage.csv",
        f"{RESULTS}/figures/uq_reliability.png",
        *expand(f"{RESULTS}/figures/uq_band_{{method}}_{UQ['figure_angle_deg']}.png", method=UQ_METHODS),
    ]
)


# The gradient GPs' function calibration (a diagnostic) is in `sweeps`: beyond the budget of `all`.
SWEEP_TARGETS.append(f"{RESULTS}/tables/uq_function_calibration.csv")
