from crgpr.commands.smk import run_rule
from crgpr.learning import gradient_models

run_rule(snakemake, gradient_models.table2, model_jsons=list(snakemake.input.models), out=snakemake.output[0])
