from crgpr.commands.models import gradient_model_paper_hyp
from crgpr.commands.smk import run_rule

run_rule(snakemake, gradient_model_paper_hyp, cfg=snakemake.params.cfg, model=snakemake.wildcards.model,
         prefilter_method=snakemake.wildcards.prefilter, prefiltered=snakemake.input.prefiltered,
         out_npz=snakemake.output.npz, gt_tests=list(snakemake.input.gt_tests))
