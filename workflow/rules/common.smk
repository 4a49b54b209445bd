# Shared paths and functions of every rule file.
import threading
from pathlib import Path

from crgpr.commands.deps import code_closure as _code_closure
from crgpr.commands.smk import config_subset as _config_subset

BASE = Path(workflow.basedir)
RESULTS = "results"
ENV = "../envs/crgpr.yaml"  # relative to the rule files in workflow/rules/


def code_closure(script):
    """Library files a rule's script imports, transitively (editing one reruns the rule)."""
    return _code_closure(BASE / "workflow" / "scripts" / script, BASE / "src")


def cancel_pending_scheduler_passes():
    """End the job rate limiter's pending re-scheduling timers (profiles/default,
    ``max-jobs-per-timespan``), so that Snakemake exits when the last job ends, not a timespan later."""
    for thread in threading.enumerate():
        if isinstance(thread, threading.Timer):
            thread.cancel()


onsuccess:
    cancel_pending_scheduler_passes()


onerror:
    cancel_pending_scheduler_passes()


def _one_of(methods):
    """Wildcard constraint matching exactly these names (none: a rule that matches nothing)."""
    return "|".join(methods) if methods else "(?!)"


def cfg_params(*keys):
    """A rule's ``params: cfg=``: the config values at dotted ``keys`` its output depends on.

    Snakemake reruns a job whose params changed; the rule function reads ``cfg`` and nothing
    else of the config (see ARCHITECTURE.md, "Conventions").
    """
    return _config_subset(config, *keys)


ANGLES_GT = sorted(
    {config["angles"]["train_deg"]}
    | set(config["angles"]["test_deg"])
    | set(config["angles"]["pinn_train_deg"])
)

# Every stage appends its final targets here; `rule all` collects them.
ALL_TARGETS = []

# Methods whose models are a `crgpr learn` directory (method -> directory; camera.smk): their
# UQ samples every learned GP of the directory in one job (uq.smk).
LEARNED_MODEL_DIRS = {}

# Rollout methods whose results/rollouts/{method}/{angle}.parquet the metrics rule gathers;
# each stage that writes rollouts extends it (report.smk's metrics rule reads it lazily).
ROLLOUT_METHODS = []
# Methods scored by a pipeline variant against its own ground truth (variants.smk): method ->
# the variant's accuracy file, whose rows the metrics rule adds under that name.
VARIANT_METHODS = {}
# Final targets of `snakemake sweeps` (Snakefile): studies that do not fit the budget of `all`.
SWEEP_TARGETS = []


# Trajectory UQ (uq.smk, paper.smk): the gradient models and sample files of a UQ method.
def _uq_models(method):
    """Gradient-model stems (results/models/{prefilter}/{model}) of one UQ method."""
    from crgpr.learning.learned import model_files

    return [j.removesuffix(".json") for j in model_files(RESULTS, config["rollouts"]["methods"][method])]


def _uq_sample_files(method):
    return [f"{RESULTS}/uq/{method}/samples/{Path(s).name}.npz" for s in _uq_models(method)]


def _uq_model_of(wc):
    stems = {Path(s).name: s for s in _uq_models(wc.method)}
    return f"{stems[wc.model]}.npz"
