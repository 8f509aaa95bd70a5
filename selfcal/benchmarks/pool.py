"""The benchmark scripts' map over their draws: ``jobs`` worker processes when ``jobs`` > 1,
else a loop in this process; the results in the items' order either way (each draw is seeded
by its item, so the numbers do not depend on ``jobs``)."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import TypeVar

__all__ = ["imap_jobs", "map_jobs"]

Item = TypeVar("Item")
Result = TypeVar("Result")


def map_jobs(fn: Callable[[Item], Result], items: Iterable[Item], jobs: int) -> list[Result]:
    """``[fn(x) for x in items]``, in a pool of ``jobs`` processes when ``jobs`` > 1 (``fn``
    and the items picklable: a module-level function and plain data), else in this process.
    An exception ``fn`` raises is raised here (the scripts' draws return a status instead)."""
    return list(imap_jobs(fn, items, jobs))


def imap_jobs(fn: Callable[[Item], Result], items: Iterable[Item], jobs: int) -> Iterator[Result]:
    """:func:`map_jobs` yielding each result as soon as it and those before it are done (a
    caller can journal each draw the moment it finishes)."""
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            yield from pool.map(fn, items)
        return
    for x in items:
        yield fn(x)
