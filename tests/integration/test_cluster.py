"""``--cluster ADDRESS``: studies and Monte Carlo runs as tasks on a Dask distributed cluster.

Claims: the optional extra is imported only with ``--cluster`` and its absence is an InputError
naming the install command; a task that raises on every try becomes a ``failed: ...`` row (none
dropped); and (slow tier, a ``LocalCluster`` of 2 worker processes) a study half done by the local
pool and finished on the cluster, with one worker killed in the middle of a run, has every row
once and the cluster's rows equal the local pool's bit for bit (all but the wall time
``seconds``); the workers run with the project's thread limit; Monte Carlo draws are the same
numbers on the cluster as in the local pool, and a Monte Carlo interrupted on the cluster,
resumed in the local pool, interrupted again and finished on the cluster has every draw once,
none recomputed once written, equal to an uninterrupted local run.
"""

from __future__ import annotations

import csv
import functools
import json
import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import cloudpickle
import pytest
from threadpoolctl import threadpool_info

from selfcal.cli.main import main
from selfcal.errors import InputError
from selfcal.studies.cluster import cluster_tasks
from selfcal.studies.montecarlo.journal import JOURNAL, DrawJournal
from selfcal.studies.montecarlo.run import draw_one, run_montecarlo
from selfcal.studies.runs import failed_row, run_one, settings_key
from selfcal.studies.study import run_study

# The tasks below run on the workers, which cannot import this test module: send them by value.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


def _always_fails(calls: Path, settings: dict) -> dict:
    with open(calls, "a") as fh:
        fh.write(settings_key(settings) + "\n")
    raise RuntimeError("this run always fails")


def _kill_first(marker: Path, settings: dict) -> dict:
    """The first task to get here kills its own worker process mid-run; every other one runs."""
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return run_one(settings)
    os.write(fd, settings_key(settings).encode())
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)
    raise AssertionError("unreachable")


def _pools(_: dict) -> dict:
    import scipy.linalg  # noqa: F401  (its own OpenBLAS loads here, after the limit)

    return {"pools": threadpool_info(), "env": os.environ.get("OPENBLAS_NUM_THREADS")}


def _without_seconds(row: dict) -> dict:
    return {k: v for k, v in row.items() if k != "seconds"}


# ---------------------------------------------------------------------------- default tier
def test_the_local_path_imports_no_dask():
    code = "import sys, selfcal.cli.main; print(sorted(m for m in ('dask', 'distributed') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_without_the_extra_cluster_is_an_input_error(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(InputError) as err:
        run_study("noise", tmp_path, cluster="tcp://127.0.0.1:1", quiet=True)
    assert "scorbot-selfcal[cluster]" in err.value.fix
    code = main(["montecarlo", "--draws", "2", "--out", str(tmp_path), "--cluster", "tcp://x:1"])
    assert code == 2  # bad input
    assert "uv sync --extra cluster" in capsys.readouterr().err


def test_a_task_failing_on_every_try_is_recorded(tmp_path, capsys):
    from distributed import LocalCluster  # here, not at the top: the collection of every test
    # process paid dask's and tornado's import (0.35 CPU s) for the one default test using it

    calls = tmp_path / "calls.txt"
    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False) as lc:
        rows = run_study(
            "noise",
            tmp_path / "out",
            cluster=lc.scheduler_address,
            retries=1,
            task=functools.partial(_always_fails, calls),
        )
    # progress per row: done / total, running (the worker's 2 threads), failed, time left
    progress = re.findall(
        r"\[(\d+)/6 done, (\d) running, (\d) failed, ~\d+ s left\]", capsys.readouterr().err
    )
    assert [(int(d), int(f)) for d, _, f in progress] == [(k, k) for k in range(1, 7)]
    assert progress[0][1] == "2" and progress[-1][1] == "0"
    assert len(rows) == 6  # the quick noise study: 3 sigmas x 2 seeds
    assert all(r["status"] == "failed: RuntimeError: this run always fails" for r in rows), rows
    tried = calls.read_text().split("\n")[:-1]
    assert sorted(tried) == sorted(2 * [r["key"] for r in rows])  # 1 try + 1 retry each
    with open(tmp_path / "out" / "runs.csv", newline="") as fh:
        on_disk = list(csv.DictReader(fh))
    assert [r["status"] for r in on_disk] == [r["status"] for r in rows]


def test_the_failed_row_keeps_the_settings():
    st = {"render": False, "pixel_sigma": 0.5, "image_sigma": 2.0, "poses": 8}
    row = failed_row({**st, "perturb_scale": 1.0, "seed": 3}, MemoryError("out of memory"))
    assert row["status"] == "failed: MemoryError: out of memory"
    assert row["seed"] == 3 and row["seconds"] is None


# ------------------------------------------------------------------------------- slow tier
@pytest.fixture(scope="module")
def cluster():
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as lc:
        yield lc.scheduler_address


@pytest.fixture(scope="module")
def local_study(tmp_path_factory):
    out = tmp_path_factory.mktemp("local")
    return out, run_study("noise", out, jobs=2, quiet=True)


