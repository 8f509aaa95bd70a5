"""Robot knowledge is data (models/<folder>/<name>.toml), not code: the mathematics, selfcal/sim/ and selfcal/hw/ hold no
five-element numeric literals, no comparisons of a joint count with 5, no ``range`` over five
joints and no robot names outside docstrings and comments (the encoder tables, for one, are the
robot file's ``[encoder]``).

The exceptions are named with their reasons: selfcal/kinematics/ik.py is the closed-form solver of the
5-revolute ER-type wrist and checks that structure before it solves; hw/ drives the SCORBOT's ACL
controller, so it names the model of that arm once and prints ACL's 5-axis Cartesian line.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
ROBOT_NAME = re.compile(r"er4u|scorbot(?![-_]selfcal)", re.IGNORECASE)  # the project keeps its name
# the parts above sim and hw (pyproject's layers): they may name robots
TOP_LAYER = {
    "benchmarks",
    "cli",
    "studies",
    "pipeline",
    "plots",
    "acquisition",
    "config",
    "console",
}
# the parts above sim and hw (pyproject's layers): they may name robots
TOP_LAYER = {
    "benchmarks",
    "cli",
    "studies",
    "pipeline",
    "plots",
    "acquisition",
    "config",
    "console",
}
ALLOWED = {
    (
        "selfcal/kinematics/ik.py",
        "compare with 5",
    ): "closed-form ER-type IK checks its own 5-joint structure",
    (
        "selfcal/hw/settings.py",
        "robot name in 'er4u-vendor'",
    ): "the ACL controller's arm: the default model",
    (
        "selfcal/hw/emulator/controller.py",
        "compare with 5",
    ): "ACL's LISTPV Cartesian line is X Y Z P R",
}


def _docstrings(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if (
            isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
            and body
            and isinstance(body[0], ast.Expr)
            and isinstance(body[0].value, ast.Constant)
            and isinstance(body[0].value.value, str)
        ):
            out.add(id(body[0].value))
        # attribute docstrings: a string expression right after an assignment
        if isinstance(body, list):
            for a, b in zip(body, body[1:]):
                if isinstance(a, (ast.Assign, ast.AnnAssign)) and isinstance(b, ast.Expr):
                    if isinstance(b.value, ast.Constant) and isinstance(b.value.value, str):
                        out.add(id(b.value))
    return out


def _is_number(e: ast.expr) -> bool:
    if isinstance(e, ast.UnaryOp):
        e = e.operand
    return isinstance(e, ast.Constant) and type(e.value) in (int, float)


def robot_specifics(source: str) -> list[tuple[int, str]]:
    """(line, kind) of every robot-specific construct in a module's source."""
    tree = ast.parse(source)
    docs = _docstrings(tree)
    found = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Tuple, ast.List)) and len(node.elts) == 5:
            if all(_is_number(e) for e in node.elts):
                found.append((node.lineno, "five-element literal"))
        elif isinstance(node, ast.Compare):
            if any(isinstance(c, ast.Constant) and c.value == 5 for c in node.comparators):
                found.append((node.lineno, "compare with 5"))
        elif isinstance(node, ast.Call) and ast.unparse(node.func) == "range":
            if (
                node.args
                and isinstance(node.args[-1], ast.Constant)
                and node.args[-1].value
                in (
                    5,
                    6,
                )
            ):
                if len(node.args) == 2 or node.args[-1].value == 5:
                    found.append((node.lineno, "range over five joints"))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            if id(node) not in docs and ROBOT_NAME.search(node.value):
                found.append((node.lineno, f"robot name in {node.value[:40]!r}"))
    return found


def test_the_checker_finds_what_it_looks_for():
    src = 'X = (1.0, 2, 3, 4, -5)\nif n == 5:\n    pass\nfor k in range(1, 6):\n    m = "er4u-paper"\n'
    kinds = [k for _, k in robot_specifics(src)]
    assert kinds[:3] == ["five-element literal", "compare with 5", "range over five joints"]
    assert kinds[3].startswith("robot name")
    ok = '"""SCORBOT ER-4u, in a docstring."""\nFORMAT = "scorbot-selfcal-dataset"\nP = (1, 2, 3)\n'
    assert robot_specifics(ok) == []


@pytest.mark.parametrize(
    "path",
    sorted(
        str(p.relative_to(ROOT))
        for p in (ROOT / "selfcal").rglob("*.py")
        if p.relative_to(ROOT / "selfcal").parts[0] not in TOP_LAYER
    ),
)
def test_no_robot_specifics_in_code(path):
    found = [
        f"{path}:{line}: {kind}"
        for line, kind in robot_specifics((ROOT / path).read_text())
        if (path, kind) not in ALLOWED
    ]
    assert not found, "robot knowledge belongs in models/<folder>/<name>.toml:\n" + "\n".join(found)
