# Baselines of the paper's "Baseline Comparisons" (issue 4): physics-only and data-assisted
# PINNs (N_init = 1, 8) and the black-box GP (N_init = 1), with the comparison table/figure.

PINN_VARIANTS = ["pinn_physics", "pinn_data_1", "pinn_data_8"]
BASELINE_METHODS = ["blackbox_gp", *PINN_VARIANTS]
ROLLOUT_METHODS.extend(BASELINE_METHODS)  # the metrics rule scores every method in this list
# ground-truth angles each PINN variant trains on (crgpr.baselines.pinn.variant_angles, same order)
PINN_DATA_ANGLES = {
    "pinn_physics": [],
    "pinn_data_1": [config["angles"]["train_deg"]],
    "pinn_data_8": list(config["angles"]["pinn_train_deg"]),
}


rule pinn_train:
    input:
        code=code_closure("pinn_train.py"),
        data=lambda wc: expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=PINN_DATA_ANGLES[wc.variant]),
    output:
        weights=f"{RESULTS}/baselines/pinn/{{variant}}.pt",
        history=f"{RESULTS}/baselines/pinn/{{variant}}_loss.parquet",
    wildcard_constraints:
        variant="|".join(PINN_VARIANTS),
    log:
        "logs/baselines/pinn_train/{variant}.log",
    benchmark:
        "benchmarks/baselines/pinn_train/{variant}.tsv"
    threads: 1  # torch on one thread: two threads on a shared 2-core box run 10x slower
    resources:
        mem_mb=3000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/pinn_train.py"


rule pinn_rollout:
    input:
        code=code_closure("pinn_rollout.py"),
        weights=f"{RESULTS}/baselines/pinn/{{method}}.pt",
        ground_truth=f"{RESULTS}/ground_truth/{{angle}}.parquet",
    output:
        f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet",
    wildcard_constraints:
        method="|".join(PINN_VARIANTS),
        angle=r"-?\d+",
    log:
        "logs/baselines/pinn_rollout/{method}/{angle}.log",
    benchmark:
        "benchmarks/baselines/pinn_rollout/{method}/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/pinn_rollout.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet", method=PINN_VARIANTS,
           angle=config["angles"]["test_deg"])
)


rule blackbox_train:
    input:
        code=code_closure("blackbox_train.py"),
        prefiltered=f"{RESULTS}/prefilter/gp/{config['angles']['train_deg']}.parquet",
    output:
        models=directory(f"{RESULTS}/baselines/blackbox_gp/models"),
        summary=f"{RESULTS}/baselines/blackbox_gp/summary.json",
    log:
        "logs/baselines/blackbox_train.log",
    benchmark:
        "benchmarks/baselines/blackbox_train.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/blackbox_train.py"


rule blackbox_rollout:
    input:
        code=code_closure("blackbox_rollout.py"),
        models=f"{RESULTS}/baselines/blackbox_gp/models",
        summary=f"{RESULTS}/baselines/blackbox_gp/summary.json",
    output:
        f"{RESULTS}/rollouts/blackbox_gp/{{angle}}.parquet",
    wildcard_constraints:
        angle=r"-?\d+",
    log:
        "logs/baselines/blackbox_rollout/{angle}.log",
    benchmark:
        "benchmarks/baselines/blackbox_rollout/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/blackbox_rollout.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/rollouts/blackbox_gp/{{angle}}.parquet", angle=config["angles"]["test_deg"])
)


rule baselines_table:
    input:
        code=code_closure("baselines_table.py"),
        accuracy=f"{RESULTS}/metrics/accuracy.parquet",
        rollouts=expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet", method=BASELINE_METHODS,
                        angle=config["angles"]["test_deg"]),
        ground_truth=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
        histories=expand(f"{RESULTS}/baselines/pinn/{{variant}}_loss.parquet", variant=PINN_VARIANTS),
    output:
        table=report(
            f"{RESULTS}/tables/baselines.csv",
            caption="../report/baselines_table.rst",
            category="Baselines",
        ),
        notes=f"{RESULTS}/tables/baselines_notes.md",
        figure=report(
            f"{RESULTS}/figures/baselines.png",
            caption="../report/baselines_figure.rst",
            category="Baselines",
        ),
    params:
        methods=BASELINE_METHODS,
        variants=PINN_VARIANTS,
    log:
        "logs/baselines/baselines_table.log",
    benchmark:
        "benchmarks/baselines/baselines_table.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/baselines_table.py"


ALL_TARGETS.extend(rules.baselines_table.output)
