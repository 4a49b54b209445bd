# Oracle ablation of the paper's CR-GPR (each learned component replaced by
# the constitutive law written in the same features), on every test angle; the all-learned
# variant is the cr_gpr rollouts themselves.


rule oracle_ablation:
    input:
        code=code_closure("oracle_ablation.py"),
        models=expand(f"{RESULTS}/models/gp/{{m}}.json",
                      m=["q_x", "q_y", "dH_dtheta", "dH_dp_x", "dH_dp_y", "dH_dp_theta"]),
        gt_train=f"{RESULTS}/ground_truth/{config['angles']['train_deg']}.parquet",
        gt_tests=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
        learned=expand(f"{RESULTS}/rollouts/cr_gpr/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
    output:
        table=report(
            f"{RESULTS}/tables/oracle_ablation.csv",
            caption="../report/oracle_table.rst",
            category="Deciding the paper's CR-GPR",
        ),
        pointwise=report(
            f"{RESULTS}/tables/oracle_pointwise.csv",
            caption="../report/oracle_pointwise.rst",
            category="Deciding the paper's CR-GPR",
        ),
        figure=report(
            f"{RESULTS}/figures/oracle_ablation.png",
            caption="../report/oracle_ablation.rst",
            category="Deciding the paper's CR-GPR",
        ),
    params:
        rod=config["rod"],
        simulation=config["simulation"],
        theta_closure=config["oracle"]["theta_closure"],
    log:
        "logs/tables/oracle_ablation.log",
    benchmark:
        "benchmarks/tables/oracle_ablation.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=30,
    conda:
        ENV
    script:
        "../scripts/oracle_ablation.py"


# a study beyond the budget of `all`: target `sweeps`
SWEEP_TARGETS.extend([
    f"{RESULTS}/tables/oracle_ablation.csv",
    f"{RESULTS}/tables/oracle_pointwise.csv",
    f"{RESULTS}/figures/oracle_ablation.png",
])
