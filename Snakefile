"""crgpr: reproduce CR-GPR (Cosserat rod + Gaussian processes) end to end.

    snakemake -j2 all                     # the paper, with config.yaml
    snakemake -j2 all --configfile tests/smoke_config.yaml    # tiny smoke run

Rules live in workflow/rules/, one file per pipeline stage; each writes Parquet under
results/. Library code is in src/crgpr; every rule lists the modules it uses as inputs
so that editing them reruns what depends on them.
"""

from snakemake.utils import min_version, validate

min_version("9.0")


configfile: "config.yaml"


validate(config, "src/crgpr/schemas/config.schema.yaml")

from crgpr.config import check_config  # noqa: E402

check_config(config, "config")

include: "workflow/rules/common.smk"
include: "workflow/rules/ground_truth.smk"
include: "workflow/rules/baselines.smk"
include: "workflow/rules/prefilter.smk"
include: "workflow/rules/models.smk"
include: "workflow/rules/rollouts.smk"
include: "workflow/rules/metrics.smk"
include: "workflow/rules/uq.smk"
include: "workflow/rules/discovery.smk"
include: "workflow/rules/camera.smk"
include: "workflow/rules/paper.smk"


rule all:
    default_target: True
    input:
        ALL_TARGETS,
