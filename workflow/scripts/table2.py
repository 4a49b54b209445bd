from crgpr import gradient_models
from crgpr.smk import run_rule

run_rule(snakemake, gradient_models.table2, model_jsons=list(snakemake.input.models), out=snakemake.output[0])
