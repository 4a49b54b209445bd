from crgpr.commands import ports
from crgpr.commands.smk import run_rule

run_rule(snakemake, ports.actuated_uq, cfg=snakemake.params.cfg, records=list(snakemake.input.records),
         inputs=list(snakemake.input.inputs), signals=list(snakemake.params.signals),
         model_dirs=list(snakemake.input.models), models=list(snakemake.params.models),
         out_csv=snakemake.output.table, out_fig=snakemake.output.figure)
