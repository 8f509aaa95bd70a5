"""Studies and Monte Carlo runs on a Dask distributed cluster (``--cluster ADDRESS``).

Each item (a run's settings, a noise draw) is one Dask task submitted to the scheduler at
``ADDRESS`` through ``dask.distributed.Client``; the results stream back in completion order
(``as_completed``) and the caller writes each at once, so an interrupted batch keeps every
finished row. Every task first applies the project's thread limit
(:func:`selfcal.threads.limit_threads`, ``SELFCAL_THREADS`` or 1), so a worker process uses
as many cores as it has Dask threads, not BLAS threads on top. Failures: a task on a worker that
dies is rescheduled by the scheduler (``distributed.scheduler.allowed-failures``, 3 by default);
a task that raises is tried ``retries`` more times; a task that fails on every try becomes an
error row (``error_row``), never a missing one.

Dask is an optional extra (``pip install "scorbot-selfcal[cluster]"``): it is imported only
here, only when a cluster is asked for. How to start a scheduler and workers: docs/cluster.md.
"""

from __future__ import annotations

import argparse
import sys
import uuid
from collections.abc import Callable, Iterator, Sequence
from types import ModuleType

from selfcal.console.progress import TaskCounts
from selfcal.errors import InputError
from selfcal.threads import limit_threads, thread_count

__all__ = [
    "DEFAULT_RETRIES",
    "INSTALL_HINT",
    "add_cluster_args",
    "cluster_tasks",
    "distributed_module",
    "limited_task",
]

INSTALL_HINT = (
    'install the cluster extra: pip install "scorbot-selfcal[cluster]" '
    "(in a checkout: uv sync --extra cluster)"
)
DEFAULT_RETRIES = 2
"""Extra tries of a task that raised (a killed worker's tasks are rescheduled anyway)."""
CONNECT_TIMEOUT = "20s"
"""How long to wait for the scheduler before giving up."""


def add_cluster_args(parser: argparse.ArgumentParser) -> None:
    """``--cluster ADDRESS`` and ``--retries N`` of the commands that run many calibrations."""
    parser.add_argument(
        "--cluster",
        metavar="ADDRESS",
        default=None,
        help="run the calibrations as tasks on the Dask scheduler at ADDRESS (e.g. "
        "tcp://host:8786) instead of local processes; needs the [cluster] extra; see "
        "docs/cluster.md",
    )
    parser.add_argument(
        "--retries",
        type=int,
        default=DEFAULT_RETRIES,
        help=f"with --cluster: extra tries of a task that raised (default {DEFAULT_RETRIES}); "
        "a task failing "
        "every try is recorded as a failed row",
    )


def distributed_module() -> ModuleType:
    """``dask.distributed``, imported now.

    Raises:
        InputError: the ``[cluster]`` extra is not installed (the fix names the command).
    """
    try:
        import distributed  # optional, heavy: only with --cluster
    except ImportError:
        raise InputError(
            "--cluster needs Dask distributed, which is not installed", fix=INSTALL_HINT
        ) from None
    return distributed


def limited_task(fn: Callable[[dict], dict], item: dict, threads: int) -> dict:
    """``fn(item)`` after limiting this worker process to ``threads`` BLAS/OpenMP threads."""
    limit_threads(threads)
    return fn(item)


def cluster_tasks(
    address: str,
    fn: Callable[[dict], dict],
    items: Sequence[dict],
    *,
    error_row: Callable[[dict, BaseException], dict],
    retries: int = DEFAULT_RETRIES,
    threads: int | None = None,
    counts: TaskCounts | None = None,
) -> Iterator[tuple[int, dict]]:
    """``(index, fn(items[index]))`` for every item, computed on the Dask cluster at ``address``
    (e.g. ``tcp://10.0.0.5:8786``), yielded as the results arrive.

    ``fn`` and the items are pickled to the workers, which must have scorbot-selfcal installed
    (the same version). ``threads``: BLAS threads per task (default :func:`thread_count`).
    ``counts.running`` is kept at the number of unfinished tasks the workers' threads can hold.
    Closing the iterator (or Ctrl-C) cancels the unfinished tasks.

    Raises:
        InputError: Dask is not installed, or the scheduler cannot be reached.
    """
    distributed = distributed_module()
    n = thread_count(threads)
    try:
        client = distributed.Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(
            f"cannot reach the Dask scheduler at {address!r}: {exc}",
            fix="start a scheduler and workers (dask scheduler; dask worker ADDRESS), "
            "see docs/cluster.md",
        ) from None
    with client:
        name = getattr(fn, "__name__", "task")
        batch = uuid.uuid4().hex[:8]
        futs = {
            client.submit(
                limited_task, fn, x, n, key=f"{name}-{batch}-{i}", pure=False, retries=retries
            ): i
            for i, x in enumerate(items)
        }
        counts = counts or TaskCounts(len(items))
        slots = sum(client.nthreads().values())
        if slots == 0:
            print(
                f"no Dask worker is connected to {address} yet: the tasks wait for one "
                "(dask worker ADDRESS, docs/cluster.md)",
                file=sys.stderr,
            )
        slots = max(1, slots)
        finished = distributed.as_completed(futs, loop=client.loop)
        try:
            for f in finished:
                i = futs[f]
                counts.running = min(finished.count(), slots)
                if f.status == "finished":
                    row = f.result()
                else:
                    err = f.exception() if f.status == "error" else None
                    row = error_row(items[i], err or RuntimeError(f"task {f.status}"))
                f.release()
                yield i, row
        finally:
            client.cancel([f for f in futs if not f.done()])
