"""``selfcal study NAME --budget quick|full --out DIR [--jobs N]``: many calibrations, in parallel.

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
and running it again does only the missing runs. Workers are ``spawn``-ed processes with one BLAS
/ OpenMP thread each.

The parts: ``scenarios.study_runs`` (one run, ``runs.csv``), ``scenarios.study_defs`` (the
studies), ``scenarios.study_summary`` (``<name>.md``, ``<name>.png``); here the driver and the
command.
"""

from __future__ import annotations

import argparse
import csv
import os
import sys
import time
from concurrent.futures import FIRST_COMPLETED, Future, wait
from pathlib import Path

from calib.errors import InputError
from scenarios.parallel import worker_pool
from scenarios.study_defs import STUDIES
from scenarios.study_runs import COLUMNS, load_runs, run_one, settings_key
from scenarios.study_summary import summarize

__all__ = ["run_study", "register"]


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
) -> list[dict]:
    """Run (or resume) study ``name`` into ``out``; returns all its rows (old and new).

    Writes ``out/runs.csv`` (a row per finished run, flushed at once), ``out/<name>.png`` and
    ``out/<name>.md``. ``jobs`` worker processes (default: the CPU count; 1 runs in-process).

    Raises:
        ValueError: unknown study or budget.
    """
    if name == "all":
        rows = []
        for n in STUDIES:
            rows += run_study(n, Path(out) / n, budget=budget, jobs=jobs, quiet=quiet)
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
    fh = open(csv_path, "a", newline="")
    writer = csv.writer(fh)
    if new_file:
        writer.writerow(COLUMNS)
        fh.flush()
    t0 = time.perf_counter()
    try:
        for phase in study.phases:
            done = {r["key"] for r in rows}
            todo = [st for st in phase(budget, rows) if settings_key(st) not in done]
            todo = list({settings_key(st): st for st in todo}.values())
            if not quiet:
                print(
                    f"study {name}: {len(todo)} run(s) to do ({len(done)} done before)",
                    file=sys.stderr,
                )

            def record(row: dict, k: int, n: int) -> None:
                row = {"study": name, "key": settings_key(row), **row}
                writer.writerow([_fmt(row.get(c)) for c in COLUMNS])
                fh.flush()
                rows.append(row)
                if not quiet:
                    msg = (
                        f"cal {row['cal_rms_mm']:.3f} mm, nominal {row['nom_rms_mm']:.3f} mm"
                        if row["status"] == "ok"
                        else row["status"]
                    )
                    print(
                        f"  [{k}/{n}] {row['key']}: {msg} ({row['seconds']:.1f} s)", file=sys.stderr
                    )

            if jobs == 1 or len(todo) <= 1:
                for k, st in enumerate(todo, 1):
                    record(run_one(st), k, len(todo))
            elif todo:
                _run_pool(todo, jobs, record, quiet)
    except KeyboardInterrupt:
        print(
            f"study {name}: interrupted; finished runs are kept in {csv_path}; run the same "
            "command again to resume",
            file=sys.stderr,
        )
        raise
    finally:
        fh.close()
    summarize(name, rows, out)
    if not quiet:
        print(
            f"study {name}: {len(rows)} run(s) in {csv_path}; plot {out / (name + '.png')}; "
            f"{time.perf_counter() - t0:.1f} s",
            file=sys.stderr,
        )
    return rows


def _run_pool(todo: list[dict], jobs: int, record, quiet: bool) -> None:
    with worker_pool(min(jobs, len(todo))) as ex:
        pending: set[Future] = {ex.submit(run_one, st) for st in todo}
        k = 0
        try:
            while pending:
                finished, pending = wait(pending, return_when=FIRST_COMPLETED)
                for f in finished:
                    k += 1
                    record(f.result(), k, len(todo))
        except KeyboardInterrupt:
            for f in pending:
                f.cancel()
            if not quiet:
                print("interrupted: waiting for the running run(s) to finish ...", file=sys.stderr)
            for f in pending:
                if not f.cancelled():
                    try:
                        row = f.result()
                    except Exception:  # noqa: BLE001
                        continue
                    k += 1
                    record(row, k, len(todo))
            raise


# --------------------------------------------------------------------------------------- CLI
def _cmd(args: argparse.Namespace) -> int:
    run_study(args.name, Path(args.out), budget=args.budget, jobs=args.jobs, quiet=args.quiet)
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal study NAME --budget quick|full --out DIR [--jobs N]``."""
    sp = subparsers.add_parser(
        "study",
        help="run many calibrations (seeds x settings) in parallel: CSV + plots",
        description="Run a study of many simulated calibrations in parallel, resumable: "
        "DIR/runs.csv (one row per run), DIR/NAME.png and DIR/NAME.md. Studies: "
        + ", ".join([*STUDIES, "all"])
        + ". See docs/studies.md.",
    )
    sp.add_argument("name", choices=[*STUDIES, "all"], help="which study")
    sp.add_argument(
        "--budget",
        choices=("quick", "full"),
        default="quick",
        help="quick: a handful of runs (seconds); full: minutes",
    )
    sp.add_argument("--out", required=True, help="output folder (resumes what is there)")
    sp.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="worker processes (default: CPU count; 1 = in-process)",
    )
    sp.add_argument("--quiet", action="store_true")
    sp.set_defaults(func=_cmd)
    return sp
