from crgpr.commands import ports
from crgpr.commands.smk import run_rule

run_rule(snakemake, ports.actuated_learn, cfg=snakemake.params.cfg, model=snakemake.wildcards.model,
         measured=snakemake.input.measured, inputs=snakemake.input.inputs, out_dir=snakemake.output[0])
