# Stage 0: ground-truth rod trajectories, one job per initial angle (paper Sec. IV).


rule ground_truth:
    input:
        code=code_closure("ground_truth.py"),
    output:
        traj=f"{RESULTS}/ground_truth/{{angle}}.parquet",
        energy=f"{RESULTS}/ground_truth/{{angle}}_energy.parquet",
    wildcard_constraints:
        angle=r"-?\d+",
    log:
        "logs/ground_truth/{angle}.log",
    benchmark:
        "benchmarks/ground_truth/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/ground_truth.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=ANGLES_GT)
)
