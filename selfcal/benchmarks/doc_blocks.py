"""Blocks of generated text in README.md and docs/*.md, between ``<!-- NAME: begin -->`` and
``<!-- NAME: end -->`` markers: the benchmark scripts rewrite them, nothing else does."""

from __future__ import annotations

import re
import subprocess
from collections.abc import Sequence
from pathlib import Path

from selfcal.io.atomic import write_text_atomic

__all__ = [
    "ROOT",
    "UNRECOVERABLE",
    "code_version",
    "codes_note",
    "codes_of",
    "print_table",
    "read_block",
    "stamp_problems",
    "write_block",
]

ROOT = Path(__file__).resolve().parents[2]
"""The repository's root (README.md and docs/ are in it)."""


CODE_PATHS = ("selfcal", "models", "scenarios", "tests/data", "pyproject.toml", "uv.lock")
"""What runs a benchmark: the package, the data it reads from the checkout (the robot models
and targets of ``models/``, :func:`selfcal.robot.definition.models_dir`; the shipped scenarios
of ``scenarios/``, :data:`selfcal.config.shipped.SHIPPED_DIR`; the test data some benchmarks
draw or calibrate, ``tests/data``: arm7, the real sets) and its dependencies; a change
elsewhere (the docs being written, a test) leaves the code the commit's."""


