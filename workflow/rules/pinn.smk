# PINN baselines (paper Sec. V, "Baseline Comparisons"): physics-only and data-assisted PINNs
# (N_init = 1, 8), trained on ground truth and evaluated on its (t, node) grid.

PINN_VARIANTS = ["pinn_physics", "pinn_data_1", "pinn_data_8"]
ROLLOUT_METHODS.extend(PINN_VARIANTS)  # the metrics rule scores every method in this list
# ground-truth angles each PINN variant trains on (crgpr.baselines.pinn.variant_angles, same order)
PINN_DATA_ANGLES = {
    "pinn_physics": [],
    "pinn_data_1": [config["angles"]["train_deg"]],
    "pinn_data_8": list(config["angles"]["pinn_train_deg"]),
}
# the config keys naming each variant's training angles (none for the physics-only PINN)
PINN_ANGLE_KEYS = {"pinn_physics": [], "pinn_data_1": ["angles.train_deg"],
                   "pinn_data_8": ["angles.pinn_train_deg"]}
PINN_PARAMS = ["seed", "rod", "simulation.t_end_s", "baselines.pinn"]


rule pinn_train:
    input:
        code=code_closure("pinn_train.py"),
        data=lambda wc: expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=PINN_DATA_ANGLES[wc.variant]),
    output:
        weights=f"{RESULTS}/baselines/pinn/{{variant}}.pt",
        history=f"{RESULTS}/baselines/pinn/{{variant}}_loss.parquet",
    params:
        cfg=lambda wc: cfg_params(*PINN_PARAMS, *PINN_ANGLE_KEYS[wc.variant]),
        angles=lambda wc: PINN_DATA_ANGLES[wc.variant],
    wildcard_constraints:
        variant="|".join(PINN_VARIANTS),
    log:
        "logs/baselines/pinn_train/{variant}.log",
    benchmark:
        "benchmarks/baselines/pinn_train/{variant}.tsv"
    priority: 10  # long and ready early: started first, so short jobs fill the end of the run
    threads: 1  # torch on one thread: two threads on a shared 2-core box run 10x slower
    resources:
        mem_mb=3000,
        runtime=15,
    conda:
        ENV
    script:
        "../scripts/pinn_train.py"


rule pinn_rollout:
    input:
        code=code_closure("pinn_rollout.py"),
        weights=f"{RESULTS}/baselines/pinn/{{method}}.pt",
        ground_truths=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
    output:
        # all test angles of one variant in one job (one start of Python and torch)
        expand(f"{RESULTS}/rollouts/{{{{method}}}}/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
    params:
        cfg=cfg_params("rod", "simulation.t_end_s", "baselines.pinn"),
        angles=config["angles"]["test_deg"],
    wildcard_constraints:
        method="|".join(PINN_VARIANTS),
    log:
        "logs/baselines/pinn_rollout/{method}.log",
    benchmark:
        "benchmarks/baselines/pinn_rollout/{method}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/pinn_rollout.py"


ALL_TARGETS.extend(
    expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet", method=PINN_VARIANTS,
           angle=config["angles"]["test_deg"])
)
