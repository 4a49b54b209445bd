# Trajectory-level UQ (issue 5; paper Sec. III "Uncertainty Quantification via RFF Sampling",
# Sec. V "Uncertainty Quantification Results"): S joint posterior samples of every gradient GP,
# propagated through the rollout per angle, band coverage of the ground truth, band figure.

UQ = config["uq"]
UQ_PREFILTER = config["rollouts"]["methods"][UQ["method"]]["prefilter"]
UQ_MODELS = list(config["gradient_models"]["models"])

rule uq_samples:
    input:
        code=code_closure("uq_samples.py"),
        models=expand(f"{RESULTS}/models/{UQ_PREFILTER}/{{model}}.npz", model=UQ_MODELS),
        meta=expand(f"{RESULTS}/models/{UQ_PREFILTER}/{{model}}.json", model=UQ_MODELS),
    output:
        samples=expand(f"{RESULTS}/uq/samples/{{model}}.npz", model=UQ_MODELS),
        diagnostics=f"{RESULTS}/uq/samples/diagnostics.json",
    params:
        cfg=cfg_params("seed", "uq"),
    log:
        "logs/uq/samples.log",
    benchmark:
        "benchmarks/uq/samples.tsv"
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
        samples=expand(f"{RESULTS}/uq/samples/{{model}}.npz", model=UQ_MODELS),
        models=expand(f"{RESULTS}/models/{UQ_PREFILTER}/{{model}}.json", model=UQ_MODELS),
    output:
        f"{RESULTS}/uq/{{angle}}.parquet",
    wildcard_constraints:
        angle=r"-?\d+",
    params:
        cfg=cfg_params("seed", "uq", "rod", "simulation"),
    log:
        "logs/uq/rollout/{angle}.log",
    benchmark:
        "benchmarks/uq/rollout/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/uq_rollout.py"


rule uq_coverage:
    input:
        code=code_closure("uq_coverage.py"),
        uq=expand(f"{RESULTS}/uq/{{angle}}.parquet", angle=UQ["angles_deg"]),
        ground_truth=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=UQ["angles_deg"]),
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
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/uq_coverage.py"


rule uq_calibration:
    input:
        code=code_closure("uq_calibration.py"),
        models=expand(f"{RESULTS}/models/{UQ_PREFILTER}/{{model}}.npz", model=UQ_MODELS),
        meta=expand(f"{RESULTS}/models/{UQ_PREFILTER}/{{model}}.json", model=UQ_MODELS),
        ground_truth=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=UQ["angles_deg"]),
    output:
        report(
            f"{RESULTS}/tables/uq_function_calibration.csv",
            caption="../report/uq_calibration.rst",
            category="Uncertainty (RFF)",
        ),
    params:
        cfg=cfg_params("uq", "rod"),
    log:
        "logs/uq/calibration.log",
    benchmark:
        "benchmarks/uq/calibration.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/uq_calibration.py"


rule uq_figure:
    input:
        code=code_closure("uq_figure.py"),
        uq=f"{RESULTS}/uq/{{angle}}.parquet",
        ground_truth=f"{RESULTS}/ground_truth/{{angle}}.parquet",
        mean_model=f"{RESULTS}/rollouts/{UQ['method']}/{{angle}}.parquet",
    output:
        report(
            f"{RESULTS}/figures/uq_band_{{angle}}.png",
            caption="../report/uq_band.rst",
            category="Uncertainty (RFF)",
        ),
    wildcard_constraints:
        angle=r"-?\d+",
    params:
        cfg=cfg_params("uq"),
    log:
        "logs/uq/figure/{angle}.log",
    benchmark:
        "benchmarks/uq/figure/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/uq_figure.py"


ALL_TARGETS.extend(
    [
        f"{RESULTS}/tables/uq_coverage.csv",
        f"{RESULTS}/tables/uq_function_calibration.csv",
        f"{RESULTS}/figures/uq_band_{UQ['figure_angle_deg']}.png",
    ]
)
