# Pipeline variants (crgpr.commands.variants): the faithful CR-GPR pipeline (paper
# Sec. III-B steps 1-4, then the metrics) rerun with a config overlay (variants.definitions) by
# the main rules themselves (`use rule`: same scripts, same rule functions), under
# results/variants/{variant}/, with each main rule's params keys read from the overlaid config.
# A stage whose values and inputs equal the main run's reuses the main run's file, so a variant
# that changes only gradient_models refits the GPs on the main ground truth and prefilter.
# variants.methods joins a variant's rows to accuracy.parquet (in `all`); variants.sensitivity
# makes results/tables/crgpr_sensitivity.csv (target `sweeps`).


use rule ground_truth as variant_ground_truth with:
    output:
        traj=f"{VROOT}/{{variant}}/ground_truth/{{angle}}.parquet",
        energy=f"{VROOT}/{{variant}}/ground_truth/{{angle}}_energy.parquet",
    params:
        cfg=variant_params(rules.ground_truth),
    wildcard_constraints:
        variant=_VARIANT_RE,
        angle=r"-?\d+",
    log:
        "logs/variants/{variant}/ground_truth/{angle}.log",
    benchmark:
        "benchmarks/variants/{variant}/ground_truth/{angle}.tsv"


use rule prefilter as variant_prefilter with:
    input:
        code=code_closure("prefilter.py"),
        gt=lambda wc: v_ground_truth(wc.variant, int(wc.angle)),
    output:
        f"{VROOT}/{{variant}}/prefilter/{{method}}/{{angle}}.parquet",
    params:
        cfg=variant_params(rules.prefilter),
    wildcard_constraints:
        variant=_VARIANT_RE,
        method="gp|fd",
        angle=r"-?\d+",
    log:
        "logs/variants/{variant}/prefilter/{method}/{angle}.log",
    benchmark:
        "benchmarks/variants/{variant}/prefilter/{method}/{angle}.tsv"


use rule gradient_model as variant_gradient_model with:
    input:
        code=code_closure("gradient_model.py"),
        prefiltered=lambda wc: v_prefilter(wc.variant, wc.prefilter,
                                           VARIANT_CFG[wc.variant]["angles"]["train_deg"]),
        gt_tests=lambda wc: [v_ground_truth(wc.variant, a) for a in VARIANT_CFG[wc.variant]["angles"]["test_deg"]],
    output:
        npz=f"{VROOT}/{{variant}}/models/{{prefilter}}/{{model}}.npz",
        json=f"{VROOT}/{{variant}}/models/{{prefilter}}/{{model}}.json",
    params:
        cfg=variant_params(rules.gradient_model),
    wildcard_constraints:
        variant=_VARIANT_RE,
        prefilter="gp|fd",
        model="q_x|q_y|dH_dtheta|dH_dp_x|dH_dp_y|dH_dp_theta|obj_n1|obj_n2|obj_m",
    log:
        "logs/variants/{variant}/models/{prefilter}/{model}.log",
    benchmark:
        "benchmarks/variants/{variant}/models/{prefilter}/{model}.tsv"


# rule rollout itself (a diverged rollout is written frozen and scored, as in the main run)
rule variant_rollout:
    input:
        code=code_closure("variant_rollout.py"),
        models=lambda wc: v_model_files(wc.variant, wc.method),
    output:
        traj=f"{VROOT}/{{variant}}/rollouts/{{method}}/{{angle}}.parquet",
        energy=f"{VROOT}/{{variant}}/rollouts/{{method}}/{{angle}}_energy.parquet",
    params:
        cfg=variant_params(rules.rollout),
    wildcard_constraints:
        variant=_VARIANT_RE,
        method="|".join(CRGPR_METHODS),
        angle=r"-?\d+",
    log:
        "logs/variants/{variant}/rollouts/{method}/{angle}.log",
    benchmark:
        "benchmarks/variants/{variant}/rollouts/{method}/{angle}.tsv"
    threads: 1
    resources:
        mem_mb=500,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/variant_rollout.py"


rule variant_metrics:
    input:
        code=code_closure("variant_metrics.py"),
        gt=lambda wc: [v_ground_truth(wc.variant, a) for a in VARIANT_CFG[wc.variant]["angles"]["test_deg"]],
        rollouts=lambda wc: [v_rollout(wc.variant, a) for a in VARIANT_CFG[wc.variant]["angles"]["test_deg"]],
    output:
        f"{VROOT}/{{variant}}/metrics/accuracy.parquet",
    params:
        cfg=lambda wc: _config_subset(VARIANT_CFG[wc.variant], "rod.L0"),
        method=lambda wc: _VDEF[wc.variant]["method"],
        angles=lambda wc: list(VARIANT_CFG[wc.variant]["angles"]["test_deg"]),
    wildcard_constraints:
        variant=_VARIANT_RE,
    log:
        "logs/variants/{variant}/metrics.log",
    benchmark:
        "benchmarks/variants/{variant}/metrics.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/variant_metrics.py"


_SENS = list(config["variants"]["sensitivity"])


rule crgpr_sensitivity:
    input:
        code=code_closure("crgpr_sensitivity.py"),
        accuracy=[v_accuracy(v) for v in _SENS],
    output:
        table=report(
            f"{RESULTS}/tables/crgpr_sensitivity.csv",
            caption="../report/crgpr_sensitivity.rst",
            category="Deciding the paper's CR-GPR",
        ),
        figure=report(
            f"{RESULTS}/figures/crgpr_sensitivity.png",
            caption="../report/crgpr_sensitivity.rst",
            category="Deciding the paper's CR-GPR",
        ),
    params:
        cfg=cfg_params("angles.test_deg", *(f"variants.definitions.{v}" for v in _SENS)),
        variants=_SENS,
    log:
        "logs/tables/crgpr_sensitivity.log",
    benchmark:
        "benchmarks/tables/crgpr_sensitivity.tsv"
    threads: 1
    resources:
        mem_mb=1000,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/crgpr_sensitivity.py"


VARIANT_METHODS.update({m: v_accuracy(v) for m, v in config["variants"]["methods"].items()})
if _SENS:
    SWEEP_TARGETS.extend(rules.crgpr_sensitivity.output)
