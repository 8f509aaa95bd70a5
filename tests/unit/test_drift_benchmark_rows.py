"""The image drift benchmark's docs block (selfcal.benchmarks.drift.images, issue #29): a run of
some setups and robots rewrites their rows and keeps the others, and refuses to mix rows
measured with other options."""

from __future__ import annotations

import pytest

from selfcal.benchmarks.doc_blocks import read_block
from selfcal.benchmarks.drift import image_table
from selfcal.benchmarks.drift import images as drift_images
from selfcal.benchmarks.drift.image_table import (
    BLOCK,
    DOC,
    docs_rows,
    merge_rows,
    parse_block,
    table,
)


def _row(setup: str, noise: float, tool: float) -> dict:
    return {"setup": setup, "noise_px": noise, "calibrations": 29, "failed": 1, "checks": 290,
            "unchanged": 0.01, "tool": tool, "tool_oracle": 0.9, "tool_size": 0.85, "tool_axes": 0.8,
            "tool_right": 0.5, "tool_wrong": 0.0, "joint": 1.0, "joint_right": 0.4,
            "joint_wrong": 0.1, "views": 5, "unchanged_cannot_tell": 2, "tool_cannot_tell": 19,
            "joint_cannot_tell": 7}  # fmt: skip


def test_the_docs_block_reads_back_as_written():
    """The block in docs/tool-accuracy.md parses into its rows and prints as it stands."""
    text = read_block(DOC, BLOCK)
    rows, calibrations, checks = parse_block(text)
    assert len(rows) >= 2 and calibrations > 0 and checks > 0
    assert table(rows, checks) == text


def test_a_run_rewrites_its_rows_and_keeps_the_others():
    old = [_row("eye-in-hand, er4u-paper", 0.05, 1.0), _row("eye-in-hand, er4u-paper", 0.2, 0.9),
           _row("eye-in-hand, ur5e", 0.2, 1.0), _row("eye-to-hand, ur5e", 0.2, 1.0)]  # fmt: skip
    new = [_row("eye-in-hand, er4u-paper", 0.2, 0.7), _row("eye-in-hand, kr6-r900", 0.2, 0.99)]
    got = merge_rows(old, new)
    assert [(r["setup"], r["noise_px"]) for r in got] == [
        ("eye-in-hand, er4u-paper", 0.05), ("eye-in-hand, er4u-paper", 0.2),
        ("eye-in-hand, ur5e", 0.2), ("eye-to-hand, ur5e", 0.2), ("eye-in-hand, kr6-r900", 0.2),
    ]  # fmt: skip
    assert [r["tool"] for r in got] == [1.0, 0.7, 1.0, 1.0, 0.99]
    text = table(got, 10)
    assert "| eye-in-hand, er4u-paper | 0.2 | 29 | 290 | 1.0 % | 70.0 % |" in text
    assert "| 40 % / 10 % | 2 / 19 / 7 |" in text  # the 'cannot tell' verdicts per kind
    assert "measured by" not in text  # no row records its code
    assert "(5 calibrations failed in all)" in text
    # the command that remakes the whole block names every setup and robot in it
    assert "--calibrations 30 --setup eye-in-hand eye-to-hand --robot er4u-paper ur5e" in text
    assert parse_block(text)[0] == [{k: v for k, v in r.items() if k != "views"} for r in got]


def test_rows_of_other_options_are_not_mixed_in(monkeypatch, tmp_path):
    doc = tmp_path / "doc.md"
    block = table([_row("eye-in-hand, ur5e", 0.2, 1.0)], 10)
    doc.write_text(f"text\n<!-- {BLOCK}: begin -->\n{block}\n<!-- {BLOCK}: end -->\nmore\n")
    monkeypatch.setattr(image_table, "DOC", doc)
    new = [_row("eye-in-hand, er4u-paper", 0.2, 0.7)]
    assert len(docs_rows(new, 30, 10)) == 2
    with pytest.raises(SystemExit, match="--calibrations 30 --checks 10"):
        docs_rows(new, 20, 10)
    with pytest.raises(SystemExit, match="--calibrations 30 --checks 10"):
        docs_rows(new, 30, 5)


