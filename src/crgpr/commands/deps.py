"""The library code a Snakemake rule depends on: the import closure of its script.

A rule lists ``code=code_closure("workflow/scripts/X.py")`` among its inputs, so editing any
``crgpr`` module that the script imports, directly or through other modules, reruns the rule
and its dependants; nothing is listed by hand. Imports are found statically (``ast``),
including imports inside functions, so optional code paths count too.
"""

from __future__ import annotations

import ast
from functools import cache
from pathlib import Path

PACKAGE = "crgpr"


def _module_file(src: Path, module: str) -> Path | None:
    """File of a ``crgpr`` module (package ``__init__`` or plain module), or None."""
    rel = Path(*module.split("."))
    for cand in (src / rel.with_suffix(".py"), src / rel / "__init__.py"):
        if cand.is_file():
            return cand
    return None


def _imports(path: Path, module: str, src: Path) -> set[str]:
    """``crgpr`` modules imported by one file (absolute and relative imports)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_pkg = path.name == "__init__.py"
    here = module.split(".") if is_pkg else module.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = here[: len(here) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            found.add(mod)
            found.update(f"{mod}.{a.name}" for a in node.names)  # "from pkg import module"
    out = set()
    for m in found:
        if m == PACKAGE or m.startswith(PACKAGE + "."):
            parts = m.split(".")
            for k in range(1, len(parts) + 1):  # parent packages' __init__ run on import
                if _module_file(src, ".".join(parts[:k])) is not None:
                    out.add(".".join(parts[:k]))
    return out


@cache
def _module_imports(module: str, src: str) -> frozenset[str]:
    """``_imports`` of a ``crgpr`` module, parsed once per process (the rule files ask for
    the closures of some fifty scripts that share most of their modules)."""
    srcp = Path(src)
    f = _module_file(srcp, module)
    return frozenset(_imports(f, module, srcp)) if f is not None else frozenset()


@cache
def _closure(script: str, src: str) -> tuple[str, ...]:
    srcp = Path(src)
    todo = list(_imports(Path(script), "__script__", srcp))
    seen: set[str] = set()
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        todo.extend(_module_imports(m, src) - seen)
    files = {str(_module_file(srcp, m)) for m in seen}
    return tuple(sorted(files))


def code_closure(script: str | Path, src: str | Path) -> list[str]:
    """Source files of every ``crgpr`` module ``script`` imports, transitively (sorted paths).

    ``src`` is the directory that contains the ``crgpr`` package (``src/``).
    """
    return list(_closure(str(Path(script).resolve()), str(Path(src).resolve())))
