"""BLAS/OpenMP threads are limited in one place (selfcal/threads.py): the CLI and every worker."""

from __future__ import annotations

import os

import pytest
from threadpoolctl import threadpool_info

from selfcal.cli.main import main
from selfcal.errors import InputError
from selfcal.studies.parallel import worker_pool
from selfcal.threads import THREAD_VARS, THREADS_ENV, thread_count


def _pools_after_scipy() -> list[dict]:
    """The worker's thread pools once numpy's and scipy's BLAS are both loaded."""
    import scipy.linalg  # noqa: F401  (its own OpenBLAS loads here, after the limit)

    return threadpool_info()


@pytest.mark.parametrize("threads", [1, 2])
def test_a_worker_pool_process_has_the_limit(threads):
    with worker_pool(1, threads=threads) as ex:
        pools = ex.submit(_pools_after_scipy).result(timeout=120)
        env = ex.submit(os.getenv, "OPENBLAS_NUM_THREADS").result(timeout=60)
    blas = [p for p in pools if p["user_api"] == "blas"]
    assert blas, pools  # numpy's (and scipy's) OpenBLAS are seen
    assert all(p["num_threads"] == threads for p in pools), pools
    assert env == str(threads)


def test_the_environment_variable_sets_the_default(monkeypatch):
    monkeypatch.setenv(THREADS_ENV, "3")
    assert thread_count() == 3 and thread_count(2) == 2
    monkeypatch.setenv(THREADS_ENV, "many")
    with pytest.raises(InputError, match=THREADS_ENV):
        thread_count()
    monkeypatch.delenv(THREADS_ENV)
    assert thread_count() == 1
    with pytest.raises(InputError, match="--threads must be at least 1"):
        thread_count(0)


def test_the_cli_limits_its_own_process(monkeypatch, capsys):
    """(The test process keeps the one thread afterwards, as every ``selfcal`` process does.)"""
    for var in (THREADS_ENV, *THREAD_VARS):
        monkeypatch.setenv(var, "7")  # monkeypatch restores them afterwards
    assert main(["--threads", "1", "fk", "--joints", "0,0,0,0,0"]) == 0
    assert all(p["num_threads"] == 1 for p in threadpool_info())
    assert os.environ[THREADS_ENV] == os.environ["OPENBLAS_NUM_THREADS"] == "1"
    assert main(["--threads", "0", "fk", "--joints", "0,0,0,0,0"]) == 2  # bad input
    assert "--threads must be at least 1" in capsys.readouterr().err


def test_helper_threads_follow_the_cores_this_process_may_use(monkeypatch):
    """A pool of GIL-releasing calls gets the cores of the process's CPU affinity (not the
    machine's count), at most the cap and the jobs, and at least one thread."""
    import os

    from selfcal.threads import helper_threads

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1, 2}, raising=False)
    monkeypatch.setattr(os, "cpu_count", lambda: 64)
    assert helper_threads(100) == 3
    assert helper_threads(100, cap=2) == 2
    assert helper_threads(1) == 1
    assert helper_threads(0) == 1
