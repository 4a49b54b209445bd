from crgpr.commands.discovery import discovery_summary
from crgpr.commands.smk import run_rule

p = snakemake.params  # noqa: F821
run_rule(snakemake, discovery_summary, cases=list(p.cases), truths=list(snakemake.input.truth),  # noqa: F821
         results=list(snakemake.input.results), min_gap_rad=float(p.min_gap_rad),  # noqa: F821
         out_csv=snakemake.output.table, out_fig=snakemake.output.figure)  # noqa: F821
