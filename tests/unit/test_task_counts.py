"""Progress of a batch of tasks (selfcal.console.progress.TaskCounts): counts and the time left."""

from __future__ import annotations

from selfcal.console import progress
from selfcal.console.progress import TaskCounts


def test_counts_and_time_left(monkeypatch):
    now = [100.0]
    monkeypatch.setattr(progress.time, "perf_counter", lambda: now[0])
    c = TaskCounts(10)
    assert c.seconds_left() is None
    assert c.line() == "0/10 done, 0 running, 0 failed"
    now[0] = 106.0  # 3 tasks in 6 s: 2 s per task, 7 left
    c.finish()
    c.finish(failed=True)
    c.finish()
    c.running = 2
    assert c.seconds_left() == 14.0
    assert c.line() == "3/10 done, 2 running, 1 failed, ~14 s left"
