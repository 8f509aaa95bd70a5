"""Worker processes for scenario scripts that run many calibrations (studies, Monte Carlo)."""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor

from scenarios.threads import THREAD_VARS, THREADS_ENV, limit_threads, thread_count

__all__ = ["worker_pool"]


def _worker_init(threads: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    limit_threads(threads)


@contextlib.contextmanager
def worker_pool(max_workers: int, threads: int | None = None) -> Iterator[ProcessPoolExecutor]:
    """Spawned worker processes with ``threads`` BLAS/OpenMP threads each (default
    :func:`scenarios.threads.thread_count`: ``SELFCAL_THREADS`` or 1; the workers, not BLAS, use
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
        initargs=(n,),
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
