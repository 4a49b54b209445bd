"""The configuration reference page (``docs/configuration.md``) generated from the schemas.

``config_markdown(schema, sections, config)`` is a pure function: the main schema
(``schemas/config.schema.yaml``), its sections (``schemas/sections/<name>.schema.yaml``, by the
``$ref`` that names them) and a configuration (``config.yaml``) in, markdown out. Each key is
one row: dotted key, type, unit (the ``[...]`` of its description), meaning (the rest of the
description) and its value in the configuration. A mapping whose keys are names
(``additionalProperties`` with a schema) is shown as ``<name>`` and its entries' keys below it.
"""

from __future__ import annotations

import json
import re
from typing import Any

MISSING = object()

# a unit in square brackets, e.g. "[m]", "[N s/m^2]", "[-]"; the last one of a description
_UNIT = re.compile(r"\s*\[([^\[\]]+)\]")


def split_unit(description: str) -> tuple[str, str]:
    """``("rod length", "m")`` from ``"rod length [m]"``: the last bracketed unit and the rest."""
    found = list(_UNIT.finditer(description))
    if not found:
        return description.strip(), ""
    m = found[-1]
    return (description[:m.start()] + description[m.end():]).strip(), m.group(1).strip()


def _resolve(node: dict[str, Any], doc: dict[str, Any], sections: dict[str, dict[str, Any]]
             ) -> tuple[dict[str, Any], dict[str, Any]]:
    """Follow ``$ref`` (a section file or ``#/$defs/<name>`` of the current document)."""
    while "$ref" in node:
        ref = node["$ref"]
        if ref.startswith("#/$defs/"):
            node = doc["$defs"][ref.removeprefix("#/$defs/")]
        else:
            doc = sections[ref]
            node = doc
    return node, doc


def type_name(node: dict[str, Any]) -> str:
    """A short type: ``number``, ``integer``, ``one of a, b``, ``list of integer``, ``a | b``."""
    if "const" in node:
        return f"`{node['const']}`"
    if "enum" in node:
        return "one of " + ", ".join(f"`{v}`" for v in node["enum"])
    if "oneOf" in node or "anyOf" in node:
        alts = node.get("oneOf", node.get("anyOf"))
        kinds = [alt.get("properties", {}).get("kind", {}).get("const") for alt in alts]
        if all(kinds):  # tagged mappings: name the tag's values
            return "mapping, `kind` one of " + ", ".join(f"`{k}`" for k in kinds)
        return " or ".join(type_name(alt) for alt in alts)
    t = node.get("type", "any")
    if t == "array":
        return f"list of {type_name(node.get('items', {}))}"
    if t == "object" and isinstance(node.get("additionalProperties"), dict) \
            and "properties" not in node:
        return f"mapping name → {type_name(node['additionalProperties'])}"
    if t == "object":
        return "mapping"
    return str(t)


def _value(value: Any) -> str:
    if value is MISSING:
        return ""
    text = json.dumps(value, ensure_ascii=False)
    if len(text) > 60:
        text = text[:57] + "..."
    return f"`{text}`"


def _cell(text: str) -> str:
    return " ".join(text.replace("|", "\\|").split())


def _rows(key: str, node: dict[str, Any], doc: dict[str, Any], sections: dict[str, dict[str, Any]],
          value: Any) -> list[tuple[str, str, str, str, str]]:
    node, doc = _resolve(node, doc, sections)
    meaning, unit = split_unit(node.get("description", ""))
    rows: list[tuple[str, str, str, str, str]] = []
    props = node.get("properties")
    entries = node.get("additionalProperties")
    if props is not None:
        rows.append((key, "mapping", unit, meaning, ""))
        for name, sub in props.items():
            sub_value = value.get(name, MISSING) if isinstance(value, dict) else MISSING
            rows += _rows(f"{key}.{name}", sub, doc, sections, sub_value)
    elif isinstance(entries, dict) and node.get("type") == "object":
        names = ", ".join(f"`{k}`" for k in value) if isinstance(value, dict) else ""
        rows.append((key, type_name(node), unit, meaning,
                     f"entries: {names}" if names else ""))
        entry, entry_doc = _resolve(entries, doc, sections)
        if "properties" in entry:
            rows += _rows(f"{key}.<name>", entry, entry_doc, sections, MISSING)[1:]
    else:
        rows.append((key, type_name(node), unit, meaning, _value(value)))
    return rows


def config_markdown(schema: dict[str, Any], sections: dict[str, dict[str, Any]],
                    config: dict[str, Any], config_name: str = "config.yaml") -> str:
    """The reference page of every configuration key, one section per top-level key.

    ``sections`` maps each ``$ref`` of ``schema`` (``sections/<name>.schema.yaml``) to that
    section's schema; ``config`` supplies the values shown (those of ``config_name``)."""
    out = [
        "# Configuration reference",
        "",
        f"Every key of `{config_name}`, generated from the JSON schemas under "
        "`src/crgpr/schemas/` by `crgpr config-doc --out docs/configuration.md` "
        "(do not edit by hand; `tests/test_docs.py` checks that this page equals the "
        f"generator's output). The value column is the one in `{config_name}`. "
        f"{_cell(schema.get('description', ''))}",
        "",
    ]
    for name, sub in schema["properties"].items():
        node, doc = _resolve(sub, schema, sections)
        rows = _rows(name, node, doc, sections, config.get(name, MISSING))
        out += [f"## `{name}`", ""]
        if node.get("description"):
            out += [_cell(node["description"]), ""]
        if len(rows) > 1:
            rows = rows[1:]  # the section's own row is its heading
        out += ["| key | type | unit | meaning | value |", "| --- | --- | --- | --- | --- |"]
        out += [f"| `{k}` | {_cell(t)} | {_cell(u)} | {_cell(m)} | {_cell(v)} |"
                for k, t, u, m, v in rows]
        out.append("")
    return "\n".join(out)


def undocumented_keys(schema: dict[str, Any], sections: dict[str, dict[str, Any]]) -> list[str]:
    """Dotted keys whose schema has no ``description`` (the page would show no meaning)."""
    missing: list[str] = []
    for name, sub in schema["properties"].items():
        node, doc = _resolve(sub, schema, sections)
        for key, _t, _u, meaning, _v in _rows(name, node, doc, sections, MISSING):
            if not meaning:
                missing.append(key)
    return missing
