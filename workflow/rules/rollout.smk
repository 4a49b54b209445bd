# Learned rollouts (paper Sec. III-B step 4, eq. (17); Table IV "stage 3"), per method and test
# angle, with the ground truth's integrator, dt and boundary conditions.

CRGPR_METHODS = list(config["rollouts"]["methods"])
# rollouts.study_methods: rolled out and scored by `snakemake sweeps` only (metrics_studies)
STUDY_METHODS = [m for m in CRGPR_METHODS if m in config["rollouts"]["study_methods"]]
MAIN_CRGPR_METHODS = [m for m in CRGPR_METHODS if m not in STUDY_METHODS]
ROLLOUT_METHODS.extend(MAIN_CRGPR_METHODS)


rule rollout:
    input:
        code=code_closure("rollout.py"),
        models=lambda wc: _model_files(RESULTS, config["rollouts"]["methods"][wc.method]),
    output:
        # all test angles of one method in one batch (crgpr.learning.learned.run_rollouts)
        traj=expand(f"{RESULTS}/rollouts/{{{{method}}}}/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
        energy=expand(f"{RESULTS}/rollouts/{{{{method}}}}/{{angle}}_energy.parquet", angle=config["angles"]["test_deg"]),
    params:
        cfg=lambda wc: cfg_params("rod", "simulation", f"rollouts.methods.{wc.method}"),
        angles=config["angles"]["test_deg"],
    wildcard_constraints:
        method="|".join(CRGPR_METHODS),
    log:
        "logs/rollouts/{method}.log",
    benchmark:
        "benchmarks/rollouts/{method}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/rollout.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet", method=MAIN_CRGPR_METHODS,
           angle=config["angles"]["test_deg"])
)
