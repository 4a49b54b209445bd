from crgpr.commands.models import paper_hyp_lml
from crgpr.commands.smk import run_rule

run_rule(snakemake, paper_hyp_lml, model_jsons=list(snakemake.input.models), out=snakemake.output[0])
