from crgpr.commands.report import metrics_studies
from crgpr.commands.smk import run_rule

i = snakemake.input
run_rule(snakemake, metrics_studies, cfg=snakemake.params.cfg, methods=list(snakemake.params.methods),
         angles=list(snakemake.params.angles), ground_truth=list(i.gt), rollouts=list(i.rollouts),
         variant_accuracy=dict(zip(snakemake.params.variant_methods, i.variant_accuracy, strict=True)),
         out=snakemake.output.accuracy)
