"""The config loader under arbitrary input: it returns a valid config or raises ConfigError
(one line), never anything else (hypothesis)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crgpr.config import ConfigError, load_config, validate_config

SMOKE_PATH = Path(__file__).parent / "smoke_config.yaml"
SMOKE = yaml.safe_load(SMOKE_PATH.read_text())


def _paths(node: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix] if prefix else []
    if isinstance(node, dict):
        for k, v in node.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            out += _paths(v, (*prefix, i))
    return out


PATHS = _paths(SMOKE)
SCALARS = st.one_of(
    st.none(), st.booleans(), st.integers(), st.integers(min_value=-(10**40), max_value=10**40),
    st.floats(allow_nan=True, allow_infinity=True), st.floats(min_value=-1e300, max_value=1e300),
    st.text(max_size=12),
)
KEYS = st.one_of(st.text(max_size=6), st.integers(), st.booleans(), st.none())
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(KEYS, inner, max_size=4)), max_leaves=10)


@st.composite
def mutated_configs(draw: st.DrawFn) -> dict[str, Any]:
    """The smoke config with 1-3 keys replaced by arbitrary values, deleted or added."""
    cfg = copy.deepcopy(SMOKE)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(PATHS))
        node: Any = cfg
        try:
            for p in path[:-1]:
                node = node[p]
            op = draw(st.sampled_from(["set", "delete", "add"]))
            if op == "set":
                node[path[-1]] = draw(VALUES)
            elif op == "delete":
                del node[path[-1]]
            elif isinstance(node, dict):
                node[draw(st.text(max_size=6))] = draw(VALUES)
        except (KeyError, IndexError, TypeError):  # an earlier mutation removed the parent
            pass
    return cfg


def _valid_or_config_error(call) -> None:
    try:
        call()
    except ConfigError as exc:
        assert "\n" not in str(exc) and str(exc)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_configs())
def test_any_mutation_of_a_valid_config_is_accepted_or_a_config_error(cfg):
    _valid_or_config_error(lambda: validate_config(cfg, "fuzz"))


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                   HealthCheck.function_scoped_fixture])
@given(mutated_configs())
def test_any_mutated_config_file_loads_or_fails_with_a_config_error(tmp_path, cfg):
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(cfg, allow_unicode=True))
    _valid_or_config_error(lambda: load_config(path))


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.one_of(st.binary(max_size=300), st.text(max_size=300).map(str.encode),
                 st.sampled_from(SMOKE_PATH.read_bytes().splitlines(keepends=True)).flatmap(
                     lambda line: st.just(SMOKE_PATH.read_bytes().replace(line, b"", 1)))))
def test_any_bytes_as_a_config_file_load_or_fail_with_a_config_error(tmp_path, data):
    path = tmp_path / "config.yaml"
    path.write_bytes(data)
    _valid_or_config_error(lambda: load_config(path))
