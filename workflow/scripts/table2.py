from crgpr.commands.report import table2
from crgpr.commands.smk import run_rule

run_rule(snakemake, table2, model_jsons=list(snakemake.input.models), out=snakemake.output[0])
