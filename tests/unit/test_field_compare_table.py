"""The field plan benchmark's table (selfcal.benchmarks.plan.field_compare): it counts the draws
each set ran, and a table short of ``--draws`` draws is printed but never written to the docs."""

from __future__ import annotations

import json

import numpy as np
import pytest

from selfcal.benchmarks import doc_blocks
from selfcal.benchmarks.plan import compare, field_compare


@pytest.fixture
def journal(tmp_path, monkeypatch):
    """Two sets with their forecasts (m) and a journal of draws; no planning, no drawing; the
    code checked out is abc1234."""
    q = np.zeros((1, 6))
    sets = {"plan 12": (tmp_path, q, 0.0003), "random 30": (tmp_path, q, 0.0002)}
    monkeypatch.setattr(field_compare, "field_sets", lambda root, **kw: sets)
    monkeypatch.setattr(field_compare, "code_version", lambda: "abc1234")
    monkeypatch.setattr(compare, "draw_all", lambda draw, items, jobs, root, done: done)

    def write(seeds: dict[str, int], cell: str = "ur5e analytic 0.5 px", **extra) -> None:
        rows = [{"set": name, "seed": s, "status": "ok", "joint_tip_rms_mm": 0.1 * s,
                 "fair_nominal_tip_rms_mm": 1.0, "cell": stamp(cell), "code": "abc1234", **extra}
                for name, n in seeds.items() for s in range(1, n + 1)]  # fmt: skip
        (tmp_path / "draws.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))

    return tmp_path, write


def stamp(cell: str) -> str:
    """The fixture's sets' stamp (both sets hold the same postures) for ``cell`` = "ROBOT PATH
    SIGMA px"."""
    robot, path, sigma, _ = cell.split()
    return field_compare.cell_stamp(robot, path == "rendered", float(sigma), np.zeros((1, 6)))


def test_a_short_table_is_not_written(journal, capsys, monkeypatch):
    root, write = journal
    written = []
    monkeypatch.setattr(doc_blocks, "write_block", lambda *a: written.append(a))
    write({"plan 12": 3, "random 30": 2})
    assert field_compare.main(["--draws", "3", "--out", str(root), "--write-docs"]) == 1
    out = capsys.readouterr().out
    assert "| random 30 | 2 of 2 |" in out and "random 30: 2 of 3 draws" in out
    assert not written


def test_a_whole_table_counts_its_draws(journal, capsys):
    root, write = journal
    write({"plan 12": 3, "random 30": 3})
    assert field_compare.main(["--draws", "3", "--out", str(root)]) == 0
    out = capsys.readouterr().out
    assert "| plan 12 | 3 of 3 | not recorded | 0.300 | 0.200 | 0.280 | 0.67 | 1.000 |" in out


def test_the_frames_used_are_summed_and_another_cell_has_its_own_block(
    journal, capsys, monkeypatch
):
    root, write = journal
    written = []
    monkeypatch.setattr(doc_blocks, "write_block", lambda *a: written.append(a))
    write({"plan 12": 3, "random 30": 3}, "kr6-r900 rendered 0.1 px", frames=12, frames_used=11)
    noise = _measured_noise(monkeypatch)
    argv = ["--robot", "kr6-r900", "--render", "--pixel-sigma", "0.1", "--draws", "3"]
    assert field_compare.main([*argv, "--out", str(root), "--write-docs"]) == 0
    out = capsys.readouterr().out
    assert "| plan 12 | 3 of 3 | 33 of 36 | 0.300 |" in out
    assert "field_compare --robot kr6-r900 --render --pixel-sigma 0.1 --draws 3" in out
    assert "(seeds 1 - 3), measured by the code at abc1234" in written[0][1]
    assert [a[2] for a in written] == ["benchmark_plan_field_compare_kr6-r900-rendered"]
    # each set's noise measured apart from the draws (seed 0, its own postures, in its own
    # folder) and its forecast at it and at its marker centres' noise
    assert noise == [(root / "plan-12", 0.1), (root / "random-30", 0.1)]
    assert "rendered for seed 0, corners against the truth, those beyond the route's 1 px" in out
    assert ("plan 12 0.030 px (500 corners, 2 left out), its marker centres' and shapes' "
            "0.010 and 0.034 px; the forecast at it 0.100 mm (median / it 2.00); at the centres' "
            "and shapes' 0.050 mm (median / it 4.00) | random 30") in out  # fmt: skip


def _measured_noise(monkeypatch) -> list:
    """The rendered table's noise measurement replaced (no images): 0.03 px over 500 corners,
    the marker centres' 0.01 px and shapes' 0.034 px, the forecast 0.1 mm at 0.03 px and
    0.05 mm at the centres' and shapes' for every set; returns the (folder, pixel sigma) each
    measurement was asked for."""
    from selfcal.benchmarks.plan import field_noise

    asked: list = []

    def measured(root, config, joints_deg, cell, pixel_sigma_px):
        asked.append((root, pixel_sigma_px))
        return {"cell": cell, "seed": 0, "count": 500, "sigma_px": 0.03, "outliers": 2,
                "centre_sigma_px": 0.01, "shape_sigma_px": 0.034}  # fmt: skip

    def at(root, robot_name, sets, pixel_sigma_px, split=None):
        assert robot_name == "kr6-r900" and len(sets) == 1 and pixel_sigma_px == 0.03
        return dict.fromkeys(sets, {None: 1e-4, (0.01, 0.034): 5e-5}[split])

    monkeypatch.setattr(field_noise, "measured_noise", measured)
    monkeypatch.setattr(field_compare, "forecasts_at", at)
    return asked


def test_the_sets_are_compared_draw_by_draw_with_a_sign_test(journal, capsys):
    root, _ = journal
    plan = [0.1, 0.3, 0.2, 0.4]  # errs less than the random set in draws 1, 3 and 4 of 4
    rand = [0.2, 0.2, 0.3, 0.5]
    rows = [{"set": name, "seed": s + 1, "status": "ok", "joint_tip_rms_mm": e[s],
             "fair_nominal_tip_rms_mm": 1.0, "cell": stamp("ur5e analytic 0.5 px"),
             "code": "abc1234"}
            for name, e in (("plan 12", plan), ("random 30", rand)) for s in range(4)]  # fmt: skip
    (root / "draws.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert field_compare.main(["--draws", "4", "--out", str(root)]) == 0
    out = capsys.readouterr().out
    # P(X >= 3 | 4, 1/2) = 5/16
    assert "plan 12 errs less in 3 of 4 draws (one-sided sign test p = 0.31)" in out


@pytest.mark.parametrize(
    ("cell", "argv"),
    [
        ("ur5e analytic 0.5 px", ["--robot", "kr6-r900"]),  # another arm
        ("ur5e analytic 0.5 px", ["--render"]),  # the rendered path
        ("ur5e analytic 0.5 px", ["--pixel-sigma", "0.1"]),  # another corner noise
        (None, []),  # an older journal: no stamp
    ],
)
def test_a_journal_of_another_cell_is_refused(journal, capsys, monkeypatch, cell, argv):
    """Resuming from a folder holding another cell's draws would table them as this cell's."""
    from selfcal.errors import InputError

    root, write = journal
    written = []
    monkeypatch.setattr(doc_blocks, "write_block", lambda *a: written.append(a))
    write({"plan 12": 3, "random 30": 3})
    if cell is None:
        rows = [json.loads(x) for x in (root / "draws.jsonl").read_text().splitlines()]
        (root / "draws.jsonl").write_text(
            "".join(json.dumps({k: v for k, v in r.items() if k != "cell"}) + "\n" for r in rows)
        )
    with pytest.raises(
        InputError, match="draws.jsonl: 6 of its 6 draws were made for another"
    ) as e:
        field_compare.main([*argv, "--draws", "3", "--out", str(root), "--write-docs"])
    assert "its own --out" in e.value.fix and not written


def test_another_plan_in_the_same_cell_is_refused(journal, monkeypatch):
    """The same cell, but the planner now picks other postures: the old draws are not its."""
    from selfcal.errors import InputError

    root, write = journal
    write({"plan 12": 3, "random 30": 3})
    moved = {
        "plan 12": (root, np.ones((1, 6)), 0.0003),
        "random 30": (root, np.zeros((1, 6)), 0.0002),
    }
    monkeypatch.setattr(field_compare, "field_sets", lambda root, **kw: moved)
    with pytest.raises(InputError, match="3 of its 6 draws .* set 'plan 12', seed 1"):
        field_compare.main(["--draws", "3", "--out", str(root)])


def test_the_default_folder_is_the_cells_own():
    a = field_compare._options(["--robot", "kr6-r900", "--render"])
    assert a.out == "runs/benchmark_plan_field_compare_kr6-r900-rendered"
    assert field_compare._options([]).out == "runs/benchmark_plan_field_compare"


@pytest.mark.parametrize("code", ["0123456", None])  # other code; an older journal: none recorded
def test_a_journal_of_other_code_is_refused(journal, monkeypatch, code):
    """The same cell and postures drawn by other code: resuming would table two codes' draws as
    one code's (review of session 23)."""
    from selfcal.errors import InputError

    root, write = journal
    written = []
    monkeypatch.setattr(doc_blocks, "write_block", lambda *a: written.append(a))
    write({"plan 12": 3, "random 30": 3}, code=code)
    with pytest.raises(InputError, match="6 of its 6 draws were made by other code") as e:
        field_compare.main(["--draws", "3", "--out", str(root), "--write-docs"])
    assert ("the code at 0123456" if code else "not recorded") in str(e.value)
    assert "check out that code" in e.value.fix and not written
