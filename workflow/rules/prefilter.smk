# Prefilter (paper Sec. III-B step 2; Table IV "stage 1"): the derivative data set E of eq. (12).
# Method gp: Matern-5/2 + quadratic-basis GPs in time (Table II); fd: central differences
# (the ablation, Table V), which uses only the output grid size.

PREFILTER_METHODS = sorted({m["prefilter"] for m in config["rollouts"]["methods"].values()})
PREFILTER_PARAMS = {"gp": ["seed", "rod", "prefilter"], "fd": ["rod", "prefilter.n_t_out"]}


rule prefilter:
    input:
        code=code_closure("prefilter.py"),
        gt=f"{RESULTS}/ground_truth/{{angle}}.parquet",
    output:
        f"{RESULTS}/prefilter/{{method}}/{{angle}}.parquet",
    params:
        cfg=lambda wc: cfg_params(*PREFILTER_PARAMS[wc.method]),
    wildcard_constraints:
        method="gp|fd",
        angle=r"-?\d+",
    log:
        "logs/prefilter/{method}/{angle}.log",
    benchmark:
        "benchmarks/prefilter/{method}/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=750,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/prefilter.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/prefilter/{{method}}/{{angle}}.parquet", method=PREFILTER_METHODS,
           angle=config["angles"]["train_deg"])
)
