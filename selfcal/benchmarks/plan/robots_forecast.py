"""``python -m selfcal.benchmarks.plan.robots_forecast --block NAME [--write-docs]``: draw
again the two forecast columns of one docs/plan.md table of
:mod:`selfcal.benchmarks.plan.robots` (``forecast median / 90th, selection drawn (mm)`` and
``forecast: a smaller set kept``, and the closing lines' forecast) with the code checked out,
keeping every other column as its simulated draws measured them (issue #30: the forecast's
draws changed their square root, the draws were not kept).

The forecast is a function of the posture set and the cell alone
(:func:`selfcal.benchmarks.plan.robots.forecast_spread`, seed 1): no simulated draw enters it. The
block's own ``Command:`` line gives the cell (robots, corner noise, view rule); each posture
set is made again (:func:`selfcal.benchmarks.plan.compare.sets_of`, deterministic) and must
give the table's ``predicted (mm)`` figure to its printed digits, else the block is refused
(the plan the table was measured with is not the plan of now: its forecast cannot be drawn
without its postures). The block gets a closing note naming this command and the code that
drew the columns (:func:`selfcal.benchmarks.doc_blocks.code_version`; a block is not written
naming code that cannot be checked out).
"""

from __future__ import annotations

import argparse
import re
import shlex
from collections.abc import Callable
from pathlib import Path

from selfcal.benchmarks.doc_blocks import ROOT, code_version, print_table, read_block
from selfcal.benchmarks.plan.robots import Forecast
from selfcal.benchmarks.usage import benchmark_parser

__all__ = ["FORECAST_COLUMNS", "NOTE", "command_of", "main", "rewrite", "table_rows"]

DOC = ROOT / "docs/plan.md"
PREDICTED = "predicted (mm)"
FORECAST_COLUMNS = ("forecast median / 90th, selection drawn (mm)", "forecast: a smaller set kept")
"""The columns this script draws again (a table without them is refused)."""
NOTE = "The forecast columns were drawn again"
"""How the block's closing note begins (a second run replaces it)."""
_CLAUSE = re.compile(
    r"forecast with the selection drawn, plan 12 against random 30: median [0-9.na]+ / "
    r"[0-9.na]+ mm, 90th percentile [0-9.na]+ / [0-9.na]+ mm"
)


def _cells(line: str) -> list[str]:
    """A markdown table line's cells, stripped."""
    return [c.strip() for c in line.strip().strip("|").split("|")]


def table_rows(
    block: str, name: str = "the block"
) -> tuple[list[str], dict[tuple[str, str], list[str]]]:
    """(header cells, ``{(robot, set): cells}``) of the table in ``block``; a table without
    :data:`FORECAST_COLUMNS` is an error naming ``name``."""
    lines = [x for x in block.splitlines() if x.startswith("| ")]
    if not lines:
        raise SystemExit(f"{name}: no table rows; nothing to draw again")
    head = _cells(lines[0])
    missing = [c for c in (PREDICTED, *FORECAST_COLUMNS) if c not in head]
    if missing:
        raise SystemExit(
            f"{name}: the table has no column {missing}: measured before the forecast; "
            "nothing to draw again (run the benchmark for a new table)"
        )
    rows = {}
    for line in lines[1:]:
        cells = _cells(line)
        rows[cells[0], cells[2]] = cells
    return head, rows


def command_of(block: str, name: str = "the block") -> argparse.Namespace:
    """The arguments of the ``Command:`` line that measured ``block`` (robots.py's parser)."""
    from selfcal.benchmarks.plan.robots import parser

    got = re.search(r"Command: `python -m selfcal\.benchmarks\.plan\.robots ([^`]*)`", block)
    if got is None:
        raise SystemExit(f"{name}: no `Command: python -m selfcal.benchmarks.plan.robots ...` line")
    return parser().parse_args(shlex.split(got.group(1)))


