# Black-box GP baseline (paper Sec. V, "Baseline Comparisons", N_init = 1): six GPs from local
# state features straight to dz/dt, trained on the prefiltered training trajectory.

ROLLOUT_METHODS.append("blackbox_gp")  # the metrics rule scores every method in this list


rule blackbox_train:
    input:
        code=code_closure("blackbox_train.py"),
        prefiltered=f"{RESULTS}/prefilter/gp/{config['angles']['train_deg']}.parquet",
    output:
        models=directory(f"{RESULTS}/baselines/blackbox_gp/models"),
        summary=f"{RESULTS}/baselines/blackbox_gp/summary.json",
    params:
        cfg=cfg_params("seed", "rod", "baselines.blackbox_gp", "gradient_models.theta_wrap"),
    log:
        "logs/baselines/blackbox_train.log",
    benchmark:
        "benchmarks/baselines/blackbox_train.tsv"
    threads: 1
    resources:
        mem_mb=750,
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
        # all test angles in one job (the GPs loaded once)
        expand(f"{RESULTS}/rollouts/blackbox_gp/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
    params:
        cfg=cfg_params("rod", "simulation"),
        angles=config["angles"]["test_deg"],
    log:
        "logs/baselines/blackbox_rollout.log",
    benchmark:
        "benchmarks/baselines/blackbox_rollout.tsv"
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
