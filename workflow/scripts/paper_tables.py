from crgpr.commands.smk import run_rule
from crgpr.report import paper

i, o = snakemake.input, snakemake.output
run_rule(snakemake, paper.build, values_path=i.values, accuracy=i.accuracy, hyper=i.hyper, timing=i.timing,
         uq=i.uq, out_csv=o.csv, out_md=o.md, out_claims=o.claims, noise=i.noise)
