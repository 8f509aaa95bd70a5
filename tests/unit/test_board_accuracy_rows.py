"""The board accuracy benchmark's rows (selfcal.benchmarks.board.accuracy): each says which code
measured it, the table names the codes, and ``--from-rows`` merges a rerun of some rows into a
whole run's."""

from __future__ import annotations

import json

import numpy as np
import pytest

from selfcal.benchmarks.board import accuracy as board_accuracy
from selfcal.benchmarks.board.accuracy_draw import REGIONS
from selfcal.benchmarks.board.accuracy_tables import BLOCK_GEAR, BLOCK_SEEDS, pooled_rows, table
from selfcal.benchmarks.doc_blocks import read_block
from selfcal.errors import InputError


def _got(n: int, seed: int = 1) -> list[dict]:
    e = np.random.default_rng(seed).uniform(0.1, 1.0, (7, 16))
    return [{"status": "ok", "model_error_mm": 0.0, **{r: e for r in REGIONS}}] * n


def _rows(robot: str, model: str, s: float, code: str | None, seed: int = 1) -> list[dict]:
    rows = pooled_rows(robot, model, s, _got(3, seed))
    return rows if code is None else [r | {"code": code} for r in rows]


def _write(path, rows):
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    return path


def test_a_run_stamps_its_rows_with_the_code_that_measured_them(tmp_path, monkeypatch):
    monkeypatch.setattr(board_accuracy, "code_version", lambda: "abc1234")
    monkeypatch.setattr(board_accuracy, "draw", lambda args: _got(1, args[3])[0])
    out = tmp_path / "rows.jsonl"
    rows = board_accuracy.run(2, ("ur5e",), ("fits",), (0.2,), jobs=1, rows_file=out)
    assert [r["code"] for r in rows] == ["abc1234"] * len(REGIONS)
    assert [json.loads(line)["code"] for line in out.read_text().splitlines()] == ["abc1234"] * 3
    assert table(rows).endswith("--jobs 1 --write-docs`, measured by the code at abc1234.")


def test_the_tables_command_names_other_seeds_and_then_writes_no_docs(monkeypatch):
    """Rows of seeds 91, 92, ... say so in the table's command, without --write-docs (no block
    holds them: :data:`BLOCK_SEEDS`): the printed command makes those rows again."""
    monkeypatch.setattr(board_accuracy, "code_version", lambda: "abc1234")
    monkeypatch.setattr(board_accuracy, "draw", lambda args: _got(1, args[3])[0])
    rows = board_accuracy.run(2, ("ur5e",), ("fits",), (0.2,), jobs=1, first_seed=91)
    text = table(rows)
    assert "--noise-px 0.2 --first-seed 91 --jobs 1`, measured by the code at abc1234." in text
    assert "--write-docs" not in text


def test_a_run_started_again_keeps_the_rows_its_code_and_seeds_measured(tmp_path, monkeypatch):
    """--rows-out resumes: a row already in the file from the same clean commit, seeds and
    draws is kept, not drawn again; another commit, other seeds, other draws or a tree with
    changes measure it again (and append it)."""
    calls = []
    monkeypatch.setattr(board_accuracy, "draw", lambda args: calls.append(args) or _got(1)[0])
    out = tmp_path / "rows.jsonl"

    def again(code: str, draws: int = 2, first_seed: int = 1) -> list[dict]:
        calls.clear()
        monkeypatch.setattr(board_accuracy, "code_version", lambda: code)
        return board_accuracy.run(draws, ("ur5e",), ("fits",), (0.2, 0.5), jobs=1,
                                  rows_file=out, first_seed=first_seed)  # fmt: skip

    first = again("abc1234")
    assert len(calls) == 4 and len(out.read_text().splitlines()) == 6
    assert again("abc1234") == first and calls == []  # both rows kept
    assert len(out.read_text().splitlines()) == 6
    lines = out.read_text().splitlines()
    out.write_text("\n".join(lines[:4]) + "\n")  # stopped within the 0.5 px row
    assert again("abc1234") == first and [a[1] for a in calls] == [0.5, 0.5]
    for code, draws, seed in (("def5678", 2, 1), ("abc1234", 3, 1), ("abc1234", 2, 4),
                              ("abc1234+changes", 2, 1)):  # fmt: skip
        again(code, draws, seed)
        assert len(calls) == 2 * draws, (code, draws, seed)


