from crgpr.commands.blackbox import blackbox_train
from crgpr.commands.smk import run_rule

run_rule(snakemake, blackbox_train, cfg=snakemake.params.cfg, prefiltered=snakemake.input.prefiltered,
         out_dir=snakemake.output.models, summary=snakemake.output.summary)
