from crgpr.commands import simulate as ground_truth
from crgpr.commands.smk import run_rule

run_rule(snakemake, ground_truth.rule, cfg=snakemake.config, angle=int(snakemake.wildcards.angle),  # noqa: F821
         out=snakemake.output.traj, energy_out=snakemake.output.energy)  # noqa: F821
