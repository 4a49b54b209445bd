from crgpr.commands.smk import run_rule
from crgpr.commands.variant_report import variant_metrics

run_rule(snakemake, variant_metrics, cfg=snakemake.params.cfg, variant=snakemake.wildcards.variant,
         method=snakemake.params.method, angles=list(snakemake.params.angles),
         ground_truth=list(snakemake.input.gt), rollouts=list(snakemake.input.rollouts),
         out=snakemake.output[0])
