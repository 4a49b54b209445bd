"""Command ``crgpr config-doc``: the configuration reference page from the schemas."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import yaml

from crgpr.config import load_config, schema, schema_path
from crgpr.io import write_text
from crgpr.report.config_doc import config_markdown


def schema_sections(main: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """Each section schema the main schema references, at any depth (``sections/<name>.schema.yaml``;
    a section's own ``$ref`` is relative to its folder, as the validator resolves it), keyed by
    the ``$ref`` as written."""
    base = schema_path().parent
    sections: dict[str, dict[str, Any]] = {}

    def walk(node: Any, folder: Path) -> None:
        if isinstance(node, dict):
            ref = node.get("$ref")
            if isinstance(ref, str) and not ref.startswith("#") and ref not in sections:
                path = folder / ref
                sections[ref] = yaml.safe_load(path.read_text(encoding="utf-8"))
                walk(sections[ref], path.parent)
            for value in node.values():
                walk(value, folder)
        elif isinstance(node, list):
            for value in node:
                walk(value, folder)

    walk(main, base)
    return sections


def config_page(config_path: str) -> str:
    """The page for the configuration file ``config_path`` (validated first)."""
    main = schema()
    return config_markdown(main, schema_sections(main), load_config(config_path),
                           Path(config_path).name)


def add_cli(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("config-doc", help="write the configuration reference (docs/configuration.md)",
                       description="Every config key with its type, unit, meaning and value, "
                                   "generated from the JSON schemas.")
    p.add_argument("--config", default="config.yaml", help="configuration whose values are shown")
    p.add_argument("--out", required=True, help="markdown file to write")
    p.set_defaults(func=_config_doc_cli)


def _config_doc_cli(args: argparse.Namespace) -> None:
    write_text(config_page(args.config), args.out)