def test_the_table_names_the_code_that_measured_each_row_and_reads_it_back():
    """Each row keeps the code that measured it (``code``) through the block; rows of an
    earlier run without it say so, and a row without 'cannot tell' counts shows "-"."""
    now = [_row("eye-in-hand, er4u-paper", 0.2, 0.7) | {"code": "abc1234"},
           _row("eye-to-hand, ur5e", 0.05, 1.0) | {"code": "abc1234"}]  # fmt: skip
    text = table(now, 10)
    assert text.endswith("--write-docs`, measured by the code at abc1234.")
    old = {k: v for k, v in _row("eye-to-hand, ur5e", 0.2, 1.0).items()
           if "cannot" not in k and k != "tool_size"}  # fmt: skip
    mixed = [*now, old | {"code": None}]
    text = table(mixed, 10)
    assert text.endswith(
        "measured by the code at abc1234 (eye-in-hand, er4u-paper, eye-to-hand, ur5e 0.05 px) "
        "and an earlier code, not recorded (eye-to-hand, ur5e 0.2 px)."
    )
    assert "| 40 % / 10 % | - |" in text
    assert "| 90.0 % / 85.0 % / 80.0 % |" in text  # direction / size / 3 axes
    got = parse_block(text)[0]
    assert [r["code"] for r in got] == ["abc1234", "abc1234", None]
    assert [r.get("tool_cannot_tell") for r in got] == [19, 19, None]
    assert "| 90.0 % / - / 80.0 % |" in text  # a row whose run did not record the size's test
    assert [r.get("tool_size") for r in got] == [0.85, 0.85, None]
    assert table(got, 10) == text


def test_a_run_stamps_its_rows_with_the_code_and_counts_its_cannot_tells(monkeypatch):
    """:func:`run` stamps each row with the checked-out code and carries the per-kind
    'cannot tell' counts summed over the calibrations (a stub calibration here)."""
    counts = {"unchanged": 0, "tool": 8, "joint": 10, "checks": 10, "tool_oracle": 9.0,
              "tool_axes": 8.0, "fold_error": 1, "tool_right": 4, "tool_wrong": 0,
              "joint_right": 5, "joint_wrong": 1, "unchanged_cannot_tell": 1,
              "tool_cannot_tell": 2, "joint_cannot_tell": 0}  # fmt: skip
    monkeypatch.setattr(drift_images, "calibration_checks",
                        lambda args: {"status": "ok", **counts, "tool_cannot_tell": args[1]})  # fmt: skip
    monkeypatch.setattr(drift_images, "code_version", lambda: "abc1234")
    (row,) = drift_images.run(3, 10, (0.2,), 1, ("eye-to-hand",))
    assert row["code"] == "abc1234" and row["checks"] == 30
    assert (row["unchanged_cannot_tell"], row["tool_cannot_tell"], row["joint_cannot_tell"]) == (
        3,
        6,
        0,
    )
    assert row["tool"] == 24 / 30
    assert "| 3 / 6 / 0 |" in table([row], 10)


def test_a_journaled_run_redoes_no_finished_calibration(monkeypatch, tmp_path):
    """``--journal``: a run stopped after some calibrations and started again computes only the
    rest and gives the same row; a journal's counts of other code, or of code with uncommitted
    changes, are computed again."""
    calls: list[int] = []

    def checks(args):
        calls.append(args[1])
        if len(calls) == 3 and stop:
            raise KeyboardInterrupt  # the run stopped in its third calibration
        return {"status": "ok", "unchanged": 0, "tool": args[1] % 3, "joint": 10, "checks": 10,
                "tool_oracle": 9.5, "tool_axes": 8.25, "tool_cannot_tell": args[1]}  # fmt: skip

    journal = tmp_path / "checks.jsonl"
    monkeypatch.setattr(drift_images, "calibration_checks", checks)
    monkeypatch.setattr(drift_images, "code_version", lambda: "abc1234")
    stop = True
    with pytest.raises(KeyboardInterrupt):
        drift_images.run(4, 10, (0.2,), 1, ("eye-to-hand",), journal=journal)
    assert calls == [1, 2, 3] and len(journal.read_text().splitlines()) == 2
    stop = False
    calls.clear()
    (row,) = drift_images.run(4, 10, (0.2,), 1, ("eye-to-hand",), journal=journal)
    assert calls == [3, 4]
    calls.clear()
    (again,) = drift_images.run(4, 10, (0.2,), 1, ("eye-to-hand",), journal=journal)
    assert calls == [] and again == row
    assert row["tool_cannot_tell"] == 1 + 2 + 3 + 4 and row["tool"] == (1 + 2 + 0 + 1) / 40
    for other in ("def5678", "abc1234+changes"):
        monkeypatch.setattr(drift_images, "code_version", lambda other=other: other)
        drift_images.run(4, 10, (0.2,), 1, ("eye-to-hand",), journal=journal)
        assert calls == [1, 2, 3, 4]
        calls.clear()
