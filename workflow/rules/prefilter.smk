# Stage 1 (issue 3): prefilter, the derivative data set E (paper Sec. III-B step 2, Table II).
# Method gp: Matern-5/2 + quadratic-basis GPs in time; fd: central differences (ablation).

PREFILTER_METHODS = sorted({m["prefilter"] for m in config["rollouts"]["methods"].values()})


rule prefilter:
    input:
        code=code_closure("prefilter.py"),
        gt=f"{RESULTS}/ground_truth/{{angle}}.parquet",
    output:
        f"{RESULTS}/prefilter/{{method}}/{{angle}}.parquet",
    wildcard_constraints:
        method="gp|fd",
        angle=r"-?\d+",
    log:
        "logs/prefilter/{method}/{angle}.log",
    benchmark:
        "benchmarks/prefilter/{method}/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/prefilter.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/prefilter/{{method}}/{{angle}}.parquet", method=PREFILTER_METHODS,
           angle=config["angles"]["train_deg"])
)
