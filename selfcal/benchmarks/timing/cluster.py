"""Benchmark: the same 40-run study in this process, in the local pool of 2 worker processes, and
on a Dask ``LocalCluster`` of 1 and 2 worker processes (``--cluster``, :mod:`selfcal.studies.cluster`).

The study: ``--runs`` calibrations (default 40) of the default scenario on the analytic path,
``--poses`` postures (default 8), 0.5 px corner noise, seeds 1 .. runs -- each a task of
:func:`selfcal.studies.runs.run_one` through :func:`selfcal.studies.parallel.run_tasks`, the path of
``selfcal study``. Per configuration: wall time from the first submission to the last row (the
cluster is started before the clock, its start-up time is reported apart; the pool's process
start is inside; every configuration runs twice, in order and back, and the means are shown), the speed-up from 1 to 2 processes, the cluster's overhead per task against
the local path with as many processes, ``(wall_cluster - wall_local) x workers / runs``, and the
worker time not spent computing per task, ``(wall x workers - sum of the tasks' own seconds) /
runs`` (dispatch, pickling, imports in a fresh worker, the idle tail), and the CPU seconds per
task of the process that ran it (all its threads: a Dask worker's own threads count), which a
shared machine's load does not inflate the way it inflates wall times. It checks that every configuration
gives the same rows (all but ``seconds``) and reports the load average (the machine may be shared).

Run: ``uv run python -m selfcal.benchmarks.timing.cluster [--runs 40] [--poses 8] [--write-doc]``
(``--write-doc`` replaces the table in docs/cluster.md). Needs the ``[cluster]`` extra.
"""

from __future__ import annotations

import os
import platform
import time
from pathlib import Path

from selfcal.benchmarks.usage import benchmark_parser
from selfcal.io.atomic import write_text_atomic
from selfcal.studies.cluster import distributed_module
from selfcal.studies.defs import BASE
from selfcal.studies.parallel import run_tasks
from selfcal.studies.runs import failed_row, run_one
from selfcal.threads import limit_threads

DOC = Path(__file__).resolve().parents[3] / "docs" / "cluster.md"
VOLATILE = ("seconds", "cpu_s")
"""Row keys that measure this machine (wall and CPU time), not the calibration."""
BEGIN, END = "<!-- benchmark_cluster:begin -->", "<!-- benchmark_cluster:end -->"


def cpu_timed(settings: dict) -> dict:
    """:func:`run_one` with ``cpu_s``: the CPU seconds its process spent meanwhile (every thread,
    so a Dask worker's own threads count too)."""
    c0 = time.process_time()
    row = run_one(settings)
    row["cpu_s"] = time.process_time() - c0
    return row


def _time(items: list[dict], **where) -> tuple[float, list[dict]]:
    t0 = time.perf_counter()
    got = dict(run_tasks(cpu_timed, items, error_row=failed_row, **where))
    return time.perf_counter() - t0, [got[i] for i in range(len(items))]


def run(runs: int, poses: int) -> str:
    """The markdown table (and a few lines around it) of one benchmark."""
    distributed = distributed_module()
    items = [{**BASE, "pixel_sigma": 0.5, "poses": poses, "seed": s} for s in range(1, runs + 1)]
    results = []  # label, workers, mean wall, start-up, rows, min/max load, busy, CPU per task
    configs: list[tuple[str, int, dict]] = [
        ("in-process (jobs 1)", 1, {"jobs": 1}),
        ("local pool, 2 processes (jobs 2)", 2, {"jobs": 2}),
        ("LocalCluster, 1 worker process", 1, {}),
        ("LocalCluster, 2 worker processes", 2, {}),
    ]
    timed: dict[int, list] = {k: [] for k in range(len(configs))}
    order = list(range(len(configs)))
    for k in order + order[::-1]:  # there and back: a drifting load weighs on every one alike
        label, workers, where = configs[k]
        load0 = os.getloadavg()[0]
        if where:
            wall, rows = _time(items, **where)
            start = 0.0
        else:
            t0 = time.perf_counter()
            with distributed.LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
            ) as lc:
                start = time.perf_counter() - t0
                wall, rows = _time(items, jobs=workers, cluster=lc.scheduler_address)
        timed[k].append((wall, start, rows, load0, os.getloadavg()[0]))
        print(f"{label}: {wall:.1f} s", flush=True)
    for k, (label, workers, where) in enumerate(configs):
        t = timed[k]
        rows = [r for x in t for r in x[2]]  # both passes: their seconds are summed below
        results.append(
            (
                label,
                workers,
                sum(x[0] for x in t) / len(t),
                None if where else sum(x[1] for x in t) / len(t),
                rows[:runs],
                min(x[3] for x in t),
                max(x[4] for x in t),
                sum(r["seconds"] or 0.0 for r in rows) / len(t),
                sum(r.get("cpu_s") or 0.0 for r in rows) / len(t) / runs,
            )
        )
    ref = [{k: v for k, v in r.items() if k not in VOLATILE} for r in results[0][4]]
    same = all(
        [{k: v for k, v in r.items() if k not in VOLATILE} for r in x[2]] == ref
        for t in timed.values()
        for x in t
    )
    ok = sum(r["status"] == "ok" for r in results[0][4])
    lines = [
        f"{runs} runs (`run_one`: {poses} poses, 0.5 px, seeds 1..{runs}; {ok} ok), "
        f"{os.cpu_count()} cores, Python {platform.python_version()}, "
        f"dask distributed {distributed.__version__}; rows identical in every configuration "
        f"(all but `seconds`): {'yes' if same else 'NO'}. Local with 1 process is in-process "
        "(`--jobs 1`). Each configuration ran twice (in the order of the table, then back) and "
        "the times are the means.",
        "",
        "| configuration | wall s | speed-up 1 -> 2 | cluster - local, s / task | worker time "
        "not computing, s / task | CPU s / task | start-up s | load (1-min average) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for k, (label, workers, wall, start_s, _, l0, l1, busy, cpu) in enumerate(results):
        idle = (wall * workers - busy) / runs
        speed = "" if workers == 1 else f"{results[k - 1][2] / wall:.2f}"
        extra = "" if start_s is None else f"{(wall - results[k - 2][2]) * workers / runs:+.2f}"
        st = "" if start_s is None else f"{start_s:.1f}"
        lines.append(
            f"| {label} | {wall:.1f} | {speed} | {extra} | {idle:.2f} | {cpu:.2f} | {st} | {l0:.1f} .. {l1:.1f} |"
        )
    return "\n".join(lines) + "\n"


def write_doc(table: str, doc: Path = DOC) -> None:
    """Replace the text between the benchmark markers of ``doc`` with ``table``."""
    text = doc.read_text()
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    write_text_atomic(doc, f"{head}{BEGIN}\n{table}{END}{tail}")


def main(argv: list[str] | None = None) -> None:
    ap = benchmark_parser(__file__, description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--poses", type=int, default=8)
    ap.add_argument("--write-doc", action="store_true", help=f"update the table in {DOC.name}")
    args = ap.parse_args(argv)
    limit_threads()  # in-process runs with the workers' thread limit, as `selfcal` does
    table = run(args.runs, args.poses)
    print(table)
    if args.write_doc:
        write_doc(table)


if __name__ == "__main__":
    main()
