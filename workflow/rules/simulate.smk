# Ground truth (paper Sec. III-B step 1, Sec. IV): rod trajectories, one job per initial angle.


rule ground_truth:
    input:
        code=code_closure("ground_truth.py"),
    output:
        traj=f"{RESULTS}/ground_truth/{{angle}}.parquet",
        energy=f"{RESULTS}/ground_truth/{{angle}}_energy.parquet",
    params:
        cfg=cfg_params("rod", "simulation"),
    wildcard_constraints:
        angle=r"-?\d+",
    log:
        "logs/ground_truth/{angle}.log",
    benchmark:
        "benchmarks/ground_truth/{angle}.tsv"
    priority: 10  # cheap and needed early by long rules (pinn_train of 8 angles, prefilter)
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