def test_the_table_names_which_code_measured_which_rows():
    now = [*_rows("er4u-paper", "fits", 0.2, "abc1234"),
           *_rows("er4u-paper", "compliance", 0.2, "abc1234")]  # fmt: skip
    old = _rows("ur5e", "fits", 0.2, None)
    assert table([*now, *old]).endswith(
        "measured by the code at abc1234 (er4u-paper) and an earlier code, not recorded (ur5e)."
    )
    split = [*now[:3], *_rows("er4u-paper", "compliance", 0.2, None),
             *_rows("er4u-paper", "compliance", 0.5, "abc1234")]  # fmt: skip
    assert table(split).endswith(
        "measured by the code at abc1234 (er4u-paper fits, er4u-paper compliance 0.5 px) and an "
        "earlier code, not recorded (er4u-paper compliance 0.2 px)."
    )
    assert "measured by" not in table(old)  # no row records its code: nothing said


def test_from_rows_puts_a_reruns_rows_in_the_place_of_the_whole_runs(tmp_path, capsys):
    whole = _write(tmp_path / "whole.jsonl", [*_rows("er4u-paper", "fits", 0.2, None),
                                              *_rows("ur5e", "fits", 0.2, None)])  # fmt: skip
    again = _write(tmp_path / "again.jsonl", [*_rows("ur5e", "fits", 0.2, "abc1234", seed=2),
                                              *_rows("kr6-r900", "fits", 0.2, "abc1234")])  # fmt: skip
    rows = board_accuracy.merged_rows([whole, again])
    assert [(r["robot"], r.get("code")) for r in rows[::3]] == [
        ("er4u-paper", None), ("ur5e", "abc1234"), ("kr6-r900", "abc1234")]  # fmt: skip
    assert rows[3] == _rows("ur5e", "fits", 0.2, "abc1234", seed=2)[0]
    assert board_accuracy.main(["--from-rows", str(whole), str(again)]) == 0
    assert (
        "measured by an earlier code, not recorded (er4u-paper) and the code at abc1234 "
        "(ur5e, kr6-r900)."
    ) in capsys.readouterr().out
    bad = tmp_path / "bad.jsonl"
    bad.write_text(whole.read_text() + "{not json\n")
    with pytest.raises(InputError, match=r"bad.jsonl: line 7 is not a row"):
        board_accuracy.merged_rows([bad])


def _seeded(rows: list[dict], first_seed: int) -> list[dict]:
    return [r | {"first_seed": first_seed} for r in rows]


def test_the_draws_seeded_181_have_a_block_of_their_own(tmp_path, monkeypatch, capsys):
    """``--from-rows FILE --first-seed 181 --write-docs`` writes the rows of seeds 181, 182, ...
    into their own block (the one the table's command names), leaving the block of seeds 1, 2,
    ... as it was; the table's command then says ``--first-seed 181 ... --write-docs``."""
    doc = tmp_path / "tool-accuracy.md"
    seeds_1, seeds_181 = BLOCK_SEEDS[1], BLOCK_SEEDS[181]
    doc.write_text("".join(f"<!-- {b}: begin -->\nold {b}\n<!-- {b}: end -->\n"
                           for b in (seeds_1, seeds_181)))  # fmt: skip
    monkeypatch.setattr(board_accuracy, "DOC", doc)
    rows = _seeded([*_rows("er4u-paper", "fits", 0.05, None), *_rows("ur5e", "fits", 0.2, None)],
                   181)  # fmt: skip
    path = _write(tmp_path / "rows.jsonl", rows)
    assert board_accuracy.main(["--from-rows", str(path), "--first-seed", "181",
                                "--write-docs"]) == 0  # fmt: skip
    written = read_block(doc, seeds_181)
    assert written == table(rows) and written in capsys.readouterr().out
    assert ("--robots er4u-paper,ur5e --models fits --noise-px 0.05,0.2 --first-seed 181 "
            "--jobs 1 --write-docs`.") in written  # fmt: skip
    assert read_block(doc, seeds_1) == f"old {seeds_1}"


