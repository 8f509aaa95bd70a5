"""How many BLAS/OpenMP threads a process of scorbot-selfcal uses (the machines are shared).

One setting: ``selfcal --threads N``, else the environment variable ``SELFCAL_THREADS``, else 1
per process. :func:`limit_threads` applies it to the running process with ``threadpoolctl`` (the
libraries loaded already) and through the usual environment variables (libraries loaded later,
and child processes); the ``selfcal`` entry point and every worker of
:func:`selfcal.studies.parallel.worker_pool` call it. Parallel studies and Monte Carlo runs use the cores
through worker processes, not through BLAS.
"""

from __future__ import annotations

import os

import numpy as np  # noqa: F401  (loads the BLAS that threadpoolctl then limits)
from threadpoolctl import threadpool_limits

from selfcal.errors import InputError

__all__ = ["DEFAULT_THREADS", "THREADS_ENV", "THREAD_VARS", "limit_threads", "thread_count"]

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
    return n
