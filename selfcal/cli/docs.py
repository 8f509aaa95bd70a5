"""docs/cli.md, generated from the ``selfcal`` parser: the grammar, the exit codes and the
``--help`` of every command.

``python -m selfcal.cli.docs --write`` rewrites docs/cli.md; ``--check`` exits 1 when it is
stale (tests/unit/test_cli_docs.py runs the same comparison).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from selfcal.cli.check import EXIT_CANNOT_TELL, EXIT_CHANGED
from selfcal.cli.main import build_parser
from selfcal.console.common import leaf_parsers
from selfcal.console.usage import module_parser
from selfcal.errors import EXIT_BROKEN_PIPE
from selfcal.io.atomic import write_text_atomic

__all__ = ["cli_markdown", "DOC", "main"]

DOC = Path(__file__).resolve().parents[2] / "docs" / "cli.md"
WIDTH = 100
"""Columns of the help text (fixed, so the file does not depend on the terminal)."""

HEADER = f"""\
# The `selfcal` command line

Generated from the parser by `python -m selfcal.cli.docs --write` (do not edit by hand;
`tests/unit/test_cli_docs.py` fails when this file is stale).

## Grammar

- Inputs are positional: `selfcal calibrate DATASET`, `selfcal run [SCENARIO]`,
  `selfcal render [SCENARIO] --joints ...`, `selfcal export CALIBRATION`.
- `--out` is always optional; its default is stated in each command's help (`runs/<name>` for the
  jobs that make a folder, the dataset folder itself for `calibrate` and `report`).
- One name per concept: `--robot` (a model name, robot TOML or URDF; default `er4u-paper`, the
  `[robot] model` of the default scenario `scenarios/paper.toml`), `--calibration`, `--rrd`,
  `--joint-units`, `--seed`. Old spellings (`--model`, `--rerun`, `render --config`,
  `montecarlo --config`) still work, hidden, and print a deprecation warning.
- `--json` prints the result as one JSON object on stdout (notes and progress go to stderr);
  `fk`, `ik`, `render`, `export` and `hw` always print JSON.
- `-v/--verbose` adds tracebacks and debug messages, `-q/--quiet` drops progress bars and notes;
  both are accepted before or after the command.
- Progress bars (done/total, time left; drawn by `rich`) are drawn on stderr only when it is a
  terminal and without `-q`; elsewhere a stage that took over a second prints one line.
- Millimetres and degrees on the command line and in files, SI units inside.

## Messages and exit codes

A failure is one line on stderr, `selfcal: error: <what> (<file/key/row>) -- <fix>`, with no
traceback unless `-v`. A warning is a `selfcal: warning: <text>` line (Python warnings too, each
once). A command that writes files ends with one line naming them and counting the warnings:
`selfcal: wrote runs/paper/ (calibration.json, ...) in 12.3 s; 0 warnings`.

| code | meaning |
|---|---|
| 0 | ok |
| 1 | internal error: a bug (`-v` prints the traceback, `SELFCAL_DEBUG=1` re-raises it) |
| 2 | bad input: scenario, dataset, robot file, calibration file, argument or command line |
| 3 | cannot calibrate from this data: too few postures, degenerate geometry, no convergence |
| 4 | robot or hardware fault: controller error, serial link, camera |
| {EXIT_CHANGED} | `selfcal check`: the robot has changed since its calibration (the check worked) |
| {EXIT_CANNOT_TELL} | `selfcal check` of a board calibration: cannot tell (the new images miss the prediction, but by no more than the calibration's own folds missed the arm configurations they left out: check at its own postures; or they fit it only with the own noise of images noisier than the calibration's frames, which would hide a change the check does not model) |
| 130 | interrupted (Ctrl-C) |
| {EXIT_BROKEN_PIPE} | the reader of the output went away (`selfcal scenarios \\| head -1`): stopped quietly |

## Commands
"""


def _help(p: argparse.ArgumentParser) -> str:
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(WIDTH)
    try:
        return p.format_help().rstrip() + "\n"
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old


def cli_markdown() -> str:
    """The text of docs/cli.md for the current parser."""
    top = build_parser()
    parts = [HEADER, "\n### `selfcal`\n\n```text\n", _help(top), "```\n"]
    for leaf in leaf_parsers(top):
        parts += [f"\n### `{leaf.prog}`\n\n```text\n", _help(leaf), "```\n"]
    return "".join(parts)


def main(argv: list[str] | None = None) -> int:
    """``--write``: rewrite docs/cli.md; ``--check``: exit 1 when it differs from the parser."""
    ap = module_parser(__file__, description=__doc__)
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--write", action="store_true", help="rewrite docs/cli.md")
    g.add_argument("--check", action="store_true", help="exit 1 when docs/cli.md is stale")
    args = ap.parse_args(argv)
    text = cli_markdown()
    if args.write:
        write_text_atomic(DOC, text)
        print(f"wrote {DOC}")
        return 0
    if not DOC.is_file() or DOC.read_text() != text:
        print(f"{DOC} is stale: run `python -m selfcal.cli.docs --write`", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
