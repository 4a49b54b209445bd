"""Command-line interface: ``crgpr <command>``. Each stage module registers its commands."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from crgpr.commands.smk import limit_threads

# Modules that provide ``add_cli(subparsers)`` (``crgpr.commands.<stage>``); a stage adds itself here.
COMMAND_MODULES: list[str] = [
    "crgpr.commands.simulate",
    "crgpr.commands.prefilter",
    "crgpr.commands.models",
    "crgpr.commands.rollout",
    "crgpr.commands.report",
    "crgpr.commands.discovery",
    "crgpr.commands.learn",
    "crgpr.commands.config_doc",
    "crgpr.commands.control",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="crgpr", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_cli(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(asctime)s %(name)s %(levelname)s: %(message)s")
    limit_threads()  # the same numbers as the pipeline's rules, whatever the core count
    try:
        args.func(args)
    except (ValueError, OSError, RuntimeError) as exc:  # ConfigError is a ValueError
        msg = " ".join(str(exc).split()) or type(exc).__name__
        print(f"crgpr {args.command}: error: {msg}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
