# Pipeline variants (rules in variants.smk): each variant's overlaid config and where
# each of its stages' files lie (its own under results/variants/{variant}/, or the main run's
# when the stage's config values and inputs equal the main run's).

import re
import sys
from functools import cache
from types import SimpleNamespace

from crgpr.commands.smk import config_subset as _config_subset
from crgpr.commands.variants import dotted_keys as _dotted_keys
from crgpr.commands.variants import variant_configs as _variant_configs
from crgpr.config import ConfigError as _ConfigError

try:
    VARIANT_CFG = _variant_configs(config, "config", tuple(ROLLOUT_METHODS))
except _ConfigError as _exc:
    print(f"crgpr: error: {_exc}", file=sys.stderr)
    sys.exit(2)
VROOT = f"{RESULTS}/variants"
_VDEF = config["variants"]["definitions"]


def _cfg_of(rule, wc, cfg):
    """``cfg``'s values of the dotted keys the main ``rule`` declares as ``params: cfg=``."""
    base = rule.rule.params.cfg
    base = base(wc) if callable(base) else base
    return _config_subset(cfg, *_dotted_keys(base, config))


def variant_params(rule):
    """A variant rule's ``params: cfg=``: the main rule's keys, read from the variant's config."""
    return lambda wc: _cfg_of(rule, wc, VARIANT_CFG[wc.variant])


def _own(variant, rule, wc, inputs=(), main_inputs=()):
    """Whether a variant's job differs from the main run's: its params or its inputs do."""
    wc = SimpleNamespace(**wc)
    return (list(inputs) != list(main_inputs)
            or _cfg_of(rule, wc, VARIANT_CFG[variant]) != _cfg_of(rule, wc, config))


def _root(variant, own):
    return f"{VROOT}/{variant}" if own else RESULTS


@cache
def v_ground_truth(variant, angle):
    """Step 1: the variant's ground truth at ``angle`` (the main one when rod and simulation agree)."""
    own = variant is not None and _own(variant, rules.ground_truth, {"angle": angle})
    return f"{_root(variant, own)}/ground_truth/{angle}.parquet"


@cache
def v_prefilter(variant, method, angle):
    """Step 2: the variant's prefiltered trajectory (prefilter ``method``, gp or fd)."""
    gt = [v_ground_truth(variant, angle)]
    own = variant is not None and _own(variant, rules.prefilter, {"method": method, "angle": angle},
                                       gt, [v_ground_truth(None, angle)])
    return f"{_root(variant, own)}/prefilter/{method}/{angle}.parquet"


@cache
def v_models_root(variant, method):
    """Step 3: the results root (main or variant) of a variant method's gradient GPs: all in
    the variant's directory when any of them differs (a rollout reads one directory)."""
    spec = config["rollouts"]["methods"][method]
    pf = spec["prefilter"]
    if variant is None:
        return RESULTS
    pre = [v_prefilter(variant, pf, VARIANT_CFG[variant]["angles"]["train_deg"])]
    main_pre = [v_prefilter(None, pf, config["angles"]["train_deg"])]
    own = any(_own(variant, rules.gradient_model, {"prefilter": pf, "model": Path(j).stem}, pre, main_pre)
              for j in _model_files(RESULTS, spec))
    return _root(variant, own)


def v_model_files(variant, method):
    """The model JSON files a variant's rollout of ``method`` reads."""
    return _model_files(v_models_root(variant, method), config["rollouts"]["methods"][method])


@cache
def v_rollout(variant, angle):
    """Step 4: the variant method's rollout at ``angle``."""
    method = _VDEF[variant]["method"]
    own = _own(variant, rules.rollout, {"method": method, "angle": angle},
               v_model_files(variant, method), v_model_files(None, method))
    return (f"{VROOT}/{variant}/rollouts/{method}/{angle}.parquet" if own
            else f"{RESULTS}/rollouts/{method}/{angle}.parquet")


def v_accuracy(variant):
    return f"{VROOT}/{variant}/metrics/accuracy.parquet"


_VARIANT_RE = "|".join(re.escape(v) for v in _VDEF)
