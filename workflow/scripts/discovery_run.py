from crgpr.commands.discovery import discovery_run
from crgpr.commands.smk import run_rule

p = snakemake.params  # noqa: F821
run_rule(snakemake, discovery_run, rod=dict(p.rod), dt_s=float(p.dt_s), discovery=dict(p.discovery),  # noqa: F821
         seed=int(p.seed), measured=snakemake.input.measured, out_dir=p.out_dir)  # noqa: F821
