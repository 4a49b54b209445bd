# Gradient GPs (paper Sec. III-B step 3; Table IV "stage 2"): the six GPs of Table II (+ the
# objective variant's three), one job per model, trained on the prefiltered training
# trajectory.

from crgpr.learning.learned import model_files as _model_files
from crgpr.learning.learned import needed_model_jsons as _needed_model_jsons

MODEL_JSONS = _needed_model_jsons(RESULTS, config["rollouts"]["methods"])
# settings shared by every model; each model also has its own entry (models.X, objective_models.Y)
_GM_SHARED = [f"gradient_models.{k}" for k in config["gradient_models"]
              if k not in ("models", "objective_models")]
_GM_OWN = {**{m: f"gradient_models.models.{m}" for m in config["gradient_models"]["models"]},
           **{f"obj_{m}": f"gradient_models.objective_models.{m}"
              for m in config["gradient_models"]["objective_models"]}}


rule gradient_model:
    input:
        code=code_closure("gradient_model.py"),
        prefiltered=f"{RESULTS}/prefilter/{{prefilter}}/{config['angles']['train_deg']}.parquet",
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
    threads: 1
    resources:
        mem_mb=3250,
        runtime=5,
    conda:
        ENV
    script:
        "../scripts/gradient_model.py"


ALL_TARGETS.extend(MODEL_JSONS)
