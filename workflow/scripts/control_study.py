from crgpr.commands import control
from crgpr.commands.smk import run_rule

run_rule(snakemake, control.control_study, cfg=snakemake.params.cfg, model_dir=snakemake.input.models,
         out_csv=snakemake.output.table, out_fig=snakemake.output.figure)
