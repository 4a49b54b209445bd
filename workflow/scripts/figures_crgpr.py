from crgpr.commands.report import figures_crgpr
from crgpr.commands.smk import run_rule

i, o = snakemake.input, snakemake.output
run_rule(snakemake, figures_crgpr, cfg=snakemake.params.cfg, method=snakemake.wildcards.method,
         angle=float(snakemake.wildcards.angle), gt_train=i.gt_train, gt_test=i.gt_test,
         gt_test_energy=i.gt_test_energy, rollout=i.rollout, rollout_energy=i.rollout_energy,
         overlays_out=o.overlays, shapes_out=o.shapes, energy_out=o.energy)
