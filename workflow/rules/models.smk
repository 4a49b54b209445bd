# Gradient GPs (paper Sec. III-B step 3; Table IV "stage 2"): the six GPs of Table II (+ the
# objective variant's three), one job per model, trained on the prefiltered training
# trajectory; the test angles' ground truth only serves to check the rollout mean against the
# dense exact posterior mean at the states the rollouts visit. ``gradient_model_paper_hyp``:
# the same models with the paper's Table II hyperparameters (method cr_gpr_paper_hyp).

from crgpr.learning.learned import model_files as _model_files
from crgpr.learning.learned import needed_model_jsons as _needed_model_jsons

# the models of the methods of `all` (rollouts.study_methods: `sweeps`, through their rollouts)
MODEL_JSONS = _needed_model_jsons(RESULTS, {m: s for m, s in config["rollouts"]["methods"].items()
                                            if m not in config["rollouts"]["study_methods"]})
# settings shared by every model; each model also has its own entry (models.X, objective_models.Y)
_GM_SHARED = [f"gradient_models.{k}" for k in config["gradient_models"]
              if k not in ("models", "objective_models")]
# the paper-hyperparameter models do not search hyperparameters
_GM_SHARED_FIXED = [k for k in _GM_SHARED if k.split(".")[1] not in ("n_hyper", "n_restarts", "hyper_bounds")]
_GM_OWN = {**{m: f"gradient_models.models.{m}" for m in config["gradient_models"]["models"]},
           **{f"obj_{m}": f"gradient_models.objective_models.{m}"
              for m in config["gradient_models"]["objective_models"]}}
_GT_TESTS = expand(f"{RESULTS}/ground_truth/{{angle}}.parquet", angle=config["angles"]["test_deg"])


rule gradient_model:
    input:
        code=code_closure("gradient_model.py"),
        prefiltered=f"{RESULTS}/prefilter/{{prefilter}}/{config['angles']['train_deg']}.parquet",
        gt_tests=_GT_TESTS,
    output:
        npz=f"{RESULTS}/models/{{prefilter}}/{{model}}.npz",
        json=f"{RESULTS}/models/{{prefilter}}/{{model}}.json",
    params:
        cfg=lambda wc: cfg_params("seed", "rod", *_GM_SHARED, _GM_OWN[wc.model]),
    wildcard_constraints:
        prefilter="gp|fd",
        model="q_x|q_y|dH_dtheta|dH_dp_x|dH_dp_y|dH_dp_theta|obj_n1|obj_n2|obj_m",
    log:
        "logs/models/{prefilter}/{model}.log",
    benchmark:
        "benchmarks/models/{prefilter}/{model}.tsv"
    priority: 10  # long and ready early: started first, so short jobs fill the end of the run
    threads: 1
    resources:
        mem_mb=5000,
        runtime=20,
    conda:
        ENV
    script:
        "../scripts/gradient_model.py"


rule gradient_model_paper_hyp:
    input:
        code=code_closure("gradient_model_paper_hyp.py"),
        prefiltered=f"{RESULTS}/prefilter/{{prefilter}}/{config['angles']['train_deg']}.parquet",
        gt_tests=_GT_TESTS,
    output:
        npz=f"{RESULTS}/models/{{prefilter}}_paper_hyp/{{model}}.npz",
        json=f"{RESULTS}/models/{{prefilter}}_paper_hyp/{{model}}.json",
    params:
        cfg=lambda wc: cfg_params("seed", "rod", *_GM_SHARED_FIXED, _GM_OWN[wc.model]),
    wildcard_constraints:
        prefilter="gp|fd",
        model="q_x|q_y|dH_dtheta|dH_dp_x|dH_dp_y|dH_dp_theta",
    log:
        "logs/models/{prefilter}_paper_hyp/{model}.log",
    benchmark:
        "benchmarks/models/{prefilter}_paper_hyp/{model}.tsv"
    threads: 1
    resources:
        mem_mb=5000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/gradient_model_paper_hyp.py"


ALL_TARGETS.extend(MODEL_JSONS)


rule paper_hyp_lml:
    input:
        code=code_closure("paper_hyp_lml.py"),
        models=expand(f"{RESULTS}/models/gp/{{m}}.json",
                      m=["q_x", "q_y", "dH_dtheta", "dH_dp_x", "dH_dp_y", "dH_dp_theta"]),
    output:
        report(
            f"{RESULTS}/tables/paper_hyp_lml.csv",
            caption="../report/paper_hyp_lml.rst",
            category="Deciding the paper's CR-GPR",
        ),
    log:
        "logs/tables/paper_hyp_lml.log",
    benchmark:
        "benchmarks/tables/paper_hyp_lml.tsv"
    threads: 1
    resources:
        mem_mb=3000,
        runtime=10,
    conda:
        ENV
    script:
        "../scripts/paper_hyp_lml.py"


SWEEP_TARGETS.append(f"{RESULTS}/tables/paper_hyp_lml.csv")
