"""Pipeline variants: the faithful CR-GPR pipeline rerun under a config overlay.

A variant is an entry of ``variants.definitions`` in config.yaml: a rollout method (a key of
``rollouts.methods``: its prefilter and feature set) and an ``overlay``, a partial configuration
deep-merged onto the main one (``crgpr.config.deep_merge``). workflow/rules/variants.smk reruns
steps 1-4 of the paper's Sec. III-B (ground truth, prefilter, gradient GPs, test-angle rollouts)
with the main rules and scripts on the overlaid config, under ``results/variants/{name}/``; a
stage whose config values (the same dotted keys as the main rule's ``params: cfg=``) and inputs
equal the main run's reuses the main run's file. This module holds the Snakefile-time part
(overlaid configs, the keys of a rule's params); a variant's rollouts are rule ``rollout``'s
command (``learning.learned.run_rollout``, divergence included); the variants'
metrics and the sensitivity table are ``crgpr.commands.variant_report``.
"""

from __future__ import annotations

import copy
import logging
from collections.abc import Mapping
from typing import Any

from crgpr.config import ConfigError, deep_merge, validate_config

log = logging.getLogger(__name__)


def variant_config(config: Mapping[str, Any], name: str, source: str = "config") -> dict[str, Any]:
    """The main ``config`` with variant ``name``'s overlay deep-merged onto it, validated.

    The result is checked like config.yaml itself (schema and physical checks); an error is a
    one-line ``ConfigError`` naming ``variants.definitions.<name>.overlay``.
    """
    spec = config["variants"]["definitions"][name]
    where = f"{source}: variants.definitions.{name}.overlay"
    base = {k: copy.deepcopy(v) for k, v in config.items() if k != "variants"}
    merged = deep_merge(base, spec["overlay"])
    # the variants section is the main config's (an overlay cannot set it; the schema says so)
    merged["variants"] = copy.deepcopy(config["variants"])
    validate_config(merged, where)
    if spec["method"] not in config["rollouts"]["methods"]:
        raise ConfigError(f"{source}: variants.definitions.{name}.method: {spec['method']!r} is not a key "
                          f"of rollouts.methods ({', '.join(config['rollouts']['methods'])})")
    if merged["rollouts"]["methods"][spec["method"]] != config["rollouts"]["methods"][spec["method"]]:
        raise ConfigError(f"{where}: rollouts.methods.{spec['method']}: a variant keeps its method's "
                          "prefilter and features (choose another method instead)")
    return merged


def variant_configs(config: Mapping[str, Any], source: str = "config",
                    taken: tuple[str, ...] = ()) -> dict[str, dict[str, Any]]:
    """Every variant's overlaid config; the references in ``variants`` checked.

    ``taken``: method names already used by the workflow (``variants.methods`` must not
    reuse one).
    """
    v = config["variants"]
    defs = v["definitions"]
    for key, names in (("methods", list(v["methods"].values())), ("sensitivity", v["sensitivity"])):
        unknown = [n for n in names if n not in defs]
        if unknown:
            raise ConfigError(f"{source}: variants.{key}: {', '.join(map(repr, unknown))} not in "
                              "variants.definitions")
    clash = sorted(set(v["methods"]) & (set(config["rollouts"]["methods"]) | set(taken)))
    if clash:
        raise ConfigError(f"{source}: variants.methods: {', '.join(clash)} already name a rollout method")
    return {name: variant_config(config, name, source) for name in defs}


def dotted_keys(subset: Mapping[str, Any], config: Mapping[str, Any], prefix: str = "") -> list[str]:
    """The dotted keys that ``crgpr.commands.smk.config_subset(config, *keys)`` gave ``subset``.

    A key is the shallowest path where ``subset`` holds the whole of ``config``'s value
    (``"rod"`` for the whole section, ``"prefilter.n_t_out"`` for one value), so a variant
    rule reads the same keys from its overlaid config as the main rule does from config.yaml.
    """
    keys = []
    for k, sub in subset.items():
        path = f"{prefix}{k}"
        full = config[k]
        if sub == full or not isinstance(sub, Mapping):
            keys.append(path)
        else:
            keys.extend(dotted_keys(sub, full, f"{path}."))
    return keys


