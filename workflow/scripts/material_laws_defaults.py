from crgpr.commands import material_report
from crgpr.commands.smk import run_rule

run_rule(snakemake, material_report.material_table, scores=list(snakemake.input.scores),
         out_csv=snakemake.output.table)
