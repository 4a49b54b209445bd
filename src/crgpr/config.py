"""Loading and validating ``config.yaml``: JSON schema plus physical checks.

Every error is a ``ConfigError`` (one line) naming the offending key as a dotted path
(``rod.L0``) and the file or the command-line options it came from. Command-line values
(``crgpr simulate --set/--dt/--t-end``, ``crgpr learn/discover --config/--set``) go through the
same schema and checks as the file.
Non-finite numbers (``.nan``, ``.inf``) are rejected everywhere: JSON schema bounds do
not catch NaN.
"""

from __future__ import annotations

import copy
import functools
import math
from importlib import resources
from pathlib import Path
from typing import Any

import jsonschema
import yaml

from crgpr.physics.params import PARAM_FIELDS, RodParams, SimSettings
from crgpr.physics.rod import check_scheme


class ConfigError(ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range (one line)."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


# the method learned by `crgpr learn` from the camera version of the training run (section camera)
CAMERA_METHOD = "cr_gpr_objective_camera"

class _UniqueKeyLoader(yaml.SafeLoader):
    """YAML's safe loader refusing a key given twice in one mapping (YAML keeps the last one
    silently, so an edit to the first would be lost without a word)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"key {key!r} at line {line} is already given at line {seen[key]}")
            seen[key] = line
        return super().construct_mapping(node, deep=deep)


def read_yaml(path: str | Path) -> Any:
    """A YAML file's document; a mapping key given twice is an error (``yaml.YAMLError``)."""
    return yaml.load(Path(path).read_text(encoding="utf-8"), Loader=_UniqueKeyLoader)  # noqa: S506 (safe loader)


def check_config_files(paths: list[str | Path]) -> None:
    """Each configuration file parses with every key once (ConfigError naming the file, one line):
    the Snakefile's ``configfile`` loader keeps the last of two equal keys without a word."""
    for path in paths:
        try:
            read_yaml(path)
        except FileNotFoundError:
            continue  # Snakemake reports a missing file itself
        except yaml.YAMLError as exc:
            raise ConfigError(f"{path}: not valid YAML: {_short(str(exc))}") from exc


def schema() -> dict[str, Any]:
    """The JSON schema of config.yaml (also used by the Snakefile's ``validate``)."""
    text = resources.files("crgpr").joinpath("schemas/config.schema.yaml").read_text()
    return yaml.safe_load(text)


def schema_defaults(section: str) -> dict[str, Any]:
    """The schema's ``default`` of every key of a config ``section`` that declares one (the
    paper's rod and time grid, Table I and Sec. IV; equal to config.yaml's, checked by a test)."""
    props = schema()["properties"][section]["properties"]
    return {k: v["default"] for k, v in props.items() if "default" in v}


def schema_path() -> Path:
    return Path(str(resources.files("crgpr").joinpath("schemas/config.schema.yaml")))


def _dotted(path: Any) -> str:
    """``rod.L0``; a key that is not a plain word is shown quoted (``rod.'L 0'``)."""
    parts = [str(p) if isinstance(p, int) or (isinstance(p, str) and p.isidentifier()) else repr(p)
             for p in path]
    return ".".join(parts) or "<top level>"


@functools.cache
def _validator() -> jsonschema.protocols.Validator:
    """Validator of the main schema; relative ``$ref``s (stage sections) load from its folder."""
    from referencing import Registry, Resource
    from referencing.jsonschema import DRAFT202012

    base = schema_path().parent

    @functools.cache
    def retrieve(uri: str) -> Resource:  # cached: the registry does not keep what it retrieves
        rel = uri.split("schemas/", 1)[-1] if "schemas/" in uri else uri
        contents = yaml.safe_load((base / rel).read_text())
        contents.pop("$schema", None)  # else jsonschema switches to its own class for the section
        return Resource(contents=contents, specification=DRAFT202012)

    main = schema()
    main["$id"] = base.joinpath("config.schema.yaml").as_uri()
    return _StrictIntegers(main, registry=Registry(retrieve=retrieve))


# JSON schema counts 80.0 as an integer; here an integer is written as one: angles name result
# files ({angle}.parquet), and 80.0 would name 80.0.parquet that no rule makes.
_StrictIntegers = jsonschema.validators.extend(
    jsonschema.Draft202012Validator,
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine(
        "integer", lambda _checker, x: isinstance(x, int) and not isinstance(x, bool)))


def check_plain(value: Any, source: str = "config", path: tuple[Any, ...] = ()) -> None:
    """Reject what JSON schema lets through: non-string keys and non-finite numbers."""
    if isinstance(value, dict):
        for k, v in value.items():
            if not isinstance(k, str):
                raise ConfigError(f"{source}: {_dotted((*path, k))}: keys must be strings, got {k!r}")
            check_plain(v, source, (*path, k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            check_plain(v, source, (*path, i))
    elif isinstance(value, float) and not math.isfinite(value):
        raise ConfigError(f"{source}: {_dotted(path)}: {value} is not a finite number")


def _schema_errors(validator: jsonschema.protocols.Validator, value: Any, source: str,
                   prefix: tuple[Any, ...] = ()) -> None:
    errors = sorted(validator.iter_errors(value), key=lambda e: [str(p) for p in e.absolute_path])
    if not errors:
        return
    msgs = []
    for e in errors[:5]:
        path = (*prefix, *e.absolute_path)
        key = _dotted(path)
        if e.validator == "additionalProperties" and isinstance(e.instance, dict):
            extra = sorted((x for x in set(e.instance) - set(e.schema.get("properties", {}))), key=str)
            msgs.append(f"unknown key(s) {', '.join(_dotted((*path, x)) for x in extra)}")
        else:
            msgs.append(f"{key}: {_short(e.message)}")
    raise ConfigError(f"{source}: invalid configuration: " + "; ".join(msgs))


def _short(msg: str, limit: int = 200) -> str:
    """One line, at most ``limit`` characters (a schema message quotes the whole value)."""
    msg = " ".join(msg.split())
    return msg if len(msg) <= limit else msg[: limit - 3] + "..."


def validate_schema(cfg: dict[str, Any], source: str = "config") -> None:
    """Validate against the schema; raise ConfigError naming the first offending keys."""
    check_plain(cfg, source)
    _schema_errors(_validator(), cfg, source)


def validate_section(name: str, value: Any, source: str) -> None:
    """Validate one top-level section (``rod``, ``simulation``, ...) against its schema."""
    check_plain(value, source, (name,))
    validator = _validator()
    sub = validator.evolve(schema={**validator.schema["properties"][name],
                                   "$id": validator.schema["$id"]})
    _schema_errors(sub, value, source, (name,))


def check_time_grid(params: RodParams, sim: dict[str, Any], source: str = "config") -> None:
    """A stable time step and a whole number of steps (schema-valid ``simulation`` section)."""
    try:
        dt_max = params.dt_stable()
    except (ArithmeticError, ValueError) as exc:
        raise ConfigError(f"{source}: rod: parameters out of numerical range ({exc})") from exc
    if not sim["dt_s"] < dt_max:
        raise ConfigError(
            f"{source}: simulation.dt_s = {sim['dt_s']:g} s is too large for a stable "
            f"Stormer-Verlet run of this rod: the highest frequency bound gives dt < {dt_max:.3g} s")
    n = sim["t_end_s"] / sim["dt_s"]
    if not math.isfinite(n) or abs(n - round(n)) > 1e-6 * n:
        raise ConfigError(f"{source}: simulation.t_end_s / simulation.dt_s = {n:g} is not an integer")
    if n > 1e9:
        raise ConfigError(f"{source}: simulation.t_end_s / simulation.dt_s = {n:g} steps is too many")


def _rod_message(exc: Exception) -> str:
    """``rod: <error>`` unless the error already names its ``rod.`` key."""
    msg = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
    return msg if msg.startswith("rod.") else f"rod: {msg}"


def check_material_scheme(params: RodParams, scheme: str, source: str = "config") -> None:
    """The collocated schemes implement linear laws and a uniform rest curvature only
    (``rod.check_scheme``)."""
    try:
        check_scheme(params, scheme)
    except ValueError as exc:
        raise ConfigError(f"{source}: {exc}") from exc


def check_config(cfg: dict[str, Any], source: str = "config") -> None:
    """Physical and consistency checks the schema cannot express."""
    try:
        params = rod_params(cfg)
    except (TypeError, ValueError, KeyError) as exc:
        raise ConfigError(f"{source}: {_rod_message(exc)}") from exc
    check_material_scheme(params, cfg["simulation"]["scheme"], source)
    check_time_grid(params, cfg["simulation"], source)
    ang = cfg["angles"]
    clash = sorted(set(ang["test_deg"]) & ({ang["train_deg"]} | set(ang["pinn_train_deg"])))
    if clash:
        raise ConfigError(f"{source}: angles.test_deg overlaps the training angles at {clash} deg")
    if ang["train_deg"] not in ang["pinn_train_deg"]:
        raise ConfigError(f"{source}: angles.pinn_train_deg must include angles.train_deg "
                          f"({ang['train_deg']})")
    disc = cfg["discovery"]  # a required section: the schema has checked it is there
    names = [c["name"] for c in disc["cases"]]
    unknown = sorted(set(disc["sweep_cases"]) - set(names))
    if unknown:
        raise ConfigError(f"{source}: discovery.sweep_cases {unknown} are not names of discovery.cases")
    if not set(names) - set(disc["sweep_cases"]):
        raise ConfigError(f"{source}: discovery.sweep_cases leaves no case for `all`")
    ro = cfg["rollouts"]
    unknown = sorted(set(ro["study_methods"]) - set(ro["methods"]))
    if unknown:
        raise ConfigError(f"{source}: rollouts.study_methods {unknown} are not keys of rollouts.methods")
    in_all = [ro["table1_method"], *ro["ablation_methods"], *cfg.get("uq", {}).get("methods", [])]
    clash = sorted(set(in_all) & set(ro["study_methods"]))
    if clash:
        raise ConfigError(f"{source}: rollouts.study_methods {clash} are used by rollouts.table1_method, "
                          "rollouts.ablation_methods or uq.methods (target `all`)")
    if "ports" in cfg:
        study, sigs = cfg["ports"]["study"], cfg["ports"]["signals"]
        named = [study["train_signal"], *study["test_signals"]]
        unknown = sorted({s for s in named if s not in sigs})
        if unknown:
            raise ConfigError(f"{source}: ports.study names {unknown}, not keys of ports.signals")
    if "control" in cfg:
        dt, ctl = float(cfg["simulation"]["dt_s"]), cfg["control"]
        for step in (dt, dt * float(ctl["study"]["fine_dt_factor"])):
            n = 1.0 / (float(ctl["control_rate_hz"]) * step)
            if round(n) < 1 or abs(n - round(n)) > 1e-6:
                raise ConfigError(f"{source}: control.control_rate_hz = {ctl['control_rate_hz']}: one sample "
                                  f"must be a whole number of time steps ({step:g} s, simulation.dt_s and "
                                  "control.study.fine_dt_factor)")
    if "materials_study" in cfg:
        _check_materials_study(cfg, source)
    if "uq" in cfg:
        from crgpr.uq.settings import UQSettings

        known = set(cfg["rollouts"]["methods"]) | ({CAMERA_METHOD} if "camera" in cfg else set())
        unknown = sorted(set(cfg["uq"]["methods"]) - known)
        if unknown:
            raise ConfigError(f"{source}: uq.methods {unknown} are neither keys of rollouts.methods nor "
                              f"{CAMERA_METHOD!r} (the model `crgpr learn` trains from the camera data)")
        UQSettings.from_section(cfg["uq"])


def material_case_rod(cfg: dict[str, Any], case: str) -> RodParams:
    """The true rod of a materials-study case: ``rod`` with ``rod.material`` replaced by
    ``materials_study.cases.<case>`` (an overlay on the linear material: keys it omits keep the
    linear defaults, whatever the config's own ``rod.material``)."""
    rod = copy.deepcopy(cfg["rod"])
    rod["material"] = copy.deepcopy(cfg["materials_study"]["cases"][case])
    return RodParams.from_dict(rod)


def _check_materials_study(cfg: dict[str, Any], source: str) -> None:
    """Every case's true rod is valid on the config's scheme and time step, and the camera rate
    divides the record rate."""
    ms = cfg["materials_study"]
    for case in ms["cases"]:
        key = f"materials_study.cases.{case}"
        try:
            params = material_case_rod(cfg, case)
        except (TypeError, ValueError, KeyError) as exc:
            raise ConfigError(f"{source}: {key}: {_rod_message(exc)}") from exc
        check_material_scheme(params, ms["scheme"], f"{source}: {key}")
        check_time_grid(params, cfg["simulation"], f"{source}: {key}")
    sim = cfg["simulation"]
    every = 1.0 / (float(ms["camera_rate_hz"]) * float(sim["dt_s"]) * int(sim["record_every"]))
    if round(every) < 1 or abs(every - round(every)) > 1e-6 * every:
        raise ConfigError(f"{source}: materials_study.camera_rate_hz = {ms['camera_rate_hz']}: one frame "
                          "must be a whole number of records (simulation.dt_s x simulation.record_every)")
    for key in ("t_end_s", "rollout_t_end_s"):
        n = float(ms[key]) / float(sim["dt_s"])
        if abs(n - round(n)) > 1e-6 * n:
            raise ConfigError(f"{source}: materials_study.{key} / simulation.dt_s = {n:g} is not an integer")


def load_config(path: str | Path | None = None, overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Read, merge ``overrides`` (nested dict) and validate a configuration file."""
    path = Path(path) if path is not None else Path("config.yaml")
    try:
        cfg = read_yaml(path)
    except FileNotFoundError as exc:
        raise ConfigError(f"config file not found: {path}") from exc
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {_short(str(exc))}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML: {_short(str(exc))}") from exc
    except (RecursionError, ValueError, TypeError, OverflowError) as exc:  # pathological YAML
        raise ConfigError(f"{path}: not a usable YAML document: {_short(str(exc))}") from exc
    if not isinstance(cfg, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level")
    if overrides:
        cfg = deep_merge(cfg, overrides)
    validate_config(cfg, str(path))
    return cfg


def validate_config(cfg: dict[str, Any], source: str = "config") -> None:
    """Schema, plain-data and physical checks; raises ConfigError (one line)."""
    try:
        validate_schema(cfg, source)
    except RecursionError as exc:
        raise ConfigError(f"{source}: nested too deeply") from exc
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
                       record_every=int(s["record_every"]), scheme=str(s["scheme"]))


def parse_set(items: list[str]) -> dict[str, Any]:
    """Parse ``KEY=VALUE`` rod-parameter overrides from the command line (``--set E=2e6``, or
    with the section named as in ``crgpr learn``: ``--set rod.E=2e6``); a key of the material
    section (``--set material.bending_law=exponential``, ``--set rod.material.bending_beta=0.05``,
    ``--set "material.stiffness_profile=[[0, 1.5], [1, 0.6]]"``) is returned under ``material``,
    its value read as YAML.

    Only the syntax is checked here (a known key and a number); ``cli_rod_sim`` validates
    the values by the config file's rules.
    """
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE")
        key, raw = item.split("=", 1)
        key = key.strip().removeprefix("rod.")
        if key.startswith("material."):
            try:
                out.setdefault("material", {})[key.removeprefix("material.")] = yaml.safe_load(raw)
            except yaml.YAMLError as exc:
                raise ConfigError(f"--set {key}={raw!r}: not a value ({_short(str(exc), 80)})") from exc
            continue
        if key not in PARAM_FIELDS:
            raise ConfigError(f"--set {key}: unknown rod parameter; known: {', '.join(PARAM_FIELDS)}")
        try:
            val: Any = int(raw)
        except ValueError:
            try:
                val = float(raw)
            except ValueError as exc:
                raise ConfigError(f"--set {key}={raw!r}: not a number") from exc
        out[key] = val
    return out


# rod effects (RodParams fields that config.yaml's rod section does not have) and the name
# under which the discovery section's ``cases[].effects`` states their rules
_EFFECT_RULES = {"viscous_drag": "viscous_drag", "air_drag": "air_drag", "tip_mass": "tip_mass",
                 "nonlinear_stiffness": "nonlinear_stiffness", "stiffness_gradient": "stiffness_gradient",
                 "base_spring": "base_compliance"}


def _check_effects(effects: dict[str, Any], source: str) -> None:
    """Effect overrides by the rules of ``discovery.cases[].effects`` (base_spring = inf: clamp)."""
    if not effects:
        return
    disc = yaml.safe_load((schema_path().parent / "sections" / "discovery.schema.yaml").read_text())
    rules = disc["properties"]["cases"]["items"]["properties"]["effects"]["properties"]
    props = {k: rules[v] for k, v in _EFFECT_RULES.items() if v in rules}
    checked = {k: v for k, v in effects.items() if not (k == "base_spring" and v == math.inf)}
    check_plain(checked, source, ("rod",))
    sub = {"type": "object", "properties": props}
    _schema_errors(jsonschema.Draft202012Validator(sub), checked, source, ("rod",))


def cli_rod_sim(rod: dict[str, Any], sim: dict[str, Any], sets: list[str], dt: float | None = None,
                t_end: float | None = None, record_every: int | None = None,
                base: str = "defaults", scheme: str | None = None) -> tuple[RodParams, SimSettings]:
    """Rod parameters and time grid from a config's ``rod``/``simulation`` sections plus
    command-line overrides, validated by the config file's schema and checks.

    ``rod`` and ``sim`` are the sections (``simulation`` keys ``dt_s``, ``t_end_s``,
    ``record_every``, ``scheme``); ``base`` names where they came from, for the messages. An option
    given as 0 is a value (and rejected), not "use the config".
    """
    given = [f"--set {x}" for x in sets]
    given += [f"{flag} {v:g}" for flag, v in (("--dt", dt), ("--t-end", t_end),
                                               ("--record-every", record_every)) if v is not None]
    given += [f"--scheme {scheme}"] if scheme is not None else []
    source = f"{base} with {' '.join(given)}" if given else base
    overrides = parse_set(sets)
    rod_keys = set(schema()["properties"]["rod"]["properties"])
    material = {**rod.get("material", {}), **overrides.pop("material", {})}
    rod = {**rod, **{k: v for k, v in overrides.items() if k in rod_keys}}
    if material:
        rod["material"] = material
    effects = {k: v for k, v in overrides.items() if k not in rod_keys}
    sim = dict(sim)
    for key, v in (("dt_s", dt), ("t_end_s", t_end), ("record_every", record_every), ("scheme", scheme)):
        if v is not None:
            sim[key] = v
    validate_section("rod", rod, source)
    _check_effects(effects, source)
    validate_section("simulation", sim, source)
    try:
        params = RodParams.from_dict({**rod, **effects})
    except (TypeError, ValueError, KeyError) as exc:
        raise ConfigError(f"{source}: {_rod_message(exc)}") from exc
    check_material_scheme(params, str(sim["scheme"]), source)
    check_time_grid(params, sim, source)
    return params, SimSettings(dt=float(sim["dt_s"]), t_end=float(sim["t_end_s"]),
                               record_every=int(sim["record_every"]), scheme=str(sim["scheme"]))


def packaged_config_path() -> Path:
    """The default configuration shipped with the package: the repository's config.yaml (the
    paper's rod, Table I, and the project's settings), for commands run outside a checkout."""
    return Path(str(resources.files("crgpr").joinpath("data/config.yaml")))


def parse_config_sets(items: list[str], cfg: dict[str, Any]) -> dict[str, Any]:
    """``KEY=VALUE`` overrides of a configuration ``cfg`` as a nested dict (for ``deep_merge``).

    KEY is a rod parameter of the ``rod`` section (``L0``, as ``crgpr simulate --set``) or the
    dotted path of any key of ``cfg`` (``rod.L0``, ``camera.learn.edge_trim_s``). VALUE is read
    as an integer, else a float, else YAML (``true``, ``[kappa]``, a word). Only the syntax and
    the key are checked here; the values are validated with the whole configuration.
    """
    rod_keys = set(schema()["properties"]["rod"]["properties"])
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ConfigError(f"--set {item!r}: expected KEY=VALUE")
        key, raw = (part.strip() for part in item.split("=", 1))
        path = key.split(".") if "." in key else ["rod", key]
        if "." not in key and key not in rod_keys:
            raise ConfigError(f"--set {key}: not a rod parameter (known: {', '.join(sorted(rod_keys))}); "
                              "another config value is named by its dotted key, e.g. rod.L0")
        node: Any = cfg
        for i, part in enumerate(path):
            if not isinstance(node, dict) or part not in node:
                raise ConfigError(f"--set {key}: unknown config key {'.'.join(path[:i + 1])}")
            node = node[part]
        try:
            val: Any = int(raw)
        except ValueError:
            try:
                val = float(raw)
            except ValueError:
                try:
                    val = yaml.safe_load(raw)
                except yaml.YAMLError as exc:
                    raise ConfigError(f"--set {key}={raw!r}: not a value ({_short(str(exc), 80)})") from exc
        nested: Any = val
        for part in reversed(path):
            nested = {part: nested}
        out = deep_merge(out, nested)
    return out


def cli_config(path: str | None, sets: list[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """The configuration of a command that reads measured data, taken as ``crgpr simulate``
    takes its rod: ``--config FILE``, else ``./config.yaml`` if it exists, else the packaged
    default (``packaged_config_path``: the paper's rod); then the ``--set`` overrides
    (``parse_config_sets``), the result validated as a config file is.

    Returns the configuration and its provenance (``config``: the file or "the packaged default
    config"; ``set``: the overrides as given) for the output's manifest.
    """
    if path:
        base_path, source = Path(path), str(path)
    elif Path("config.yaml").exists():
        base_path, source = Path("config.yaml"), "config.yaml"
    else:
        base_path, source = packaged_config_path(), "the packaged default config"
    cfg = load_config(base_path)
    if sets:
        cfg = deep_merge(cfg, parse_config_sets(sets, cfg))
        validate_config(cfg, f"{source} with {' '.join(f'--set {x}' for x in sets)}")
    return cfg, {"config": source, "set": list(sets)}


def add_config_options(parser: Any, what: str) -> None:
    """``--config`` and ``--set`` of a command that reads measured data (``cli_config``);
    ``parser`` is its ``argparse`` parser, ``what`` names the values it takes from the config."""
    parser.add_argument("--config", default=None, help=f"config.yaml with {what} (default: ./config.yaml "
                        "if it exists, else the packaged default config: the paper's rod)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                        help="override a rod parameter (E=2e6) or any config value by its dotted key "
                             "(rod.L0=0.4, camera.learn.edge_trim_s=0.1); repeatable")
