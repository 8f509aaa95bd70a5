"""Benchmark: false alarms, power and attribution of ``selfcal check`` on images (issue #29).

Per pixel noise level: ``--calibrations`` simulated board calibrations (the analytic board
scenario ``scenarios/mono-charuco.toml``: the ER-4u of the paper with every minimal parameter
perturbed, one wrist camera with a Brown-Conrady lens, a ChArUco board on the table, 30
postures, joints read back at the robot file's encoder resolution as the simulated
acquisition reads them; calibrated as ``selfcal run`` does, seeded by the draw), each checked
``--checks`` times with 5 new views at new postures (a calibration posture moved by up to 10
deg per joint, kept when the board is in view), the corners projected through the true chain
and camera at that posture with the same pixel noise, the joints as the controller reads them
back (:func:`selfcal.benchmarks.drift.image_checks.read_joints`: rounded to the encoder count, the noise the check assumes from the
same robot file, :func:`selfcal.estimation.joint_report.encoder_sigma`): unchanged, the camera moved on its mount by
0.2 mm (a random direction: the hand-eye's translation changed) and one joint (drawn at random)
offset by 0.05 deg. Reported: the share of checks that say "changed"
(:func:`selfcal.calibration.drift.images.image_drift_check`, alpha = 0.01; the issue's target:
below 2 % unchanged, at least 95 % changed) and, of the changed ones found, the share whose
cause is named right (the hand-eye; the joint) and wrong (the rest: cause not named). Beside the
mount shift's share, what a test that knew more would find, the mean over the checks of its
power (:func:`selfcal.calibration.drift.p_value.known_change_power`) from the noncentrality
``mu^T Sigma^-1 mu`` of the shift's linearised pixels ``mu`` under the check's own covariance
``Sigma`` (the calibration's uncertainty, the assumed joint and corner noise): the oracle that
knew the shift's direction (no test does better), one that knew its size and that the mount
moved without turning but not the direction (:func:`selfcal.calibration.drift.p_value.
known_size_power`: the likelihood ratio averaged over the directions, the largest mean power a
test of the benchmark's random 0.2 mm shifts can have without being told the direction) and one
that knew only that the mount moved without turning (the chi-square of its 3 translations alone,
at the whole alpha). The log line of each row also gives the check's own power against the
shift as ``selfcal check`` states it (:func:`selfcal.calibration.drift.power.shift_power`,
averaged over the checks) beside the share it found. ``--choose POOL``: each check's new views
are the ones of POOL postures drawn so that, one by one, each raises that power most
(:func:`selfcal.calibration.drift.choose.chosen_views`, what ``selfcal plan --check`` chooses
by), not the first drawn. Each row also
counts the checks per kind that answered "cannot tell" (the verdict, exit 6: not counted as
changed) and records the code that measured it (:func:`selfcal.benchmarks.doc_blocks.
code_version`), which the table's last line names (:func:`selfcal.benchmarks.doc_blocks.
codes_note`).

``--setup eye-to-hand``: the same on ``scenarios/eye-to-hand.toml`` (a static camera, the board
on a UR5e's flange; the mount shift moves the board on the flange, analytic path).
``--robot``: the eye-in-hand rows on these robots' files instead of the ER-4u's (the same
scenario, as :mod:`selfcal.benchmarks.board.accuracy` runs it on them), each with its own
encoder read-back (e.g. the UR5e's 0.0007 deg per count; the KR 6's file states none: its
joints are read and taken as exact).

Run: ``nice -n 10 uv run python -m selfcal.benchmarks.drift.images [--calibrations 30]
[--checks 10] [--setup eye-in-hand eye-to-hand] [--robot er4u-paper ur5e kr6-r900] [--jobs 1]
[--views 5] [--min-p] [--choose POOL] [--journal FILE] [--write-docs]`` (rewrites the rows of the setups, robots and noise levels it ran
in the table of docs/tool-accuracy.md and keeps the others, :func:`selfcal.benchmarks.drift.image_table.docs_rows`).
One calibration's checks: :mod:`selfcal.benchmarks.drift.image_checks`; the table:
:mod:`selfcal.benchmarks.drift.image_table`.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from pathlib import Path

from selfcal.benchmarks.doc_blocks import code_version, print_table
from selfcal.benchmarks.drift.image_checks import (
    KINDS,
    NEW_VIEWS,
    NOISE_PX,
    SCENARIOS,
    calibration_checks,
)
from selfcal.benchmarks.drift.image_table import BLOCK, DOC, docs_rows, table
from selfcal.benchmarks.pool import imap_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.config.scenario import load_scenario
from selfcal.studies.montecarlo.journal import DrawJournal, draw_key
from selfcal.threads import limit_threads

__all__ = ["journaled_checks", "main", "run"]


def journaled_checks(todo: list[tuple], jobs: int, code: str | None, journal: Path | None,
                     measure: Callable[[tuple], dict] | None = None) -> list[dict]:  # fmt: skip
    """``measure`` (default
    :func:`~selfcal.benchmarks.drift.image_checks.calibration_checks`; another's items are keyed by its name
    too) of each item of ``todo`` (``jobs`` processes), each result
    appended to ``journal`` (a JSON line, :class:`selfcal.studies.montecarlo.journal.
    DrawJournal`) the moment it is done and taken from there when a run before made it: an
    interrupted run loses no finished calibration. The key is the item and ``code`` (the code
    that measures, :func:`code_version`): a journal's results of other code are not reused,
    and none of code with uncommitted changes (``+changes``: which changes is not recorded).
    Prints each calibration's time as it finishes (stderr), from which a run's end can be told."""
    book = DrawJournal(journal) if journal is not None else None
    reuse = book is not None and code is not None and not code.endswith("+changes")
    fn = calibration_checks if measure is None else measure
    what = {} if measure is None else {"measure": fn.__qualname__}
    keys = [draw_key({"checks": list(item), "code": code} | what) for item in todo]
    done = book.load() if book is not None and reuse else {}
    out = {k: done[k] for k in keys if k in done}
    left = [(k, item) for k, item in zip(keys, todo, strict=True) if k not in out]
    if out:
        print(f"  {len(out)} of {len(todo)} calibrations from {journal}", file=sys.stderr)
    t0 = time.perf_counter()
    for n, ((key, item), got) in enumerate(
        zip(left, imap_jobs(fn, [i for _, i in left], jobs), strict=True), 1
    ):
        out[key] = got
        if book is not None and got["status"] == "ok":
            book.append(key, got)
        print(f"  seed {item[1]}: {n} of {len(left)} in {time.perf_counter() - t0:.0f} s "
              f"({got['status']})", file=sys.stderr)  # fmt: skip
    return [out[k] for k in keys]


def run(calibrations: int = 30, checks: int = 10, noise_px=NOISE_PX, jobs: int = 1,
        setups: tuple[str, ...] = tuple(SCENARIOS), robots: tuple[str, ...] | None = None,
        views: int = NEW_VIEWS, exact: bool = False, choose: int = 0,
        journal: Path | None = None) -> list[dict]:  # fmt: skip
    """One row per setup (eye-in-hand: per robot of ``robots``, default the scenario's) and
    noise level over ``calibrations`` calibrations (``jobs`` processes), ``views`` new views
    per check (``exact``, ``choose``:
    :func:`~selfcal.benchmarks.drift.image_checks.calibration_checks`; each calibration's counts
    kept in ``journal``: :func:`journaled_checks`)."""
    rows, code = [], code_version()
    cells = [(u, r) for u in setups
             for r in (robots if robots and u == "eye-in-hand" else (None,))]  # fmt: skip
    for (setup, robot), s in ((c, s) for c in cells for s in noise_px):
        t0 = time.perf_counter()
        name = robot or load_scenario(SCENARIOS[setup]).robot.model
        label = f"{setup}, {name}"
        todo = [(s, seed, checks, setup, robot, views, exact, choose)
                for seed in range(1, calibrations + 1)]  # fmt: skip
        got = journaled_checks(todo, jobs, code, journal)
        ok = [g for g in got if g["status"] == "ok"]
        print(f"{label} {s} px: {len(ok)}/{calibrations} calibrations in {time.perf_counter() - t0:.0f} s "
              + "; ".join(sorted({g['status'] for g in got} - {'ok'})), file=sys.stderr)  # fmt: skip
        total = {k: sum(g[k] for g in ok) for k in ok[0] if k != "status"} if ok else {}
        print(f"  the folds' error at left-out configurations counted in {total.get('fold_error', 0)} "
              f"calibrations; 'cannot tell' (not counted as changed): "
              + ", ".join(f"{k} {total.get(f'{k}_cannot_tell', 0)}" for k in KINDS), file=sys.stderr)  # fmt: skip
        m = max(total.get("checks", 0), 1)
        print(f"  the check's own power against the mount shift (selfcal check's power line): "
              f"{100 * total.get('tool_power', 0) / m:.1f} % on average; found "
              f"{100 * total.get('tool', 0) / m:.1f} %", file=sys.stderr)  # fmt: skip
        row = {"setup": label, "noise_px": s, "calibrations": len(ok), "failed": calibrations - len(ok),
               "checks": total.get("checks", 0), "views": views, "exact": exact, "code": code,
               "choose": choose}  # fmt: skip
        row |= {k: total.get(k, 0) / m
                for k in (*KINDS, "tool_oracle", "tool_size", "tool_axes", "tool_power")}  # fmt: skip
        row |= {f"{k}_cannot_tell": total.get(f"{k}_cannot_tell", 0) for k in KINDS}
        for k in ("tool", "joint"):
            found = max(total.get(k, 0), 1)
            row[f"{k}_right"] = total.get(f"{k}_right", 0) / found
            row[f"{k}_wrong"] = total.get(f"{k}_wrong", 0) / found
        rows.append(row)
    return rows


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread per process) and print, or write, the table."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--calibrations", type=int, default=30, help="per noise level (default 30)")
    ap.add_argument("--checks", type=int, default=10, help="per calibration (default 10)")
    ap.add_argument("--noise-px", type=float, nargs="+", default=list(NOISE_PX),
                    help="pixel noise levels (default 0.05 0.2)")  # fmt: skip
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--views", type=int, default=NEW_VIEWS,
                    help=f"new views per check (default {NEW_VIEWS}, the docs block's)")  # fmt: skip
    ap.add_argument("--min-p", action="store_true",
                    help="combine the check's tests by their smallest p-value's exact "
                    "distribution, not Bonferroni's bound (not the docs block's)")  # fmt: skip
    ap.add_argument("--choose", type=int, default=0, metavar="POOL",
                    help="choose each check's new views from POOL postures by the check's own "
                    "power (not the docs block's)")  # fmt: skip
    ap.add_argument("--journal", type=Path, default=None, metavar="FILE",
                    help="append each calibration's counts to FILE (JSON lines) as it finishes "
                    "and take those of the same settings and committed code from it: a run "
                    "stopped and started again redoes no finished calibration")  # fmt: skip
    ap.add_argument("--setup", nargs="+", default=list(SCENARIOS), choices=tuple(SCENARIOS),
                    help="camera setups (default both)")  # fmt: skip
    ap.add_argument(
        "--robot",
        nargs="+",
        default=None,
        metavar="ROBOT",
        help="the eye-in-hand rows on these robots (default the scenario's ER-4u)",
    )
    ap.add_argument("--write-docs", action="store_true",
                    help="rewrite the rows of the setups, robots and noise levels run in the "
                    "table of docs/tool-accuracy.md (the others kept)")  # fmt: skip
    args = ap.parse_args(argv)
    if args.write_docs and (args.views != NEW_VIEWS or args.min_p or args.choose):
        ap.error(f"--write-docs writes the table of the check as it is, {NEW_VIEWS} views: "
                 "leave out --views, --min-p and --choose, or --write-docs")  # fmt: skip
    if args.choose and args.choose < args.views:
        ap.error(f"--choose {args.choose}: the pool must hold at least --views {args.views}")
    rows = run(args.calibrations, args.checks, tuple(args.noise_px), args.jobs, tuple(args.setup),
               tuple(args.robot) if args.robot else None, args.views, args.min_p,
               args.choose, args.journal)  # fmt: skip
    if args.write_docs:
        rows = docs_rows(rows, args.calibrations, args.checks)
    return print_table(table(rows, args.checks), DOC, BLOCK, write=args.write_docs)


if __name__ == "__main__":
    sys.exit(main())
