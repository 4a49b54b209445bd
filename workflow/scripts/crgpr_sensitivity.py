from crgpr.commands.smk import run_rule
from crgpr.commands.variant_report import crgpr_sensitivity

run_rule(snakemake, crgpr_sensitivity, cfg=snakemake.params.cfg, variants=list(snakemake.params.variants),
         accuracy=list(snakemake.input.accuracy), table_out=snakemake.output.table,
         figure_out=snakemake.output.figure)
