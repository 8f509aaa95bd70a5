"""The --add benchmark reuses a truth's folder only for the same K, mount and clean commit
(selfcal/benchmarks/plan/add.py ``fresh_truth``): a table never holds rows another K or other
code measured (review finding 3 of session 23)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import selfcal.benchmarks.plan.add as bench


@pytest.fixture
def code(monkeypatch):
    now = {"code": "abc1234"}
    monkeypatch.setattr(bench, "code_version", lambda: now["code"])
    return now


def _measured(root):
    (root / "plan").mkdir(parents=True)
    (root / "plan/plan.json").write_text("{}")


def test_the_same_k_mount_and_commit_keep_the_folder(tmp_path, code):
    root = tmp_path / "truth1"
    bench.fresh_truth(root, 5, "eye-to-hand")
    _measured(root)
    bench.fresh_truth(root, 5, "eye-to-hand")
    assert (root / "plan/plan.json").is_file()
    stamp = json.loads((root / "benchmark.json").read_text())
    assert stamp == {"add": 5, "mount": "eye-to-hand", "code": "abc1234"}


@pytest.mark.parametrize(
    ("add", "mount", "later"),
    [(8, "eye-to-hand", "abc1234"), (5, "eye-in-hand", "abc1234"), (5, "eye-to-hand", "def5678"),
     (5, "eye-to-hand", "abc1234+changes"), (5, "eye-to-hand", None)],
    ids=["other-K", "other-mount", "other-commit", "uncommitted", "no-git"],
)  # fmt: skip
def test_another_k_mount_or_code_measures_anew(tmp_path, code, add, mount, later):
    root = tmp_path / "truth1"
    bench.fresh_truth(root, 5, "eye-to-hand")
    _measured(root)
    code["code"] = later
    bench.fresh_truth(root, add, mount)
    assert not (root / "plan").exists()
    assert json.loads((root / "benchmark.json").read_text())["add"] == add


def test_a_folder_without_a_stamp_is_measured_anew(tmp_path, code):
    root = tmp_path / "truth1"
    _measured(root)  # a run of the code before the stamp
    bench.fresh_truth(root, 5, "eye-in-hand")
    assert not (root / "plan").exists() and (root / "benchmark.json").is_file()


def test_a_wrist_only_draw_that_selfcal_run_refuses_is_a_row_saying_so(tmp_path, monkeypatch):
    # session 29's run of 30 truths stopped at truth 16 (5 feasible postures, then fewer than
    # `selfcal run` took) with FileNotFoundError; the board route now takes 4 (folds.MIN_FRAMES),
    # so the draw is cut to 3 feasible postures here
    import selfcal.calibration.board.plan.feasible as rules

    real = rules.feasible

    def three(setup, q):
        ok = real(setup, q)
        ok[np.flatnonzero(ok)[3:]] = False
        return ok

    monkeypatch.setattr(rules, "feasible", three)
    row = bench.wrist_only_row(tmp_path / "truth16", 16, 5)
    assert row["frames"] == 3
    assert "selfcal run stopped" in row["error"]
    assert row["predicted_before_mm"] != row["predicted_before_mm"]  # NaN, not a number
