from crgpr.commands import ports
from crgpr.commands.smk import run_rule

run_rule(snakemake, ports.actuated_data, cfg=snakemake.params.cfg, signal=snakemake.wildcards.signal,
         out=snakemake.output.traj, energy_out=snakemake.output.energy, inputs_out=snakemake.output.inputs)
