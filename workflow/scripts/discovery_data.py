from crgpr.commands.discovery import discovery_data
from crgpr.commands.smk import run_rule

p = snakemake.params  # noqa: F821
run_rule(snakemake, discovery_data, rod=dict(p.rod), discovery=dict(p.discovery), seed=int(p.seed),  # noqa: F821
         case=snakemake.wildcards.case, out=snakemake.output.measured,  # noqa: F821
         truth_out=snakemake.output.truth)  # noqa: F821
