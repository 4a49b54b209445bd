# Stage 2 (issue 3): the six gradient GPs of Table II (+ the objective variant's three), one
# job per model, trained on the prefiltered training trajectory; Table II.

from crgpr.learning.learned import model_files as _model_files
from crgpr.learning.learned import needed_model_jsons as _needed_model_jsons

MODEL_JSONS = _needed_model_jsons(RESULTS, config["rollouts"]["methods"])


rule gradient_model:
    input:
        code=code_closure("gradient_model.py"),
        prefiltered=f"{RESULTS}/prefilter/{{prefilter}}/{config['angles']['train_deg']}.parquet",
    output:
        npz=f"{RESULTS}/models/{{prefilter}}/{{model}}.npz",
        json=f"{RESULTS}/models/{{prefilter}}/{{model}}.json",
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


rule table2:
    input:
        code=code_closure("table2.py"),
        models=MODEL_JSONS,
    output:
        report(
            f"{RESULTS}/tables/table2_hyperparameters.csv",
            caption="../report/table2.rst",
            category="CR-GPR (Tables I, II, IV)",
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


ALL_TARGETS.extend([*MODEL_JSONS, f"{RESULTS}/tables/table2_hyperparameters.csv"])
