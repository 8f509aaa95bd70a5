"""``selfcal montecarlo --out DIR`` is resumable (issue #18): every finished draw goes to the
journal ``DIR/draws.jsonl`` at once; read back it is the same row bit for bit; a line cut short by
a kill is skipped; a run interrupted part-way and run again computes only the missing draws, and
draws of other settings in the folder are never taken for this run's. (On a Dask cluster and
back: tests/integration/test_cluster.py, slow tier.)"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from selfcal.studies.montecarlo.journal import JOURNAL, DrawJournal, draw_key
from selfcal.studies.montecarlo.run import run_montecarlo


def test_rows_read_back_bit_identical(tmp_path):
    j = DrawJournal(tmp_path / JOURNAL)
    row = {
        "seed": 3,
        "a": 0.1 + 0.2,
        "b": np.float64(1.0) / 3.0,
        "tiny": 5e-324,
        "none": None,
        "flag": True,
        "nan": float("nan"),
        "status": "ok",
    }
    j.append("k", row)
    back = j.load()["k"]
    assert list(back) == list(row)  # column order kept (runs.csv's columns)
    for k, v in row.items():
        if k == "nan":
            assert math.isnan(back[k])
        else:
            assert back[k] == v, k  # floats: the same number, so the same bits


def test_a_line_cut_short_by_a_kill_is_skipped(tmp_path):
    p = tmp_path / JOURNAL
    j = DrawJournal(p)
    j.append("a", {"x": 1.0})
    with open(p, "a") as fh:
        fh.write('{"key": "b", "row": {"x": 2')  # the writer died mid-line
    assert set(j.load()) == {"a"}
    j.append("c", {"x": 3.0})
    assert j.load() == {"a": {"x": 1.0}, "c": {"x": 3.0}}
    assert len(p.read_text().splitlines()) == 3


def test_the_key_is_the_complete_settings():
    a = {"seed": 1, "pixel_sigma": 0.5, "config": None}
    assert draw_key(a) == draw_key(dict(reversed(list(a.items()))))
    assert draw_key(a) != draw_key({**a, "pixel_sigma": 0.25})
    assert draw_key({**a, "q": np.array([1.0, 2.0])}) == draw_key({**a, "q": [1.0, 2.0]})


def _fake(calls: list, stop_at: int | None, settings: dict) -> dict:
    """A draw without a calibration: its row is a function of the settings alone."""
    if settings["seed"] == stop_at:
        raise KeyboardInterrupt  # Ctrl-C while this draw runs
    calls.append(settings["seed"])
    return {
        "seed": settings["seed"],
        "pixel_sigma": settings["pixel_sigma"],
        "status": "fake",
        "value": settings["seed"] / 7.0,
        "seconds": 0.0,
    }


def test_an_interrupted_run_resumes_without_computing_a_draw_twice(tmp_path):
    calls: list[int] = []
    kw = {"jobs": 1, "quiet": True, "first_seed": 1}
    with pytest.raises(KeyboardInterrupt):
        run_montecarlo(5, tmp_path, task=lambda s: _fake(calls, 3, s), **kw)
    assert calls == [1, 2]
    assert len((tmp_path / JOURNAL).read_text().splitlines()) == 2
    calls.clear()
    rows, summary = run_montecarlo(5, tmp_path, task=lambda s: _fake(calls, None, s), **kw)
    assert calls == [3, 4, 5]  # the two finished draws are not run again
    assert [r["seed"] for r in rows] == [1, 2, 3, 4, 5]
    assert [r["value"] for r in rows] == [s / 7.0 for s in range(1, 6)]
    assert summary["draws"] == 5
    with open(tmp_path / "runs.csv", newline="") as fh:
        assert [int(r["seed"]) for r in csv.DictReader(fh)] == [1, 2, 3, 4, 5]
    # more draws later: only the new ones run
    calls.clear()
    rows, _ = run_montecarlo(7, tmp_path, task=lambda s: _fake(calls, None, s), **kw)
    assert calls == [6, 7] and len(rows) == 7
    # other settings in the same folder: none of the journal's draws is theirs
    calls.clear()
    rows, _ = run_montecarlo(
        2, tmp_path, pixel_sigma=0.25, task=lambda s: _fake(calls, None, s), **kw
    )
    assert calls == [1, 2] and all(r["pixel_sigma"] == 0.25 for r in rows)
    keys = [json.loads(line)["key"] for line in (tmp_path / JOURNAL).read_text().splitlines()]
    assert len(keys) == len(set(keys)) == 9
