"""Where the many calibrations of a study or Monte Carlo run execute: in this process, in a pool
of local worker processes (the default, :func:`worker_pool`), or on a Dask distributed cluster
(``--cluster ADDRESS``, :mod:`selfcal.studies.cluster`). :func:`run_tasks` is the one entry point; it
yields each task's result row as it arrives, in completion order."""

from __future__ import annotations

import contextlib
import logging
import multiprocessing as mp
import os
import signal
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool

from selfcal.console.log import LOGGER, get_logger
from selfcal.console.progress import TaskCounts
from selfcal.studies.cluster import DEFAULT_RETRIES, cluster_tasks
from selfcal.threads import THREAD_VARS, THREADS_ENV, limit_threads, thread_count

__all__ = ["ErrorRow", "run_tasks", "worker_pool"]

ErrorRow = Callable[[dict, BaseException], dict]
"""``error_row(item, exc)``: the result row recording that the task for ``item`` failed."""


def _worker_init(threads: int, parent: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    _die_with(parent)
    limit_threads(threads)


def _die_with(parent: int) -> None:
    """End this worker when the parent process ``parent`` ends, however it ends: a parent
    killed by SIGTERM runs no cleanup, and its idle workers waited for work forever (Linux:
    ``prctl(PR_SET_PDEATHSIG)``; elsewhere the pool's shutdown alone)."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    PR_SET_PDEATHSIG = 1
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != parent:  # the parent ended before the line above
        os._exit(1)


@contextlib.contextmanager
def worker_pool(max_workers: int, threads: int | None = None) -> Iterator[ProcessPoolExecutor]:
    """Spawned worker processes with ``threads`` BLAS/OpenMP threads each (default
    :func:`selfcal.threads.thread_count`: ``SELFCAL_THREADS`` or 1; the workers, not BLAS, use
    the cores); they ignore Ctrl-C, which the parent handles. The parent's environment is
    restored and unfinished work cancelled on exit."""
    n = thread_count(threads)
    names = (THREADS_ENV, *THREAD_VARS)
    saved = {v: os.environ.get(v) for v in names}
    for v in names:  # the limit holds from the worker's first import on
        os.environ[v] = str(n)
    ex = ProcessPoolExecutor(
        max_workers=max_workers,
        mp_context=mp.get_context("spawn"),
        initializer=_worker_init,
        initargs=(n, os.getpid()),
    )
    try:
        yield ex
    finally:
        ex.shutdown(wait=True, cancel_futures=True)
        for v, val in saved.items():
            if val is None:
                os.environ.pop(v, None)
            else:
                os.environ[v] = val


def run_tasks(
    fn: Callable[[dict], dict],
    items: Sequence[dict],
    *,
    jobs: int,
    error_row: ErrorRow,
    cluster: str | None = None,
    retries: int = DEFAULT_RETRIES,
    counts: TaskCounts | None = None,
) -> Iterator[tuple[int, dict]]:
    """``(index, fn(items[index]))`` for every item, in the order the results arrive.

    Runs in this process (``jobs`` 1 or a single item), in ``jobs`` local worker processes, or,
    with ``cluster`` (a Dask scheduler address such as ``tcp://host:8786``), as one Dask task per
    item (:func:`selfcal.studies.cluster.cluster_tasks`; ``retries`` extra tries of a task that raised).
    A task that raises gives ``error_row(item, exc)`` instead of its row, so no item is dropped.
    ``counts.running`` is kept up to date (tasks on the workers now). A local pool whose worker
    died (``BrokenProcessPool``) stops the batch: the rows yielded so far stand.
    """
    if cluster is not None:
        yield from cluster_tasks(
            cluster, fn, items, error_row=error_row, retries=retries, counts=counts
        )
        return
    counts = counts or TaskCounts(len(items))
    if jobs <= 1 or len(items) <= 1:
        for i, x in enumerate(items):
            counts.running = 1
            try:
                row = fn(x)
            except Exception as exc:  # noqa: BLE001 - recorded as the item's row
                row = error_row(x, exc)
            counts.running = 0
            yield i, row
        return
    workers = min(jobs, len(items))
    with worker_pool(workers) as ex:
        futs: dict[Future, int] = {ex.submit(_logged, fn, x): i for i, x in enumerate(items)}
        pending = set(futs)
        try:
            while pending:
                counts.running = min(len(pending), workers)
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    counts.running = min(len(pending), workers)
                    yield futs[f], _outcome(f, items[futs[f]], error_row)
        except KeyboardInterrupt:
            for f in pending:
                f.cancel()
            print("interrupted: waiting for the running task(s) to finish ...", file=sys.stderr)
            for f in pending:
                if not f.cancelled():
                    try:
                        row = _unpack(f.result())
                    except Exception:  # noqa: BLE001
                        continue
                    yield futs[f], row
            raise


class _Collect(logging.Handler):
    """Keeps the text of every record (a worker's warnings, for the parent to log)."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.texts: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.texts.append(record.getMessage())


def _logged(fn: Callable[[dict], dict], item: dict) -> tuple[dict, list[str]]:
    """``fn(item)`` in a worker, with the warnings it logged: a worker has no ``selfcal`` log
    handler, so they went raw to the shared stderr, onto the parent's progress bar, and were not
    counted in the command's last line."""
    logger, keep = logging.getLogger(LOGGER), _Collect()
    logger.addHandler(keep)
    logger.propagate = False
    try:
        return fn(item), keep.texts
    finally:
        logger.removeHandler(keep)


def _unpack(result: tuple[dict, list[str]]) -> dict:
    """The row of :func:`_logged`, its warnings logged here (printed above the bar, counted)."""
    row, texts = result
    for text in texts:
        get_logger("worker").warning("%s", text)
    return row


def _outcome(f: Future, item: dict, error_row: ErrorRow) -> dict:
    try:
        return _unpack(f.result())
    except BrokenProcessPool:
        raise
    except Exception as exc:  # noqa: BLE001 - recorded as the item's row
        return error_row(item, exc)
