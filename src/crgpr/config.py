"""Loading and validating ``config.yaml``: JSON schema plus physical checks.

Every error names the offending key as a dotted path (``rod.L0``) and the file.
"""

from __future__ import annotations

import copy
import math
from importlib import resources
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from crgpr.physics.params import PARAM_FIELDS, RodParams, SimSettings


class ConfigError(ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""


def schema() -> dict[str, Any]:
    """The JSON schema of config.yaml (also used by the Snakefile's ``validate``)."""
    text = resources.files("crgpr").joinpath("schemas/config.schema.yaml").read_text()
    return yaml.safe_load(text)


def schema_path() -> Path:
    return Path(str(resources.files("crgpr").joinpath("schemas/config.schema.yaml")))


def _dotted(path: Any) -> str:
    return ".".join(str(p) for p in path) or "<top level>"


def _validator() -> jsonschema.Draft202012Validator:
    """Validator of the main schema; relative ``$ref``s (stage sections) load from its folder."""
    from referencing import Registry, Resource

    base = schema_path().parent

    def retrieve(uri: str) -> Resource:
        rel = uri.split("schemas/", 1)[-1] if "schemas/" in uri else uri
        return Resource.from_contents(yaml.safe_load((base / rel).read_text()))

    main = schema()
    main["$id"] = base.joinpath("config.schema.yaml").as_uri()
    return jsonschema.Draft202012Validator(main, registry=Registry(retrieve=retrieve))


def validate_schema(cfg: dict[str, Any], source: str = "config") -> None:
    """Validate against the schema; raise ConfigError naming the first offending key."""
    validator = _validator()
    errors = sorted(validator.iter_errors(cfg), key=lambda e: list(e.absolute_path))
    if not errors:
        return
    msgs = []
    for e in errors[:5]:
        key = _dotted(e.absolute_path)
        if e.validator == "additionalProperties":
            extra = sorted(set(e.instance) - set(e.schema.get("properties", {})))
            where = f"{key}." if e.absolute_path else ""
            msgs.append(f"unknown key(s) {', '.join(where + x for x in extra)}")
        else:
            msgs.append(f"{key}: {e.message}")
    raise ConfigError(f"{source}: invalid configuration: " + "; ".join(msgs))


def check_config(cfg: dict[str, Any], source: str = "config") -> None:
    """Physical and consistency checks the schema cannot express."""
    params = rod_params(cfg)
    sim = cfg["simulation"]
    dt_max = params.dt_stable()
    if sim["dt_s"] >= dt_max:
        raise ConfigError(
            f"{source}: simulation.dt_s = {sim['dt_s']:g} s is too large for a stable "
            f"Stormer-Verlet run of this rod: the highest frequency bound gives dt < {dt_max:.3g} s")
    n = sim["t_end_s"] / sim["dt_s"]
    if abs(n - round(n)) > 1e-6 * n:
        raise ConfigError(f"{source}: simulation.t_end_s / simulation.dt_s = {n:g} is not an integer")
    ang = cfg["angles"]
    clash = sorted(set(ang["test_deg"]) & ({ang["train_deg"]} | set(ang["pinn_train_deg"])))
    if clash:
        raise ConfigError(f"{source}: angles.test_deg overlaps the training angles at {clash} deg")
    if ang["train_deg"] not in ang["pinn_train_deg"]:
        raise ConfigError(f"{source}: angles.pinn_train_deg must include angles.train_deg "
                          f"({ang['train_deg']})")
    if "uq" in cfg:
        from crgpr.uq.settings import UQSettings

        unknown = sorted(set(cfg["uq"]["methods"]) - set(cfg["rollouts"]["methods"]))
        if unknown:
            raise ConfigError(f"{source}: uq.methods {unknown} are not keys of rollouts.methods")
        UQSettings.from_section(cfg["uq"])


def load_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Read, merge ``overrides`` (nested dict) and validate a configuration file."""
    path = Path(path) if path is not None else Path("config.yaml")
    try:
        cfg = yaml.safe_load(path.read_text())
    except FileNotFoundError as exc:
        raise ConfigError(f"config file not found: {path}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {exc}") from exc
    if not isinstance(cfg, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level")
    if overrides:
        cfg = deep_merge(cfg, overrides)
    validate_config(cfg, str(path))
    return cfg


def validate_config(cfg: dict[str, Any], source: str = "config") -> None:
    validate_schema(cfg, source)
    check_config(cfg, source)


def deep_merge(base: dict[str, Any], extra: dict[str, Any]) -> dict[str, Any]:
    out = copy.deepcopy(base)
    for k, v in extra.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = deep_merge(out[k], v)
        else:
            out[k] = v
    return out


def rod_params(cfg: dict[str, Any]) -> RodParams:
    """RodParams from the ``rod`` section (extra effect keys allowed, see RodParams)."""
    return RodParams.from_dict(dict(cfg["rod"]))


def sim_settings(cfg: dict[str, Any]) -> SimSettings:
    s = cfg["simulation"]
    return SimSettings(dt=float(s["dt_s"]), t_end=float(s["t_end_s"]),
                       record_every=int(s["record_every"]))


def parse_set(items: list[str]) -> dict[str, Any]:
    """Parse ``KEY=VALUE`` rod-parameter overrides from the command line (``--set E=2e6``)."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE")
        key, raw = item.split("=", 1)
        key = key.strip()
        if key not in PARAM_FIELDS:
            raise ConfigError(f"--set {key}: unknown rod parameter; known: {', '.join(PARAM_FIELDS)}")
        try:
            val = float(raw)
        except ValueError as exc:
            raise ConfigError(f"--set {key}={raw!r}: not a number") from exc
        if not math.isfinite(val) and key != "base_spring":
            raise ConfigError(f"--set {key}={raw!r}: must be finite")
        out[key] = int(val) if key == "N" else val
    return out
