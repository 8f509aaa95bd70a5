"""Every ``from selfcal... import name`` in the package names something its module has, the
imports inside functions too (a benchmark's or a command's lazy import runs only when it is
used, and mypy checks the mathematics layer only): a renamed function left a benchmark that
imported the old name at its import (two test files could not be collected) and two that
failed when run."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import selfcal

PACKAGE = Path(selfcal.__file__).parent


def _imports() -> list[tuple[str, int, str, str]]:
    """(file, line, module, name) of every ``from selfcal.X import name`` in the package."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                if node.module == "selfcal" or node.module.startswith("selfcal."):
                    rel = str(path.relative_to(PACKAGE.parent))
                    found += [(rel, node.lineno, node.module, a.name) for a in node.names]
    return found


def test_every_imported_name_exists():
    imports = _imports()
    assert len(imports) > 1000  # the scan reads the package
    missing = []
    for file, line, module, name in imports:
        mod = importlib.import_module(module)
        if name != "*" and not hasattr(mod, name):
            try:  # a submodule imported by name
                importlib.import_module(f"{module}.{name}")
            except ModuleNotFoundError:
                missing.append(f"{file}:{line}: {module} has no {name}")
    assert not missing, "\n".join(missing)


def test_the_scan_finds_a_wrong_name(tmp_path, monkeypatch):
    """The test can fail: a module importing a name its source module lacks is reported."""
    fake = tmp_path / "selfcal"
    fake.mkdir()
    (fake / "__init__.py").write_text("")
    (fake / "a.py").write_text("def f():\n    from selfcal.errors import NoSuchName\n")
    monkeypatch.setattr(f"{__name__}.PACKAGE", fake)
    imports = _imports()
    assert imports == [("selfcal/a.py", 2, "selfcal.errors", "NoSuchName")]
    assert not hasattr(importlib.import_module("selfcal.errors"), "NoSuchName")
