"""How many BLAS/OpenMP threads a process of scorbot-selfcal uses (the machines are shared).

One setting: ``selfcal --threads N``, else the environment variable ``SELFCAL_THREADS``, else 1
per process. :func:`limit_threads` applies it to the running process with ``threadpoolctl`` (the
libraries loaded already) and through the usual environment variables (libraries loaded later,
and child processes); the ``selfcal`` entry point and every worker of
:func:`selfcal.studies.parallel.worker_pool` call it. :func:`limited` applies the same number for
the length of one call and restores the caller's pools after it: the public API's computing
functions (``selfcal.calibrate``, ``selfcal.evaluate``, ...: docs/api.md) run under it, so a
program that calls them as a library gets the command's limit without having its own process
changed. Parallel studies and Monte Carlo runs use the cores through worker processes, not
through BLAS.

:func:`limit_threads` also keeps the memory of freed large arrays in this process for the next
ones (:func:`reuse_freed_memory`, glibc only): the default allocator maps an array above 32 MiB
afresh and unmaps it when freed, so each of the solver's per-iteration arrays (the Jacobian
pieces, the Schur assembly's gathered columns and coupling block: tens of MB from ~3000
postures up) cost its size in page faults, zeroed by the kernel, every iteration.

Pools of Python threads that run OpenCV calls releasing the GIL (image decoding and marker
detection, the epipolar pairs) are not BLAS threads: :func:`helper_threads` sizes them, from the
cores this process may run on (its CPU affinity, not the machine's count), capped by the caller.
"""

from __future__ import annotations

import ctypes
import functools
import os
import platform
from collections.abc import Callable
from typing import ParamSpec, TypeVar

import numpy as np  # noqa: F401  (loads the BLAS that threadpoolctl then limits)
from threadpoolctl import threadpool_limits

from selfcal.errors import InputError

__all__ = [
    "ALLOCATOR_KEEP_BYTES",
    "DEFAULT_THREADS",
    "THREADS_ENV",
    "THREAD_VARS",
    "helper_threads",
    "limit_threads",
    "limited",
    "reuse_freed_memory",
    "thread_count",
]

THREADS_ENV = "SELFCAL_THREADS"
"""Environment variable with the number of BLAS/OpenMP threads per process."""
DEFAULT_THREADS = 1
"""Threads per process when neither ``--threads`` nor ``SELFCAL_THREADS`` says otherwise."""
THREAD_VARS = (
    "OPENBLAS_NUM_THREADS",
    "OMP_NUM_THREADS",
    "MKL_NUM_THREADS",
    "NUMEXPR_NUM_THREADS",
    "VECLIB_MAXIMUM_THREADS",
)
"""What BLAS and OpenMP libraries read when they load."""

ALLOCATOR_KEEP_BYTES = 1 << 29
"""Arrays up to this size (512 MiB) come from the process's heap, and this much freed memory at
its top stays mapped (:func:`reuse_freed_memory`)."""

_P = ParamSpec("_P")
_R = TypeVar("_R")


def thread_count(threads: int | None = None) -> int:
    """``threads`` if given, else ``$SELFCAL_THREADS``, else :data:`DEFAULT_THREADS`.

    Raises:
        InputError: not a whole number >= 1 (the message names where it came from).
    """
    where, value = "--threads", threads
    if value is None:
        text = os.environ.get(THREADS_ENV, "").strip()
        if not text:
            return DEFAULT_THREADS
        where = THREADS_ENV
        try:
            value = int(text)
        except ValueError:
            raise InputError(
                f"{THREADS_ENV}={text!r} is not a whole number",
                fix=f"set {THREADS_ENV} to the number of BLAS threads per process, e.g. 1",
            ) from None
    if value < 1:
        raise InputError(f"{where} must be at least 1, got {value}")
    return int(value)


def limit_threads(threads: int | None = None) -> int:
    """Limit this process's BLAS and OpenMP thread pools to :func:`thread_count` ``(threads)``
    and export the limit (``SELFCAL_THREADS`` and the libraries' variables) to libraries loaded
    later and to child processes. Returns the limit."""
    n = thread_count(threads)
    os.environ[THREADS_ENV] = str(n)
    for var in THREAD_VARS:
        os.environ[var] = str(n)
    threadpool_limits(limits=n)
    reuse_freed_memory()
    return n


def reuse_freed_memory() -> bool:
    """Let glibc's allocator serve arrays up to :data:`ALLOCATOR_KEEP_BYTES` from the heap and
    keep that much freed memory mapped (``mallopt`` ``M_MMAP_THRESHOLD`` and
    ``M_TRIM_THRESHOLD``), so that the next iteration's arrays reuse the pages the last one
    freed. Its default maps every array above 32 MiB afresh (page faults: the system time that
    made ``calibrate`` grow faster than the postures, issue 32) and returns it when freed. The
    peak resident memory is about the same (the live arrays are); memory freed below the
    largest live block is returned only when the process ends. Returns whether it was applied
    (False where the C library is not glibc: macOS, Windows, musl)."""
    if platform.system() != "Linux" or platform.libc_ver()[0] != "glibc":
        return False
    mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
    if mallopt is None:
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # malloc.h
    return bool(mallopt(m_mmap_threshold, ALLOCATOR_KEEP_BYTES)) and bool(
        mallopt(m_trim_threshold, ALLOCATOR_KEEP_BYTES)
    )


def limited(func: Callable[_P, _R]) -> Callable[_P, _R]:
    """``func`` run with this process's BLAS and OpenMP pools limited to :func:`thread_count`
    (``SELFCAL_THREADS``, else 1) for the length of the call, the caller's limits restored after
    it. The one place a library call gets the command's limit: the public API's computing
    functions are wrapped in it (an unlimited OpenBLAS on a loaded 2-core machine made a
    0.8 s calibration take 18.8 s). scipy's own BLAS is loaded first so that the limit reaches
    it too.

    Raises:
        InputError: ``SELFCAL_THREADS`` is not a whole number >= 1.
    """

    @functools.wraps(func)
    def run(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        import scipy.linalg  # noqa: F401  (its own OpenBLAS, loaded before the limit is set)

        with threadpool_limits(limits=thread_count()):
            return func(*args, **kwargs)

    return run


def helper_threads(jobs: int, cap: int | None = None) -> int:
    """Threads for a pool of ``jobs`` calls that release the GIL (OpenCV's decoding, detection
    and estimators): the cores this process may run on (``os.sched_getaffinity``, else
    ``os.cpu_count``), at most ``cap`` (None: no cap) and ``jobs``; at least 1. The one place
    such pools are sized (the BLAS limit, :func:`thread_count`, does not apply to them)."""
    try:
        cores = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        cores = os.cpu_count() or 1
    n = min(cores, int(jobs), cap if cap is not None else cores)
    return max(1, n)
