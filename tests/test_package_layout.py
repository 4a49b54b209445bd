"""Import direction between the concept subpackages (read statically, every import counted,
including those inside functions): measured records are the common ground of learning from
camera data and of the missing-physics workflow, which do not depend on each other."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "crgpr"


def _imported(package: str, root: Path = SRC) -> dict[str, set[str]]:
    """Per file of ``crgpr.<package>``, the ``crgpr`` modules it imports (absolute names)."""
    out: dict[str, set[str]] = {}
    for path in sorted((root / package).rglob("*.py")):
        mods: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.Import):
                mods.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{path}: relative import"
                mods.add(node.module or "")
        out[path.relative_to(root).as_posix()] = {m for m in mods if m.split(".")[0] == "crgpr"}
    return out


@pytest.mark.parametrize(("package", "forbidden"), [
    ("learning", ("crgpr.discovery",)),
    ("discovery", ("crgpr.learning",)),
    ("measured", ("crgpr.discovery", "crgpr.learning", "crgpr.commands")),
])
def test_import_direction(package, forbidden):
    files = _imported(package)
    assert files, f"no files under crgpr.{package}"
    bad = {f: sorted(m for m in mods if m.startswith(forbidden)) for f, mods in files.items()}
    assert not {f: m for f, m in bad.items() if m}


def test_learning_and_discovery_read_measured_records():
    """The two users of measured records take them from crgpr.measured (the check above would
    pass vacuously if neither imported anything)."""
    for package, user in (("learning", "learning/camera.py"), ("discovery", "discovery/selection.py")):
        assert any(m.startswith("crgpr.measured") for m in _imported(package)[user])


def test_the_import_walk_sees_imports_inside_functions(tmp_path):
    """A forbidden import hidden in a function body is found."""
    pkg = tmp_path / "learning"
    pkg.mkdir()
    (pkg / "x.py").write_text("import numpy\n\n\ndef f():\n"
                              "    from crgpr.discovery.selection import discover\n")
    assert _imported("learning", tmp_path) == {"learning/x.py": {"crgpr.discovery.selection"}}