def test_the_gear_rows_have_a_block_of_their_own(tmp_path, monkeypatch, capsys):
    """``--from-rows FILE --write-docs`` of ``gear`` rows alone writes :data:`BLOCK_GEAR`,
    leaving the fits / compliance block as it was; the table's command says ``--models gear
    ... --write-docs``; rows mixing the gear with another model are refused in one line."""
    doc = tmp_path / "tool-accuracy.md"
    doc.write_text("".join(f"<!-- {b}: begin -->\nold {b}\n<!-- {b}: end -->\n"
                           for b in (BLOCK_SEEDS[1], BLOCK_GEAR)))  # fmt: skip
    monkeypatch.setattr(board_accuracy, "DOC", doc)
    rows = [*_rows("ur5e", "gear", 0.05, None), *_rows("kr6-r900", "gear", 0.05, None)]
    path = _write(tmp_path / "rows.jsonl", rows)
    assert board_accuracy.main(["--from-rows", str(path), "--write-docs"]) == 0
    written = read_block(doc, BLOCK_GEAR)
    assert written == table(rows) and written in capsys.readouterr().out
    assert "--robots ur5e,kr6-r900 --models gear --noise-px 0.05 --jobs 1 --write-docs`" in written
    assert read_block(doc, BLOCK_SEEDS[1]) == f"old {BLOCK_SEEDS[1]}"
    mixed = _write(tmp_path / "mixed.jsonl", [*rows, *_rows("ur5e", "fits", 0.05, None)])
    assert board_accuracy.main(["--from-rows", str(mixed), "--write-docs"]) == 2
    err = capsys.readouterr().err
    assert "--models gear,fits: --write-docs writes the gear rows" in err and err.count("\n") == 1
    assert "--write-docs" not in table([*rows, *_rows("ur5e", "fits", 0.2, None)])


@pytest.mark.parametrize(
    ("argv", "said"),
    [(["--first-seed", "91"], "--first-seed 91: --write-docs writes the analytic path's blocks "
      "of --first-seed 1 or --first-seed 181"),
     (["--read-back", "gaussian"], "--read-back gaussian: --write-docs writes blocks of the "
      "rounded read-back"),
     (["--poses", "12"], "--poses 12: --write-docs writes blocks of 30 postures"),
     (["--render", "--first-seed", "181"], "--write-docs writes the rendered path's blocks of "
      "--first-seed 1"),
     (["--draws", "0"], "--draws 0: give at least 1 draw per row")],
)  # fmt: skip
def test_options_no_block_takes_are_one_line_before_any_draw(argv, said, monkeypatch, capsys):
    """``--write-docs`` with draws no block holds (other seeds, read-back, postures) is refused
    in one line on stderr, exit 2, before a draw runs (no traceback)."""
    monkeypatch.setattr(board_accuracy, "draw", lambda args: pytest.fail("a draw ran"))
    assert board_accuracy.main([*argv, "--write-docs"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("board_accuracy: error: ") and said in err, err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_from_rows_writes_docs_only_for_the_seeds_it_is_given(tmp_path, monkeypatch, capsys):
    """``--from-rows --write-docs``: rows of seeds 181, ... without ``--first-seed 181`` are
    refused (the command would name the block of seeds 1), so are rows of several seeds and an
    empty file; each in one line, and the docs are not touched."""
    doc = tmp_path / "tool-accuracy.md"
    doc.write_text("untouched\n")
    monkeypatch.setattr(board_accuracy, "DOC", doc)
    ur5e = _rows("ur5e", "fits", 0.2, None)
    cases = [
        ([*_seeded(ur5e, 181)], [], "the rows are of the draws seeded 181, ... and --first-seed "
         "is 1 (fix: give --first-seed 181)"),
        ([*_seeded(ur5e, 181), *_rows("er4u-paper", "fits", 0.2, None)], ["--first-seed", "181"],
         "the rows mix first seeds, read-backs or postures"),
        ([], [], "no rows"),
    ]  # fmt: skip
    for k, (rows, argv, said) in enumerate(cases):
        path = _write(tmp_path / f"rows{k}.jsonl", rows)
        assert board_accuracy.main(["--from-rows", str(path), *argv, "--write-docs"]) == 2
        err = capsys.readouterr().err
        assert said in err and err.count("\n") == 1, err
    assert doc.read_text() == "untouched\n"


def test_docs_hold_a_block_for_each_seed_block_write_docs_writes():
    """docs/tool-accuracy.md has the markers of every block of :data:`BLOCK_SEEDS`, so
    ``--write-docs`` of those seeds has where to write (a missing pair is an error there)."""
    from selfcal.benchmarks.board.accuracy_tables import DOC

    for name in [*BLOCK_SEEDS.values(), BLOCK_GEAR]:
        assert "|---|" in read_block(DOC, name), name
