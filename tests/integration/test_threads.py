"""BLAS/OpenMP threads are limited in one place (selfcal/threads.py): the CLI and every worker."""

from __future__ import annotations

import os
import platform
import subprocess
import sys

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


_FAULTS = """
import sys
import numpy as np
from selfcal.threads import reuse_freed_memory

def faults():
    return int(open("/proc/self/stat").read().rsplit(")", 1)[1].split()[7])  # minflt

applied = reuse_freed_memory() if sys.argv[1] == "1" else False
a = np.ones(64 * 2**20 // 8); del a  # 64 MiB: above glibc's largest dynamic mmap threshold
f0 = faults()
b = np.ones(64 * 2**20 // 8); del b
print(applied, faults() - f0)
"""


@pytest.mark.skipif(
    not (sys.platform.startswith("linux") and platform.libc_ver()[0] == "glibc"),
    reason="glibc's mallopt",
)
def test_a_freed_large_array_s_pages_are_reused():
    """64 MiB is 16384 pages of 4 kB (8192 at 8 kB): glibc maps it afresh after a free unless
    reuse_freed_memory applied (then its pages are the freed array's: a few faults)."""
    got = {}
    for on in ("0", "1"):
        out = subprocess.run([sys.executable, "-c", _FAULTS, on], capture_output=True, text=True,
                             check=True).stdout.split()  # fmt: skip
        got[on] = (out[0] == "True", int(out[1]))
    assert got["1"][0] and not got["0"][0]
    assert got["0"][1] > 30  # huge pages may make it 32 faults of 2 MiB
    assert got["1"][1] < 10, got
