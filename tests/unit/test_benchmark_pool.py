"""The benchmark scripts' map (selfcal.benchmarks.pool): worker processes when jobs > 1, this
process otherwise, the results in the items' order either way."""

from __future__ import annotations

import os

from selfcal.benchmarks.pool import map_jobs


def _square_and_pid(x: int) -> tuple[int, int]:
    return x * x, os.getpid()


def test_the_map_keeps_the_order_and_runs_where_jobs_say():
    items = list(range(7))
    here = map_jobs(_square_and_pid, items, 1)
    pooled = map_jobs(_square_and_pid, iter(items), 2)  # any iterable
    assert [r for r, _ in here] == [r for r, _ in pooled] == [x * x for x in items]
    assert {p for _, p in here} == {os.getpid()}
    assert os.getpid() not in {p for _, p in pooled}
    assert map_jobs(_square_and_pid, [], 2) == []
