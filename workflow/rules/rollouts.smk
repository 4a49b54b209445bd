# Stage 3 (issue 3): learned-model rollouts (eq. (nonpde)) per method and test angle, same
# integrator, dt and boundary conditions as the ground truth.

CRGPR_METHODS = list(config["rollouts"]["methods"])
ROLLOUT_METHODS.extend(CRGPR_METHODS)


rule rollout:
    input:
        code=code_closure("rollout.py"),
        models=lambda wc: _model_files(RESULTS, config["rollouts"]["methods"][wc.method]),
    output:
        traj=f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet",
        energy=f"{RESULTS}/rollouts/{{method}}/{{angle}}_energy.parquet",
    wildcard_constraints:
        method="|".join(CRGPR_METHODS),
        angle=r"-?\d+",
    log:
        "logs/rollouts/{method}/{angle}.log",
    benchmark:
        "benchmarks/rollouts/{method}/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/rollout.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet", method=CRGPR_METHODS,
           angle=config["angles"]["test_deg"])
)
