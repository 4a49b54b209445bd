from crgpr.commands.smk import run_rule
from crgpr.learning import learned

run_rule(snakemake, learned.rule, cfg=snakemake.config, method=snakemake.wildcards.method,
         angle=int(snakemake.wildcards.angle), out=snakemake.output.traj, energy_out=snakemake.output.energy,
         model_json=snakemake.input.models[0])
