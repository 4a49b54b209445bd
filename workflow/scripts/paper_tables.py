from crgpr.commands.report import paper_tables
from crgpr.commands.smk import run_rule

i, o = snakemake.input, snakemake.output
run_rule(snakemake, paper_tables, values=i.values, accuracy=i.accuracy, hyper=i.hyper, timing=i.timing,
         uq=i.uq, out_csv=o.csv, out_md=o.md, out_claims=o.claims)
