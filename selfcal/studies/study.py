"""``selfcal study NAME --budget quick|full --out DIR [--jobs N | --cluster ADDRESS]``: many
calibrations, in parallel.

Each run is one simulated calibration (acquire -> calibrate -> report in a temporary folder) of
the default scenario (``scenarios/paper.toml``) with a few settings changed; its result is one row
of ``DIR/runs.csv``. The measure is the held-out validation tool-tip error after rigid alignment
(``report.json``: RMS over 20 validation postures, mm) of the calibrated model, with the nominal
model's error of the same run for contrast.

Studies (x = the swept setting; seeds vary the perturbation, the trajectory and the noise):

- ``noise``: analytic corner noise ``pixel_sigma`` 0 .. 2 px;
- ``poses``: number of calibration poses 6 .. 100 (analytic, 0.25 px);
- ``perturbation``: size of the injected kinematic errors, a factor on (1 mm, 0.5 deg);
- ``observation``: rendered images (several ``image_sigma``) against analytic projections with the
  SAME effective corner noise: each analytic run uses ``pixel_sigma`` = the paired rendered run's
  reprojection RMS / sqrt(2) (same seed, same postures). Runs in two phases.
- ``all``: the four above, each in ``DIR/<name>/``.

Runs are keyed by their complete settings: an interrupted study (Ctrl-C) keeps every finished row,
and running it again does only the missing runs, locally or on a cluster whichever ran the first
part. Workers are ``spawn``-ed processes with one BLAS / OpenMP thread each, or, with
``--cluster ADDRESS``, the workers of a Dask distributed scheduler (``selfcal.studies.cluster``,
docs/cluster.md).

The parts: ``selfcal.studies.runs`` (one run, ``runs.csv``), ``selfcal.studies.defs`` (the
studies), ``selfcal.studies.summary`` (``<name>.md``, ``<name>.png``); here the driver and the
command.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from selfcal.console.common import add_json, note_written
from selfcal.console.log import get_logger
from selfcal.console.progress import Progress
from selfcal.errors import InputError
from selfcal.studies.cluster import DEFAULT_RETRIES

if TYPE_CHECKING:
    pass

__all__ = ["run_study", "register"]

# The runs (calibrations, the simulator) are imported by the functions that use them, so that
# `selfcal --help` builds this command's parser without them.


def run_one(settings: dict) -> dict:
    """One run of a study: :func:`selfcal.studies.runs.run_one` (imported when a study runs)."""
    from selfcal.studies.runs import run_one as run

    return run(settings)


# ------------------------------------------------------------------------------------ driver
def _fmt(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return f"{v:.6g}"
    return str(v)


def run_study(
    name: str,
    out: str | Path,
    *,
    budget: str = "quick",
    jobs: int | None = None,
    quiet: bool = False,
    cluster: str | None = None,
    retries: int = DEFAULT_RETRIES,
    task: Callable[[dict], dict] | None = None,
    seed: int = 1,
) -> list[dict]:
    """Run (or resume) study ``name`` into ``out``; returns all its rows (old and new).

    Writes ``out/runs.csv`` (a row per finished run, flushed at once), ``out/<name>.png`` and
    ``out/<name>.md``. ``jobs`` worker processes (default: the CPU count; 1 runs in-process), or,
    with ``cluster`` (a Dask scheduler address), one Dask task per run (``retries`` extra tries of
    a task that raised; see :mod:`selfcal.studies.cluster`). ``task`` computes one row from a run's
    settings (default :func:`selfcal.studies.runs.run_one`); a task that fails on every try is
    recorded as a ``failed: ...`` row (:func:`selfcal.studies.runs.failed_row`). Resuming works
    the same whichever ran the finished rows: a run whose key is in ``runs.csv`` is not run again.
    ``seed``: the first seed of every setting (its runs take ``seed``, ``seed + 1``, ...: the
    perturbation, trajectory and noise seeds of each run); the same seed gives the same rows.

    Raises:
        InputError: unknown study or budget; no Dask or no scheduler with ``cluster``.
    """
    from selfcal.console.progress import TaskCounts
    from selfcal.studies.defs import STUDIES
    from selfcal.studies.parallel import run_tasks
    from selfcal.studies.row_checks import count_check_failures
    from selfcal.studies.runs import COLUMNS, failed_row, load_runs, settings_key
    from selfcal.studies.summary import plotted, summarize, worse_than_nominal

    if name == "all":
        rows = []
        for n in STUDIES:
            rows += run_study(
                n,
                Path(out) / n,
                budget=budget,
                jobs=jobs,
                quiet=quiet,
                cluster=cluster,
                retries=retries,
                task=task,
                seed=seed,
            )
        return rows
    if name not in STUDIES:
        raise InputError(f"unknown study {name!r}; choose from {', '.join([*STUDIES, 'all'])}")
    if budget not in ("quick", "full"):
        raise InputError(f"budget must be 'quick' or 'full', got {budget!r}")
    study = STUDIES[name]
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    csv_path = out / "runs.csv"
    rows = [r for r in load_runs(csv_path) if r.get("study") == name]
    jobs = max(1, int(jobs or os.cpu_count() or 1))
    new_file = not csv_path.is_file()
    if not new_file:
        _upgrade_columns(csv_path, COLUMNS, load_runs)
    fh = open(csv_path, "a", newline="")
    writer = csv.writer(fh)
    if new_file:
        writer.writerow(COLUMNS)
        fh.flush()
    t0 = time.perf_counter()
    try:
        for phase in study.phases:
            done = {r["key"] for r in rows}
            todo = [st for st in phase(budget, rows, seed) if settings_key(st) not in done]
            todo = list({settings_key(st): st for st in todo}.values())
            where = f"on {cluster}" if cluster else f"{min(jobs, max(1, len(todo)))} process(es)"
            if not quiet:
                print(
                    f"study {name}: {len(todo)} run(s) to do ({len(done)} done before), {where}",
                    file=sys.stderr,
                )
            counts = TaskCounts(len(todo))
            bar = Progress(f"study {name}", enabled=not quiet, counts=counts)
            bar.start(len(todo))
            for _, row in run_tasks(
                task or run_one,
                todo,
                jobs=jobs,
                error_row=failed_row,
                cluster=cluster if todo else None,
                retries=retries,
                counts=counts,
            ):
                row = {"study": name, "key": settings_key(row), **row}
                writer.writerow([_fmt(row.get(c)) for c in COLUMNS])
                fh.flush()
                rows.append(row)
                counts.finish(failed=row["status"] != "ok")
                bar.advance(note=_note(row))
            bar.finish()
    except KeyboardInterrupt:
        print(
            f"study {name}: interrupted; finished runs are kept in {csv_path}; run the same "
            "command again (with or without --cluster) to resume",
            file=sys.stderr,
        )
        raise
    finally:
        fh.close()
    res = summarize(name, rows, out)
    for text in worse_than_nominal(study, res):  # counted in the last line
        get_logger(__name__).warning("study %s: %s", name, text)
    checks = count_check_failures(rows)
    if checks:
        get_logger(__name__).warning(
            "study %s: %d of %d calibration(s) FAILED their reliability checks (runs.csv "
            "columns checks, failed_checks)",
            name,
            checks,
            len(rows),
        )
    if not quiet:
        drawn = f"plot {out / (name + '.png')}" if plotted(res) else "one setting: table only"
        print(
            f"study {name}: {len(rows)} run(s) in {csv_path}, {checks} failed the checks; table "
            f"{out / (name + '.md')}; {drawn}; {time.perf_counter() - t0:.1f} s",
            file=sys.stderr,
        )
    return rows


def _upgrade_columns(csv_path: Path, columns: tuple[str, ...], load_runs) -> None:
    """Rewrite ``csv_path`` with the header ``columns`` when it was written with other columns
    (a study begun before a column was added): its rows keep their values, new cells are empty."""
    with open(csv_path, newline="") as fh:
        header = next(csv.reader(fh), [])
    if tuple(header) == tuple(columns):
        return
    rows = load_runs(csv_path)
    tmp = csv_path.with_suffix(".csv.tmp")
    with open(tmp, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for r in rows:
            w.writerow([_fmt(r.get(c)) for c in columns])
    os.replace(tmp, csv_path)


def _note(row: dict) -> str:
    """One finished run, for the progress display."""
    msg = (
        f"cal {row['cal_rms_mm']:.3f} mm, nominal {row['nom_rms_mm']:.3f} mm"
        if row["status"] == "ok"
        else row["status"]
    )
    if row.get("checks") == "failed":
        msg += ", checks FAILED"
    took = "" if row.get("seconds") is None else f" ({row['seconds']:.1f} s)"
    return f"{row['key']}: {msg}{took}"


# --------------------------------------------------------------------------------------- CLI
def _cmd(args: argparse.Namespace) -> int:
    args.out = args.out or f"runs/study-{args.name}"
    rows = run_study(
        args.name,
        Path(args.out),
        budget=args.budget,
        jobs=args.jobs,
        quiet=args.quiet,
        cluster=args.cluster,
        retries=args.retries,
        seed=1 if args.seed is None else args.seed,
    )
    note_written(args, args.out)
    if args.json:
        from selfcal.studies.row_checks import count_check_failures

        ok = sum(r.get("status") == "ok" for r in rows)
        doc = {"study": args.name, "out": str(args.out), "runs": len(rows), "ok": ok}
        doc["checks_failed"] = count_check_failures(rows)
        print(json.dumps(doc))
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal study NAME --budget quick|full --out DIR [--jobs N | --cluster ADDRESS]``."""
    from selfcal.studies.cluster import add_cluster_args
    from selfcal.studies.defs import STUDIES

    sp = subparsers.add_parser(
        "study",
        help="run many calibrations (seeds x settings) in parallel: CSV + plots",
        description="Run a study of many simulated calibrations in parallel (local worker "
        "processes, or a Dask cluster with --cluster), resumable: "
        "DIR/runs.csv (one row per run), DIR/NAME.png and DIR/NAME.md. Studies: "
        + ", ".join([*STUDIES, "all"])
        + ". See docs/studies.md and docs/cluster.md.",
    )
    sp.add_argument("name", choices=[*STUDIES, "all"], help="which study")
    sp.add_argument(
        "--budget",
        choices=("quick", "full"),
        default="quick",
        help="quick: a handful of runs (seconds); full: minutes",
    )
    sp.add_argument(
        "--out",
        default=None,
        help="output folder, resumes what is there (default runs/study-NAME)",
    )
    sp.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="worker processes (default: CPU count; 1 = in-process; not with --cluster)",
    )
    sp.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="S",
        help="first seed of every setting (default 1): its runs take seeds S, S+1, ..., each "
        "overriding the scenario's [perturbation], [trajectory] and [noise] seeds (the marker "
        "field and the validation postures stay the scenario's); the same S gives the same rows. "
        "Rows already in --out (other seeds too) are kept and pooled in the summary: give "
        "another --out for a separate set",
    )
    add_cluster_args(sp)
    add_json(sp)
    sp.set_defaults(func=_cmd)
    return sp
