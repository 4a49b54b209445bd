# Stage 7: the paper regenerated: timing from the benchmark files, then every table and claim
# of the paper beside ours (results/tables/paper_vs_reproduction.{csv,md}).


TRAIN = config["angles"]["train_deg"]
TEST = config["angles"]["test_deg"]
TIMED_MODELS = list(config["gradient_models"]["models"])


rule timing:
    input:
        code=code_closure("timing.py"),
        stage1=f"{RESULTS}/prefilter/gp/{TRAIN}.parquet",
        stage2=expand(f"{RESULTS}/models/gp/{{model}}.json", model=TIMED_MODELS),
        stage3=expand(f"{RESULTS}/rollouts/cr_gpr/{{angle}}.parquet", angle=TEST),
        # stage 4 is timed on the first UQ method (cr_gpr in config.yaml: the paper's model)
        stage4=expand(f"{RESULTS}/uq/{UQ_METHODS[0]}/{{angle}}.parquet", angle=UQ["angles_deg"]),
    output:
        f"{RESULTS}/metrics/timing.parquet",  # shown in the report via paper_vs_reproduction
    params:
        # the benchmark files written by the jobs that produced the inputs above
        stage_files={
            "stage1": {"sum": [f"benchmarks/prefilter/gp/{TRAIN}.tsv"]},
            "stage2": {"sum": [f"benchmarks/models/gp/{m}.tsv" for m in TIMED_MODELS]},
            "stage3": {"mean": [f"benchmarks/rollouts/cr_gpr/{a}.tsv" for a in TEST]},
            "stage4": {
                "sum": [f"benchmarks/uq/{UQ_METHODS[0]}/samples/{Path(s).name}.tsv"
                        for s in _uq_models(UQ_METHODS[0])],
                "mean": [f"benchmarks/uq/{UQ_METHODS[0]}/rollout/{a}.tsv" for a in UQ["angles_deg"]],
            },
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
        code=code_closure("paper_tables.py"),
        values=str(BASE / "workflow" / "paper_values.yaml"),
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
