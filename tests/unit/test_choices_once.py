"""The command line's choices are named once, in :mod:`selfcal.choices`: an option that offers the
camera setups takes :data:`selfcal.choices.SETUPS`, never its own list (a third setup added
there would be missing from it)."""

from __future__ import annotations

import ast
from pathlib import Path

import selfcal
from selfcal.choices import SETUPS

PACKAGE = Path(selfcal.__file__).parent


def _literal_choices(path: Path) -> list[tuple[int, tuple[str, ...]]]:
    """The ``choices=`` keywords of ``path`` given as a literal list or tuple of strings. Only a
    source whose text spells "choices" can hold one: the others are not parsed (53 of the
    package's 435 files hold the word; parsing them all took 1.6 CPU s of the default tier)."""
    out: list[tuple[int, tuple[str, ...]]] = []
    text = path.read_text(encoding="utf-8")
    if "choices" not in text:
        return out
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.keyword) and node.arg == "choices":
            v = node.value
            if isinstance(v, (ast.List, ast.Tuple)) and all(
                isinstance(e, ast.Constant) and isinstance(e.value, str) for e in v.elts
            ):
                out.append((v.lineno, tuple(str(e.value) for e in v.elts)))
    return out


def test_no_option_spells_out_the_setups():
    own = [f"{p.relative_to(PACKAGE.parent)}:{line}"
           for p in sorted(PACKAGE.rglob("*.py")) if p.name != "choices.py"
           for line, values in _literal_choices(p) if set(values) == set(SETUPS)]  # fmt: skip
    assert own == [], f"use selfcal.choices.SETUPS in {own}"
