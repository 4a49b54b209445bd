# Reports: metrics of every rollout method in ROLLOUT_METHODS (common.smk; each stage extends
# it) on the test angles (accuracy.parquet; the studies of `sweeps` in accuracy_studies.parquet; the paper's Table III in table1_accuracy.csv and
# Table V in table4_ablation.csv); CR-GPR figures (paper Figs. 3-5); Table II; the baseline
# comparison; the timing table (Table IV) from the benchmark files; every table and claim of
# the paper beside ours.


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
            category="CR-GPR (Tables II, III, V)",
        ),
        table4=report(
            f"{RESULTS}/tables/table4_ablation.csv",
            caption="../report/table4.rst",
            category="CR-GPR (Tables II, III, V)",
        ),
    params:
        methods=lambda wc: list(ROLLOUT_METHODS),
        angles=list(config["angles"]["test_deg"]),
        cfg=cfg_params("rod.L0", "rollouts.table1_method", "rollouts.ablation_methods"),
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


# The studies of `snakemake sweeps` (rollouts.study_methods, variants.methods): same scoring.
rule metrics_studies:
    input:
        code=code_closure("metrics_studies.py"),
        gt=expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=config["angles"]["test_deg"]),
        rollouts=expand(f"{RESULTS}/rollouts/{{method}}/{{angle}}.parquet",
                        method=STUDY_METHODS, angle=config["angles"]["test_deg"]),
        variant_accuracy=lambda wc: list(VARIANT_METHODS.values()),
    output:
        accuracy=f"{RESULTS}/metrics/accuracy_studies.parquet",
    params:
        methods=STUDY_METHODS,
        variant_methods=lambda wc: list(VARIANT_METHODS),
        angles=list(config["angles"]["test_deg"]),
        cfg=cfg_params("rod.L0"),
    log:
        "logs/metrics/accuracy_studies.log",
    benchmark:
        "benchmarks/metrics/accuracy_studies.tsv"
    threads: 1
    resources:
        mem_mb=2000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/metrics_studies.py"


SWEEP_TARGETS.append(f"{RESULTS}/metrics/accuracy_studies.parquet")


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
    params:
        cfg=cfg_params("angles.train_deg"),
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
    *expand(f"{RESULTS}/figures/{{method}}_{{kind}}_{{angle}}.png", method=MAIN_CRGPR_METHODS,
            kind=["overlays", "shapes", "energy"], angle=[_FIG_ANGLE]),
])
rule table2:
    input:
        code=code_closure("table2.py"),
        models=MODEL_JSONS,
    output:
        report(
            f"{RESULTS}/tables/table2_hyperparameters.csv",
            caption="../report/table2.rst",
            category="CR-GPR (Tables II, III, V)",
        ),
    log:
        "logs/tables/table2.log",
    benchmark:
        "benchmarks/tables/table2.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/table2.py"


ALL_TARGETS.append(f"{RESULTS}/tables/table2_hyperparameters.csv")


# The baselines beside the paper's CR-GPR and ours (paper Sec. V, "Baseline Comparisons")
BASELINE_METHODS = ["blackbox_gp", *PINN_VARIANTS]


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
        cfg=cfg_params("angles.test_deg"),
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


# The paper regenerated: timing from the benchmark files (Table IV "stages" 1-4 = prefilter,
# gradient GPs, one rollout, UQ), then every table and claim of the paper beside ours
# (results/tables/paper_vs_reproduction.{csv,md}).

TRAIN = config["angles"]["train_deg"]
TEST = config["angles"]["test_deg"]
TIMED_MODELS = list(config["gradient_models"]["models"])


rule timing:
    input:
        code=code_closure("timing.py"),
        stage1=f"{RESULTS}/prefilter/gp/{TRAIN}.parquet",
        stage2=expand(f"{RESULTS}/models/gp/{{model}}.json", model=TIMED_MODELS),
        stage3=expand(f"{RESULTS}/rollouts/cr_gpr/{{angle}}.parquet", angle=TEST),
        # stage 4 is timed on the first UQ method (cr_gpr in config.yaml: the paper's model)
        stage4=expand(f"{RESULTS}/uq/{UQ_METHODS[0]}/{{angle}}.parquet", angle=UQ["angles_deg"]),
    output:
        f"{RESULTS}/metrics/timing.parquet",  # shown in the report via paper_vs_reproduction
    params:
        # the benchmark files written by the jobs that produced the inputs above
        stage_files={
            "stage1": {"sum": [f"benchmarks/prefilter/gp/{TRAIN}.tsv"]},
            "stage2": {"sum": [f"benchmarks/models/gp/{m}.tsv" for m in TIMED_MODELS]},
            "stage3": {"mean": ["benchmarks/rollouts/cr_gpr.tsv"], "per_job": len(TEST)},  # one batch job
            "stage4": {
                "sum": [f"benchmarks/uq/{UQ_METHODS[0]}/samples/{Path(s).name}.tsv"
                        for s in _uq_models(UQ_METHODS[0])],
                "mean": [f"benchmarks/uq/{UQ_METHODS[0]}/rollout.tsv"],  # all angles in one batch
                "per_job": len(UQ["angles_deg"]),
            },
        },
    log:
        "logs/paper/timing.log",
    benchmark:
        "benchmarks/paper/timing.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/timing.py"


rule paper_tables:
    input:
        code=code_closure("paper_tables.py"),
        values=str(BASE / "workflow" / "paper_values.yaml"),
        accuracy=f"{RESULTS}/metrics/accuracy.parquet",
        hyper=f"{RESULTS}/tables/table2_hyperparameters.csv",
        timing=f"{RESULTS}/metrics/timing.parquet",
        uq=f"{RESULTS}/tables/uq_coverage.csv",
    output:
        csv=report(
            f"{RESULTS}/tables/paper_vs_reproduction.csv",
            caption="../report/paper_vs_reproduction.rst",
            category="Paper vs reproduction",
        ),
        md=f"{RESULTS}/tables/paper_vs_reproduction.md",
        claims=report(
            f"{RESULTS}/tables/paper_claims.csv",
            caption="../report/paper_claims.rst",
            category="Paper vs reproduction",
        ),
    log:
        "logs/paper/paper_tables.log",
    benchmark:
        "benchmarks/paper/paper_tables.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/paper_tables.py"


# The claims paper_tables leaves out (they need the noise ablation of `sweeps`).
rule paper_claims_sweeps:
    input:
        code=code_closure("paper_claims_sweeps.py"),
        values=str(BASE / "workflow" / "paper_values.yaml"),
        noise=f"{RESULTS}/tables/noise_ablation.csv",
    output:
        claims=report(
            f"{RESULTS}/tables/paper_claims_sweeps.csv",
            caption="../report/paper_claims.rst",
            category="Paper vs reproduction",
        ),
    log:
        "logs/paper/paper_claims_sweeps.log",
    benchmark:
        "benchmarks/paper/paper_claims_sweeps.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/paper_claims_sweeps.py"


SWEEP_TARGETS.extend(rules.paper_claims_sweeps.output)


ALL_TARGETS.extend(rules.paper_tables.output)
