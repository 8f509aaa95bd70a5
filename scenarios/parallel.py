"""Worker processes for scenario scripts that run many calibrations (studies, Monte Carlo)."""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor

__all__ = ["worker_pool"]

_THREAD_VARS = (
    "OPENBLAS_NUM_THREADS",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)


def _worker_init() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C


@contextlib.contextmanager
def worker_pool(max_workers: int) -> Iterator[ProcessPoolExecutor]:
    """Spawned worker processes with one BLAS/OpenMP thread each (the workers, not BLAS, use the
    cores); they ignore Ctrl-C, which the parent handles. The parent's environment is restored and
    unfinished work cancelled on exit."""
    saved = {v: os.environ.get(v) for v in _THREAD_VARS}
    for v in _THREAD_VARS:
        os.environ[v] = "1"
    ex = ProcessPoolExecutor(
        max_workers=max_workers, mp_context=mp.get_context("spawn"), initializer=_worker_init
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
