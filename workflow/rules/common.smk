# Shared paths and helpers of every rule file.
from pathlib import Path

BASE = Path(workflow.basedir)
RESULTS = "results"
ENV = "../envs/crgpr.yaml"  # relative to the rule files in workflow/rules/


def lib(*modules):
    """Library source files a rule depends on (so edits to them trigger reruns)."""
    return [str(BASE / "src" / "crgpr" / f"{m}.py") for m in ("__init__", "io", "params", *modules)]


ANGLES_GT = sorted(
    {config["angles"]["train_deg"]}
    | set(config["angles"]["test_deg"])
    | set(config["angles"]["pinn_train_deg"])
)

# Every stage appends its final targets here; `rule all` collects them.
ALL_TARGETS = []

# Rollout methods whose results/rollouts/{method}/{angle}.parquet the metrics rule gathers;
# each stage that writes rollouts extends it (metrics.smk reads it lazily).
ROLLOUT_METHODS = []


