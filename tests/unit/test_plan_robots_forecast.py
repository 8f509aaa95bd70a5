"""The plan benchmark's forecast-only mode (selfcal/benchmarks/plan/robots_forecast.py): a
table of :func:`selfcal.benchmarks.plan.robots.table` drawn again changes its two forecast
columns and the closing line's forecast clause and nothing else, refuses a table whose posture
sets predict other figures (other postures) or that has no forecast columns, and writes the
block through the block writer."""

from __future__ import annotations

from pathlib import Path

import pytest

from selfcal.benchmarks.doc_blocks import code_version
from selfcal.benchmarks.plan import robots_forecast as rf
from selfcal.benchmarks.plan.robots import Forecast, table

OLD = {
    ("kr6-r900", "plan 12"): Forecast(0.042, 0.038, 0.056, 0.0),
    ("kr6-r900", "random 30"): Forecast(0.069, 0.055, 0.097, 0.07),
}
NEW = {
    ("kr6-r900", "plan 12"): Forecast(0.042, 0.037, 0.058, 0.004),
    ("kr6-r900", "random 30"): Forecast(0.069, 0.061, 0.102, 0.12),
}
COMMAND = ("\n\nCells: kr6-r900 board. Command: `python -m selfcal.benchmarks.plan.robots "
           "--render --pixel-sigma 0.04 --robot kr6-r900 --sets 'plan 12' 'random 30' "
           "--draws 2 --jobs 1 --block kr6-test` (draws per row).")  # fmt: skip


def _block(forecasts: dict) -> str:
    """A table of two sets' two draws each, as robots.py writes it, with ``forecasts``."""
    rows = [{"robot": "kr6-r900", "set": s, "seed": k, "render": True, "tip_mm": 0.03 + 0.01 * k,
             "frames": 12, "whole": 12, "sigma_px": 0.04, "held": [], "status": "ok"}
            for s in ("plan 12", "random 30") for k in (1, 2)]  # fmt: skip
    held = {k: (lambda names, m=v.mean: m) for k, v in forecasts.items()}
    return table(rows, forecasts, held) + COMMAND


def test_only_the_forecast_columns_and_clause_change() -> None:
    old, want = _block(OLD), _block(NEW)
    got = rf.rewrite(old, NEW, rf.NOTE + " here.")
    # exactly the table robots.py would write with the new forecasts, and a note
    assert got == want + "\n\n" + rf.NOTE + " here."
    head, before = rf.table_rows(old)
    _, after = rf.table_rows(got)
    changed = [head.index(c) for c in rf.FORECAST_COLUMNS]
    for key, cells in before.items():
        kept = [(a, b) for i, (a, b) in enumerate(zip(cells, after[key], strict=True))
                if i not in changed]  # fmt: skip
        assert all(a == b for a, b in kept), key
        assert cells[changed[0]] != after[key][changed[0]], key
    assert after["kr6-r900", "random 30"][changed[0]] == "0.061 / 0.102"
    assert after["kr6-r900", "random 30"][changed[1]] == "12 %"
    assert "median 0.037 / 0.061 mm, 90th percentile 0.058 / 0.102 mm" in got
    assert "0.055" not in got
    # a second run replaces its note rather than adding one
    again = rf.rewrite(got, NEW, rf.NOTE + " again.")
    assert again.count(rf.NOTE) == 1 and again.endswith("again.")


def test_other_postures_are_refused() -> None:
    other = dict(NEW)
    other["kr6-r900", "plan 12"] = Forecast(0.043, 0.037, 0.058, 0.0)
    with pytest.raises(SystemExit, match=r"plan 12.*0\.043 mm, the table 0\.042 mm"):
        rf.rewrite(_block(OLD), other, rf.NOTE)
    with pytest.raises(SystemExit, match="no forecast for the row"):
        rf.rewrite(_block(OLD), {("kr6-r900", "plan 12"): NEW["kr6-r900", "plan 12"]}, rf.NOTE)


def test_a_table_without_the_forecast_columns_is_refused() -> None:
    block = "| robot | path | postures | predicted (mm) |\n|---|---|---|---|\n| a | b | c | 1 |"
    with pytest.raises(SystemExit, match="no column"):
        rf.rewrite(block, NEW, rf.NOTE)


def test_the_command_line_is_read_back() -> None:
    a = rf.command_of(_block(OLD))
    assert a.robot == ["kr6-r900"] and a.pixel_sigma == 0.04 and a.render
    assert a.sets == ["plan 12", "random 30"]


def test_main_writes_the_block(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The block is written with a note naming the command and the code that drew the
    columns (review of session 24: the note said "the code of now" and named no commit), and
    not written when that code has uncommitted changes."""
    doc = tmp_path / "plan.md"
    name = "benchmark_plan_robots_kr6-test"
    before = f"before\n<!-- {name}: begin -->\n{_block(OLD)}\n<!-- {name}: end -->\nafter\n"
    doc.write_text(before)
    monkeypatch.setattr(rf, "_forecasts", lambda block, where: NEW)
    head = (code_version() or "abc1234").removesuffix("+changes")
    monkeypatch.setattr(rf, "code_version", lambda: f"{head}+changes")
    if code_version() is not None:  # a git checkout: the stamp is checked
        with pytest.raises(SystemExit, match="cannot be checked out"):
            rf.main(["--block", "kr6-test", "--doc", str(doc), "--write-docs"])
        assert doc.read_text() == before
    monkeypatch.setattr(rf, "code_version", lambda: head)
    assert rf.main(["--block", "kr6-test", "--doc", str(doc), "--write-docs"]) == 0
    text = doc.read_text()
    assert text.startswith("before\n") and text.endswith("after\n")
    assert _block(NEW) in text
    assert f"robots_forecast --block kr6-test` with the code at {head}:" in text
