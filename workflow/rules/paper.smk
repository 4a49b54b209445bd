# Stage 7: the paper regenerated: timing from the benchmark files, then every table and claim
# of the paper beside ours (results/tables/paper_vs_reproduction.{csv,md}).


rule timing:
    input:
        code=lib("timing"),
        stage1=f"{RESULTS}/prefilter/gp/{config['angles']['train_deg']}.parquet",
        stage2=expand(f"{RESULTS}/models/gp/{{model}}.json", model=GRADIENT_MODELS),
        stage3=expand(f"{RESULTS}/rollouts/cr_gpr/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
        stage4=expand(f"{RESULTS}/uq/{{angle}}.parquet", angle=UQ_ANGLES),
    output:
        report(
            f"{RESULTS}/metrics/timing.parquet",
            caption="../report/timing.rst",
            category="Paper vs reproduction",
        ),
    params:
        stage_files=lambda wildcards, input: {
            "stage1": [benchmark_of("prefilter", input.stage1)],
            "stage2": [benchmark_of("models", f) for f in input.stage2],
            "stage3": [benchmark_of("rollouts", f) for f in input.stage3],
            "stage4": [benchmark_of("uq", f) for f in input.stage4],
        },
    log:
        "logs/paper/timing.log",
    benchmark:
        "benchmarks/paper/timing.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    conda:
        ENV
    script:
        "../scripts/timing.py"


rule paper_tables:
    input:
        code=lib("paper"),
        values="workflow/paper_values.yaml",
        accuracy=f"{RESULTS}/metrics/accuracy.parquet",
        hyper=f"{RESULTS}/tables/table2_hyperparameters.csv",
        timing=f"{RESULTS}/metrics/timing.parquet",
        uq=f"{RESULTS}/tables/uq_coverage.csv",
    output:
        csv=report(
            f"{RESULTS}/tables/paper_vs_reproduction.csv",
            caption="../report/paper_vs_reproduction.rst",
            category="Paper vs reproduction",
        ),
        md=f"{RESULTS}/tables/paper_vs_reproduction.md",
        claims=report(
            f"{RESULTS}/tables/paper_claims.csv",
            caption="../report/paper_claims.rst",
            category="Paper vs reproduction",
        ),
    log:
        "logs/paper/paper_tables.log",
    benchmark:
        "benchmarks/paper/paper_tables.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=2,
    conda:
        ENV
    script:
        "../scripts/paper_tables.py"


ALL_TARGETS.extend(rules.paper_tables.output)
