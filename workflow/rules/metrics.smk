# Metrics of every rollout method in ROLLOUT_METHODS (common.smk; each stage extends it) on
# the test angles: accuracy.parquet, Tables I and IV; CR-GPR figures (paper Figs. 3-5).


rule metrics:
    input:
        code=code_closure("metrics.py"),
        gt=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
        rollouts=lambda wc: expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet",
                                   method=ROLLOUT_METHODS, angle=config["angles"]["test_deg"]),
    output:
        accuracy=f"{RESULTS}/metrics/accuracy.parquet",
        table1=report(
            f"{RESULTS}/tables/table1_accuracy.csv",
            caption="../report/table1.rst",
            category="CR-GPR (Tables I, II, IV)",
        ),
        table4=report(
            f"{RESULTS}/tables/table4_ablation.csv",
            caption="../report/table4.rst",
            category="CR-GPR (Tables I, II, IV)",
        ),
    params:
        methods=lambda wc: list(ROLLOUT_METHODS),
    log:
        "logs/metrics/accuracy.log",
    benchmark:
        "benchmarks/metrics/accuracy.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/metrics.py"


_FIG_ANGLE = config["rollouts"]["figure_angle_deg"]


rule figures_crgpr:
    input:
        code=code_closure("figures_crgpr.py"),
        gt_train=f"{RESULTS}/ground_truth/{config['angles']['train_deg']}.parquet",
        gt_test=f"{RESULTS}/ground_truth/{{angle}}.parquet",
        gt_test_energy=f"{RESULTS}/ground_truth/{{angle}}_energy.parquet",
        rollout=f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet",
        rollout_energy=f"{RESULTS}/rollouts/{{method}}/{{angle}}_energy.parquet",
    output:
        overlays=report(
            f"{RESULTS}/figures/{{method}}_overlays_{{angle}}.png",
            caption="../report/crgpr_overlays.rst",
            category="CR-GPR figures",
        ),
        shapes=report(
            f"{RESULTS}/figures/{{method}}_shapes_{{angle}}.png",
            caption="../report/crgpr_shapes.rst",
            category="CR-GPR figures",
        ),
        energy=report(
            f"{RESULTS}/figures/{{method}}_energy_{{angle}}.png",
            caption="../report/crgpr_energy.rst",
            category="CR-GPR figures",
        ),
    wildcard_constraints:
        method="|".join(CRGPR_METHODS),
        angle=r"-?\d+",
    log:
        "logs/figures/{method}_{angle}.log",
    benchmark:
        "benchmarks/figures/{method}_{angle}.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/figures_crgpr.py"


ALL_TARGETS.extend([
    f"{RESULTS}/metrics/accuracy.parquet",
    f"{RESULTS}/tables/table1_accuracy.csv",
    f"{RESULTS}/tables/table4_ablation.csv",
    *expand(f"{RESULTS}/figures/{{method}}_{{kind}}_{{angle}}.png", method=CRGPR_METHODS,
            kind=["overlays", "shapes", "energy"], angle=[_FIG_ANGLE]),
])
