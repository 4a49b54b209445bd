from crgpr.commands import ports
from crgpr.commands.smk import run_rule

run_rule(snakemake, ports.actuated_camera, cfg=snakemake.params.cfg, record=snakemake.input.record,
         out=snakemake.output[0])
