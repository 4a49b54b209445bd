from crgpr.commands.report import paper_claims_sweeps
from crgpr.commands.smk import run_rule

i = snakemake.input  # noqa: F821
run_rule(snakemake, paper_claims_sweeps, values=i.values, noise=i.noise,  # noqa: F821
         out_claims=snakemake.output.claims)  # noqa: F821