def code_version(root: Path = ROOT) -> str | None:
    """The code that measures a benchmark's rows: the commit checked out at ``root`` (short
    hash), with ``+changes`` when its files of :data:`CODE_PATHS` differ from it (a new file
    there too); None outside a git checkout (or without git)."""
    git = ["git", "-C", str(root)]
    try:
        head = subprocess.run([*git, "rev-parse", "--short=7", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()  # fmt: skip
        changed = subprocess.run([*git, "status", "--porcelain", "--", *CODE_PATHS],
                                 capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+changes" if changed else "")


STAMP = re.compile(r"the code at ([0-9a-f]{7,40})(\+changes)?", re.IGNORECASE)
"""A code stamp in a block's text (:func:`codes_note`, "Measured by the code at X")."""


def stamp_problems(text: str, root: Path = ROOT) -> list[str]:
    """The code stamps in ``text`` that name code no one can check out: with uncommitted
    changes (``X+changes``) or not a commit of the history of ``root``'s HEAD (unknown, or a
    branch's commit that a rebase replaced), each with why; [] outside a git checkout."""
    if code_version(root) is None:
        return []
    out = []
    for sha, dirty in dict.fromkeys(STAMP.findall(text)):
        if dirty:
            out.append(f"{sha}+changes (uncommitted changes)")
            continue
        known = subprocess.run(["git", "-C", str(root), "merge-base", "--is-ancestor", sha,
                                "HEAD"], capture_output=True).returncode == 0  # fmt: skip
        if not known:
            out.append(f"{sha} (not a commit of HEAD's history)")
    return out


UNRECOVERABLE = "not recoverable"
"""A row's ``code`` when the commit its stamp named cannot be checked out and no commit of the
history can be shown to hold the code it measured (:func:`stamp_problems`; the docs say which
and why): :func:`codes_note` names it "code that is not recoverable"."""


def _code_name(code: str | None) -> str:
    """How :func:`codes_note` names a row's code."""
    if not code:
        return "an earlier code, not recorded"
    return "code that is not recoverable" if code == UNRECOVERABLE else f"the code at {code}"


def _label(prefix: str, value: object) -> str:
    """A row's label in :func:`codes_note`: the values of its keys, a number as ``N px``."""
    cell = f"{value:g} px" if isinstance(value, (int, float)) else str(value)
    return f"{prefix} {cell}" if prefix else cell


def codes_note(rows: list[dict], keys: Sequence[str]) -> str:
    """The end of a benchmark table's last line: the code that measured ``rows`` (each row's
    ``code``, :func:`code_version`; None: an earlier code, not recorded; :data:`UNRECOVERABLE`),
    per code the rows it measured when they are not all one code's, named by the values of
    ``keys`` (e.g. robot, model, noise: a robot when all its rows are one code's, else its
    models, else its noise levels); "" when no row records one (older rows)."""
    code = [r.get("code") for r in rows]
    if not any(code):
        return ""
    name = {c: _code_name(c) for c in code}
    if len(set(code)) == 1:
        return f", measured by {name[code[0]]}"
    parts: dict[str | None, list[str]] = {}

    def group(mine: list[tuple[dict, str | None]], depth: int, prefix: str) -> None:
        key = keys[depth]
        for value in dict.fromkeys(r[key] for r, _ in mine):
            its = [(r, c) for r, c in mine if r[key] == value]
            label = _label(prefix, value)
            if len({c for _, c in its}) == 1 or depth + 1 == len(keys):
                parts.setdefault(its[0][1], []).append(label)
            else:
                group(its, depth + 1, label)

    group(list(zip(rows, code, strict=True)), 0, "")
    said = [f"{name[c]} ({', '.join(labels)})" for c, labels in parts.items()]
    return ", measured by " + ", ".join(said[:-1]) + " and " + said[-1]


def codes_of(text: str, rows: list[dict], keys: Sequence[str]) -> list[str | None]:
    """The code of each of ``rows`` (parsed back from a table) that the note :func:`codes_note`
    wrote into ``text`` names (None: not recorded, or no note)."""
    sha = r"([0-9a-f]+(?:\+changes)?)"
    lost = "(code that is not recoverable)"
    one = re.search(rf", measured by (?:the code at {sha}|{lost})\.?$", text.rstrip())
    if one:
        return [one.group(1) or UNRECOVERABLE] * len(rows)
    groups = [(m.group(1) or (UNRECOVERABLE if m.group(2) else None), f", {m.group(3)}, ")
              for m in re.finditer(rf"(?:the code at {sha}|{lost}|an earlier code, not recorded) "
                                   r"\(([^)]*)\)", text)]  # fmt: skip
    out: list[str | None] = []
    for r in rows:
        labels, prefix = [], ""
        for key in keys:
            prefix = _label(prefix, r[key])
            labels.append(f", {prefix}, ")
        out.append(next((c for c, said in groups if any(x in said for x in labels)), None))
    return out


def _split(path: Path, name: str) -> tuple[str, str, str, str, str]:
    """``path``'s text around the ``name`` block: (head, begin marker, block, end marker,
    tail); no markers is an error naming the file."""
    begin, end = f"<!-- {name}: begin -->", f"<!-- {name}: end -->"
    text = path.read_text()
    if begin not in text or end not in text:
        raise SystemExit(f"{path}: no {begin} ... {end} markers to write between")
    head, rest = text.split(begin, 1)
    block, tail = rest.split(end, 1)
    return head, begin, block, end, tail


def read_block(path: Path, name: str) -> str:
    """What stands between ``<!-- NAME: begin -->`` and ``<!-- NAME: end -->`` in ``path``
    (stripped); no markers is an error naming the file."""
    return _split(path, name)[2].strip()


def write_block(path: Path, block: str, name: str = "benchmark_speed") -> None:
    """Replace what stands between ``<!-- NAME: begin -->`` and ``<!-- NAME: end -->`` in
    ``path`` by ``block``; no markers is an error naming the file, and so is a block naming
    code no one can check out (:func:`stamp_problems`)."""
    bad = stamp_problems(block)
    if bad:
        raise SystemExit(
            f"{path}: the {name} block would say its rows were measured by code that cannot be "
            f"checked out: {'; '.join(bad)}; not written. Fix: commit the code and measure again "
            "(a block's rows measured on a branch before its rebase: name the main commit whose "
            "selfcal/ tree is the one measured, `git diff X C -- selfcal` empty, or measure again)"
        )
    head, begin, _, end, tail = _split(path, name)
    write_text_atomic(path, f"{head}{begin}\n{block}\n{end}{tail}")


def print_table(text: str, path: Path, name: str, *, write: bool) -> int:
    """Print a benchmark's table ``text`` and, with ``write``, put it between the ``name``
    markers of ``path`` (:func:`write_block`); returns 0 (the script's exit code)."""
    print(text)
    if write:
        write_block(path, text, name)
    return 0