@pytest.mark.slow
def test_a_study_resumed_on_the_cluster_with_a_killed_worker_equals_the_local_one(
    cluster, local_study, tmp_path
):
    local_out, local_rows = local_study
    assert len(local_rows) == 6 and all(r["status"] == "ok" for r in local_rows)
    lines = (local_out / "runs.csv").read_text().splitlines(keepends=True)
    out = tmp_path / "study"
    out.mkdir()
    (out / "runs.csv").write_text("".join(lines[:4]))  # the header and 3 runs done locally
    marker = tmp_path / "killed"
    rows = run_study(
        "noise", out, cluster=cluster, task=functools.partial(_kill_first, marker), quiet=True
    )
    killed = marker.read_text()
    assert killed in {r["key"] for r in rows[3:]}  # one of the cluster's runs died once
    assert len(rows) == 6 and all(r["status"] == "ok" for r in rows), rows
    by_key = {r["key"]: _without_seconds(r) for r in local_rows}
    for r in rows[3:]:  # computed on the cluster: bit-identical to the local pool's
        assert _without_seconds(r) == by_key[r["key"]]
    got = sorted((out / "runs.csv").read_text().splitlines())
    want = sorted(lines_ := [ln.rstrip("\n") for ln in lines])
    assert len(got) == len(want) == 7  # header + 6 runs, none twice

    def strip(text: list[str]) -> list[dict]:  # every column but the wall time
        return sorted((_without_seconds(r) for r in csv.DictReader(text)), key=lambda r: r["key"])

    assert strip((out / "runs.csv").read_text().splitlines()) == strip(lines_)


@pytest.mark.slow
def test_cluster_workers_have_the_thread_limit(cluster):
    res = [r for _, r in cluster_tasks(cluster, _pools, [{}, {}], error_row=failed_row)]
    for r in res:
        assert r["env"] == "1"
        assert r["pools"] and all(p["num_threads"] == 1 for p in r["pools"]), r["pools"]


MC = {"poses": 12, "first_seed": 5, "quiet": True}


@pytest.fixture(scope="module")
def local_draws(paper_montecarlo_12):
    # The local pool (one BLAS thread per process, as on the cluster); this test process may
    # have several BLAS threads, whose sums round differently (~1e-8 relative). Draws 5-7 of the
    # paper's Monte Carlo of 12 postures, computed once per test run (tests/conftest.py; the
    # bound's test takes all 8): the draws of MC, each a function of its settings alone.
    rows = paper_montecarlo_12[0][MC["first_seed"] - 1 : MC["first_seed"] + 2]
    assert [r["seed"] for r in rows] == [5, 6, 7] and all(r["poses"] == MC["poses"] for r in rows)
    assert all(r["status"] == "ok" for r in rows), rows
    return rows


@pytest.mark.slow
def test_monte_carlo_draws_are_the_same_on_the_cluster(cluster, local_draws):
    there, _ = run_montecarlo(2, cluster=cluster, **MC)
    assert [_without_seconds(r) for r in there] == [_without_seconds(r) for r in local_draws[:2]]


def _logged_draw(calls: Path, settings: dict) -> dict:
    with open(calls, "a") as fh:
        fh.write(f"{settings['seed']}\n")
    return draw_one(settings)


@pytest.mark.slow
def test_monte_carlo_interrupted_on_the_cluster_resumes_locally_and_back(
    cluster, local_draws, tmp_path, monkeypatch
):
    """Ctrl-C once a draw is written (on the cluster, then in the local pool), then the same
    command to the end on the cluster: every draw once in the journal, none computed again once
    written, and the rows those of an uninterrupted local run bit for bit."""
    out = tmp_path / "mc"
    appended = []
    append = DrawJournal.append

    def interrupt_after(n: int):
        def hook(self, key, row):
            append(self, key, row)
            appended.append(row["seed"])
            if len(appended) == n:
                raise KeyboardInterrupt

        monkeypatch.setattr(DrawJournal, "append", hook)

    def calls(phase: str) -> list[int]:
        p = tmp_path / phase
        return [int(s) for s in p.read_text().split()] if p.exists() else []

    interrupt_after(1)
    task = functools.partial(_logged_draw, tmp_path / "cluster1")
    with pytest.raises(KeyboardInterrupt):
        run_montecarlo(3, out, cluster=cluster, task=task, **MC)
    interrupt_after(2)
    task = functools.partial(_logged_draw, tmp_path / "local")
    with pytest.raises(KeyboardInterrupt):
        run_montecarlo(3, out, jobs=2, task=task, **MC)
    monkeypatch.setattr(DrawJournal, "append", append)
    task = functools.partial(_logged_draw, tmp_path / "cluster2")
    rows, _ = run_montecarlo(3, out, cluster=cluster, task=task, **MC)
    first, second = appended
    assert first not in calls("local") + calls("cluster2")
    assert second not in calls("cluster2") and second != first
    lines = (out / JOURNAL).read_text().splitlines()
    assert sorted(json.loads(ln)["row"]["seed"] for ln in lines) == [5, 6, 7]
    assert [_without_seconds(r) for r in rows] == [_without_seconds(r) for r in local_draws]
