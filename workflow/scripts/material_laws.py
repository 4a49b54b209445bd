from crgpr.commands import material_report
from crgpr.commands.smk import run_rule

run_rule(snakemake, material_report.material_laws, cfg=snakemake.params.cfg, cases=snakemake.params.cases,
         scores=list(snakemake.input.scores), tips=list(snakemake.input.tips),
         model_dirs=list(snakemake.input.models), trains=list(snakemake.input.trains),
         out_csv=snakemake.output.table, figures=list(snakemake.output.figures))
