"""Blocks of generated text in README.md and docs/*.md, between ``<!-- NAME: begin -->`` and
``<!-- NAME: end -->`` markers: the benchmark scripts rewrite them, nothing else does."""

from __future__ import annotations

import subprocess
from pathlib import Path

from selfcal.io.atomic import write_text_atomic

__all__ = ["ROOT", "code_version", "print_table", "read_block", "write_block"]

ROOT = Path(__file__).resolve().parents[2]
"""The repository's root (README.md and docs/ are in it)."""


def code_version(root: Path = ROOT) -> str | None:
    """The code that measures a benchmark's rows: the commit checked out at ``root`` (short
    hash), with ``+changes`` when its tracked files differ from it; None outside a git checkout
    (or without git)."""
    git = ["git", "-C", str(root)]
    try:
        head = subprocess.run([*git, "rev-parse", "--short=7", "HEAD"], capture_output=True,
                              text=True, check=True).stdout.strip()  # fmt: skip
        changed = subprocess.run([*git, "status", "--porcelain", "--untracked-files=no"],
                                 capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return None
    return head + ("+changes" if changed else "")


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
    ``path`` by ``block``; no markers is an error naming the file."""
    head, begin, _, end, tail = _split(path, name)
    write_text_atomic(path, f"{head}{begin}\n{block}\n{end}{tail}")


def print_table(text: str, path: Path, name: str, *, write: bool) -> int:
    """Print a benchmark's table ``text`` and, with ``write``, put it between the ``name``
    markers of ``path`` (:func:`write_block`); returns 0 (the script's exit code)."""
    print(text)
    if write:
        write_block(path, text, name)
    return 0
