from crgpr.commands.simulate import ground_truth
from crgpr.commands.smk import run_rule

run_rule(snakemake, ground_truth, cfg=snakemake.params.cfg, angle=int(snakemake.wildcards.angle),
         out=snakemake.output.traj, energy_out=snakemake.output.energy)