def rewrite(
    block: str, forecasts: dict[tuple[str, str], Forecast], note: str, name: str = "the block"
) -> str:
    """``block`` with the forecast columns of every row and the closing lines' forecast clause
    from ``forecasts`` (``{(robot, set): Forecast}``, mm), ``note`` as its last paragraph
    (an earlier :data:`NOTE` replaced); every other character kept. A row without a forecast,
    or whose :attr:`Forecast.mean` does not print as the row's ``predicted (mm)``, is an error
    naming ``name`` and the row (the postures are not the table's)."""
    head, rows = table_rows(block, name)
    i_pred, i_fc, i_small = (head.index(c) for c in (PREDICTED, *FORECAST_COLUMNS))
    out = []
    for line in block.splitlines():
        cells = _cells(line) if line.startswith("| ") else []
        key = (cells[0], cells[2]) if len(cells) == len(head) and cells != head else None
        if key is not None and key in rows:
            fc = forecasts.get(key)
            if fc is None:
                raise SystemExit(f"{name}: no forecast for the row {key}; not written")
            if f"{fc.mean:.3f}" != cells[i_pred]:
                raise SystemExit(
                    f"{name}: row {key}: the posture set made now predicts {fc.mean:.3f} mm, "
                    f"the table {cells[i_pred]} mm: not the postures the table was measured "
                    "with, so its forecast cannot be drawn again; not written (measure the "
                    "table again with `python -m selfcal.benchmarks.plan.robots`)"
                )
            cells[i_fc] = f"{fc.median:.3f} / {fc.p90:.3f}"
            cells[i_small] = f"{100 * fc.smaller:.0f} %"
            line = "| " + " | ".join(cells) + " |"
        else:
            robot = line.split(":", 1)[0]
            p, r = forecasts.get((robot, "plan 12")), forecasts.get((robot, "random 30"))
            if p is not None and r is not None:
                line = _CLAUSE.sub(
                    "forecast with the selection drawn, plan 12 against random 30: median "
                    f"{p.median:.3f} / {r.median:.3f} mm, 90th percentile {p.p90:.3f} / "
                    f"{r.p90:.3f} mm",
                    line,
                )
        out.append(line)
    text = "\n".join(out).rstrip()
    cut = text.find("\n\n" + NOTE)
    text = text if cut < 0 else text[:cut]
    return f"{text}\n\n{note}"


def forecasts_now(block: str, name: str) -> dict[tuple[str, str], Forecast]:
    """``{(robot, set): Forecast}`` (mm) of the table's rows, the posture sets made again by
    the code of now for the cell, noise and view rule of the block's command (:func:`rewrite`
    checks their predictions against the table's)."""
    from selfcal.benchmarks.plan.compare import sets_of
    from selfcal.benchmarks.plan.robots import cell, forecast_spread
    from selfcal.calibration.board.plan.views import ViewRule

    _, rows = table_rows(block, name)
    a = command_of(block, name)
    rule = ViewRule(min_pitch_px=a.min_pitch_px, max_tilt_deg=a.max_tilt_deg,
                    min_module_px=a.min_module_px)  # fmt: skip
    out: dict[tuple[str, str], Forecast] = {}
    for robot in dict.fromkeys(r for r, _ in rows):
        setup, _, _ = cell(robot, rule)
        got = sets_of(setup, 12, (12, 30), pixel_sigma_px=a.pixel_sigma)
        for r, s in rows:
            if r != robot:
                continue
            q, pred = got["sets"][s]
            out[r, s] = Forecast(
                1000.0 * pred, *forecast_spread(setup, q, got["workspace"], a.pixel_sigma)
            )
            print(f"{r} {s}: {out[r, s]}", flush=True)
    return out


def main(argv: list[str] | None = None) -> int:
    """Draw the block's forecast columns again, print it and, with ``--write-docs``, put it
    in docs/plan.md."""
    ap = benchmark_parser(__file__, description=__doc__.split("\n\n")[0])
    ap.add_argument("--block", required=True,
                    help="the docs block's name after benchmark_plan_robots_")  # fmt: skip
    ap.add_argument("--doc", type=Path, default=DOC, help=argparse.SUPPRESS)
    ap.add_argument("--write-docs", action="store_true")
    a = ap.parse_args(argv)
    name = f"benchmark_plan_robots_{a.block}"
    where = f"{a.doc.name}'s {name} block"
    block = read_block(a.doc, name)
    code = code_version()
    by = f" with the code at {code}" if code else " (the code not recorded: not a git checkout)"
    note = (
        f"{NOTE} (the closing lines' forecast too) by `python -m "
        f"selfcal.benchmarks.plan.robots_forecast --block {a.block}`{by}: each posture set made "
        "again by that code for the command's cell, noise and view rule, its prediction "
        "the table's `predicted (mm)` to its 3 decimals, the forecast's draws through the "
        "symmetric root (issue #30); every other column is the simulated draws' as the command "
        "measured them."
    )
    text = rewrite(block, _forecasts(block, where), note, where)
    return print_table(text, a.doc, name, write=a.write_docs)


_forecasts: Callable[[str, str], dict[tuple[str, str], Forecast]] = forecasts_now
"""What :func:`main` draws the forecasts with (a test replaces it)."""


if __name__ == "__main__":
    raise SystemExit(main())
