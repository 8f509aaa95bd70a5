"""Every exception selfcal/ raises is under the one root, selfcal.errors.SelfCalError (#31).

A bare ``raise ValueError(...)`` reaches the command line as "internal error ... a bug" and a
library caller cannot catch the project's errors by one class. The scan reads the source (no
import), so it also covers the modules that need MuJoCo or a serial port.
"""

from __future__ import annotations

import ast
import builtins
import functools
import re
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "selfcal"

BUILTIN_EXCEPTIONS = frozenset(
    name
    for name, v in vars(builtins).items()
    if isinstance(v, type) and issubclass(v, BaseException) and not issubclass(v, Warning)
)
"""Python's exception classes (warnings are not raised)."""

NOT_ERRORS = frozenset({"SystemExit", "KeyboardInterrupt", "GeneratorExit", "StopIteration"})
"""A script's exit and the interpreter's protocols: not errors the project reports."""


_CANDIDATE = re.compile(
    r"raise\s+(?:{0})\b|class\s+\w+\([^)]*\b(?:{0})\b".format("|".join(BUILTIN_EXCEPTIONS))
)
"""Text that may hold a bare raise or an exception class: only those files are parsed."""


@functools.cache
def _sources() -> list[tuple[str, ast.Module]]:
    texts = {p: p.read_text() for p in sorted(PACKAGE.rglob("*.py"))}
    return [(str(p.relative_to(PACKAGE.parent)), ast.parse(t, str(p)))
            for p, t in texts.items() if _CANDIDATE.search(t)]  # fmt: skip


def _placeholder(func: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    """A method whose body is (a docstring and) ``raise NotImplementedError``: Python's way of
    saying a subclass provides it."""
    body = func.body[1:] if ast.get_docstring(func) is not None else func.body
    return (
        len(body) == 1
        and isinstance(body[0], ast.Raise)
        and isinstance(body[0].exc, ast.Name)
        and body[0].exc.id == "NotImplementedError"
    )


def _protocol(func: ast.FunctionDef | ast.AsyncFunctionDef) -> set[int]:
    """The ``raise AttributeError`` of a module's or class's ``__getattr__`` (PEP 562: Python's
    way of saying a name is not there; no other exception will do)."""
    if func.name != "__getattr__":
        return set()
    return {
        id(n)
        for n in ast.walk(func)
        if isinstance(n, ast.Raise)
        and isinstance(f := n.exc.func if isinstance(n.exc, ast.Call) else n.exc, ast.Name)
        and f.id == "AttributeError"
    }


def _bare_raises(tree: ast.Module) -> list[tuple[int, str]]:
    """(line, name) of every ``raise Builtin(...)`` outside an abstract placeholder and a
    ``__getattr__``'s AttributeError."""
    funcs = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)]
    allowed = {id(f.body[-1]) for f in funcs if _placeholder(f)}
    allowed |= {i for f in funcs for i in _protocol(f)}
    out = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Raise) or node.exc is None or id(node) in allowed:
            continue
        f = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
        if isinstance(f, ast.Name) and f.id in BUILTIN_EXCEPTIONS - NOT_ERRORS:
            out.append((node.lineno, f.id))
    return sorted(out)


def test_no_bare_builtin_raise():
    bare = [f"{path}:{line}: raise {name}" for path, tree in _sources()
            for line, name in _bare_raises(tree)]  # fmt: skip
    assert not bare, (
        "raise a kind of selfcal.errors.SelfCalError instead (InputError for what a user wrote, "
        "UsageError for a caller's bad argument, EstimationError, InternalError ...):\n"
        + "\n".join(bare)
    )


def test_every_exception_class_is_under_the_root():
    """A class deriving from a builtin exception also derives from a project class (a kind of
    SelfCalError, which test_exit_codes checks), as ``class X(SelfCalError, ValueError)``."""
    loose = [
        f"{path}:{node.lineno}: class {node.name}"
        for path, tree in _sources()
        for node in ast.walk(tree)
        if isinstance(node, ast.ClassDef)
        and path != "selfcal/errors.py"
        and any(isinstance(b, ast.Name) and b.id in BUILTIN_EXCEPTIONS for b in node.bases)
        and not any(
            isinstance(b, ast.Name) and b.id not in BUILTIN_EXCEPTIONS for b in node.bases
        )  # fmt: skip
    ]
    assert not loose, "derive from a kind of selfcal.errors.SelfCalError:\n" + "\n".join(loose)


def test_the_scan_finds_a_bare_raise():
    tree = ast.parse(
        "def f(x):\n    if x:\n        raise ValueError('bad')\n    raise KeyError\n"
        "class A:\n    def g(self):\n        '''doc'''\n        raise NotImplementedError\n"
        "    def h(self):\n        print()\n        raise NotImplementedError\n"
        "if __name__ == '__main__':\n    raise SystemExit(0)\n"
        "def __getattr__(name):\n    raise AttributeError(name)\n"
    )
    assert _bare_raises(tree) == [(3, "ValueError"), (4, "KeyError"), (11, "NotImplementedError")]
