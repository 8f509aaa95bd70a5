"""Benchmark: false alarms, power and attribution of ``selfcal check`` on images (issue #29).

Per pixel noise level: ``--calibrations`` simulated board calibrations (the analytic board
scenario ``scenarios/mono-charuco.toml``: the ER-4u of the paper with every minimal parameter
perturbed, one wrist camera with a Brown-Conrady lens, a ChArUco board on the table, 30
postures, joints read back at the robot file's encoder resolution as the simulated
acquisition reads them; calibrated as ``selfcal run`` does, seeded by the draw), each checked
``--checks`` times with 5 new views at new postures (a calibration posture moved by up to 10
deg per joint, kept when the board is in view), the corners projected through the true chain
and camera at that posture with the same pixel noise, the joints as the controller reads them
back (:func:`read_joints`: rounded to the encoder count, the noise the check assumes from the
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
in the table of docs/tool-accuracy.md and keeps the others, :func:`docs_rows`).
"""

from __future__ import annotations

import re
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

from selfcal.benchmarks.board.accuracy_draw import SCENARIO, simulated_calibration
from selfcal.benchmarks.doc_blocks import (
    ROOT,
    code_version,
    codes_note,
    codes_of,
    print_table,
    read_block,
)
from selfcal.benchmarks.pool import imap_jobs
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.drift.choose import chosen_views
from selfcal.calibration.drift.covariance import change_information
from selfcal.calibration.drift.fold_error import fold_error_model
from selfcal.calibration.drift.images import (
    ALPHA,
    calibration_error_model,
    calibration_views,
    estimate_covariance,
    fold_recheck,
    image_drift_check,
    view_noise,
)
from selfcal.calibration.drift.p_value import known_change_power, known_size_power
from selfcal.calibration.drift.power import shift_power
from selfcal.config.scenario import load_scenario, scenarios_dir
from selfcal.errors import InternalError
from selfcal.io.target_toml import parse_target
from selfcal.kinematics.forward import fk_tool
from selfcal.robot.definition import RobotDef, load_robot
from selfcal.sim.analytic import project_board
from selfcal.sim.kinematic_robot import read_back
from selfcal.studies.montecarlo.journal import DrawJournal, draw_key
from selfcal.target.boards import Board
from selfcal.threads import limit_threads

__all__ = [
    "NOISE_PX",
    "calibration_checks",
    "docs_rows",
    "drawn_calibration",
    "journaled_checks",
    "main",
    "merge_rows",
    "parse_block",
    "read_joints",
    "run",
    "table",
]

NOISE_PX = (0.05, 0.2)
NEW_VIEWS = 5
TOOL_SHIFT_M, JOINT_OFFSET_RAD = 0.2e-3, np.radians(0.05)
SPREAD_RAD = np.radians(10.0)
DOC = ROOT / "docs" / "tool-accuracy.md"
BLOCK = "benchmark_drift_images"
KINDS = ("unchanged", "tool", "joint")
CODE_KEYS = ("setup", "noise_px")
"""The keys that name a row in the note of the code that measured it (:func:`table`)."""
SCENARIOS = {"eye-in-hand": SCENARIO, "eye-to-hand": scenarios_dir() / "eye-to-hand.toml"}


def read_joints(robot: RobotDef, q: np.ndarray) -> np.ndarray:
    """The joints (rad / m) the controller of ``robot`` reports with the arm at the true
    posture ``q`` (..., n): its motors' counts rounded as its robot file's encoder table reads
    them, as the simulated acquisition does (:func:`selfcal.sim.kinematic_robot.read_back`);
    exact for a robot file without an encoder resolution."""
    return read_back(np.asarray(q, float), robot.encoder, True)


def drawn_calibration(sigma_px: float, seed: int, setup: str, robot_name: str | None) -> tuple:
    """One simulated calibration of the benchmark (the ``setup``'s scenario, its robot replaced
    by ``robot_name`` unless None, noise ``sigma_px``, ``seed``) and what its check uses:
    ``(cal, truth, robot, board, em, C, wide)`` (the error model, the estimate covariance and
    the folds' error model, None where the check runs no second null)."""
    cal, truth = simulated_calibration(sigma_px, seed, scenario_file=SCENARIOS[setup],
                                       robot=robot_name)  # fmt: skip
    robot = load_robot(cal.robot_model)
    board = parse_target(cal.target, "calibration.json: target")
    assert isinstance(board, Board)
    em = calibration_error_model(cal, "calibration.json")
    C = estimate_covariance(cal, em)
    wide = fold_error_model(em, cal.accuracy, view_noise(cal).misfit_counted)  # as check's
    return cal, truth, robot, board, em, C, wide


def calibration_checks(args: tuple) -> dict:
    """One calibration (noise ``sigma_px``, ``seed``, ``setup``, ``robot``: the setup's
    scenario's robot replaced, or None; optionally the new views per check, default
    :data:`NEW_VIEWS`, whether the check combines its tests by their smallest p-value's
    exact distribution rather than Bonferroni's bound: ``exact`` of
    :func:`selfcal.calibration.drift.images.image_drift_check`, and a pool of postures to
    choose the views from, 0: none,
    :func:`selfcal.calibration.drift.choose.chosen_views`) checked ``checks`` times: per kind the count of "changed" verdicts, and
    of the changes the causes named right and wrong."""
    sigma_px, seed, checks, setup, robot_name = args[:5]
    new_views = int(args[5]) if len(args) > 5 else NEW_VIEWS
    exact = bool(args[6]) if len(args) > 6 else False
    choose = int(args[7]) if len(args) > 7 else 0
    e2h = setup == "eye-to-hand"
    out: dict = {"status": "ok"} | {k: 0 for k in KINDS} | {"checks": 0}
    out |= {f"{k}_{w}": 0 for k in ("tool", "joint") for w in ("right", "wrong")}
    out |= {"tool_oracle": 0.0, "tool_size": 0.0, "tool_axes": 0.0, "tool_power": 0.0}
    out["fold_error"] = 0
    out |= {f"{k}_cannot_tell": 0 for k in KINDS}
    try:
        cal, truth, robot, board, em, C, wide = drawn_calibration(sigma_px, seed, setup,
                                                                  robot_name)  # fmt: skip
        out["fold_error"] = int(wide is not None)
        camera, true = truth.intrinsics_left, truth.true_model
        board_doc = truth.board or {}
        T_static = np.asarray(board_doc.get("T_world_cam" if e2h else "T_world_board"), float)
        q_cal = np.array([f.joints_rad for f in truth.frames])
        rng = np.random.default_rng(seed + 7000)
        n = true.n

        def seen(T_tool: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
            """The board's features seen with the chain's tool at ``T_tool`` (world frame)."""
            T_cam, T_board = (T_static, T_tool) if e2h else (T_tool, T_static)
            got = project_board(T_cam, camera, board, T_board, pixel_sigma=sigma_px, rng=rng)
            if not got:
                return None
            ids = np.array(sorted(got))
            return board.points(ids), np.concatenate([got[i] for i in ids])

        for _ in range(checks):
            views: dict[str, list] = {k: [] for k in KINDS}
            u = rng.normal(size=3)
            shift = np.eye(4)
            shift[:3, 3] = TOOL_SHIFT_M * u / np.linalg.norm(u)
            joint = int(rng.integers(n))
            q_new: list[np.ndarray] = []
            drawn = max(new_views, choose)
            for _ in range(10_000):
                if len(q_new) == drawn:
                    break
                q = q_cal[rng.integers(len(q_cal))] + rng.uniform(-SPREAD_RAD, SPREAD_RAD, n)
                q_off = q.copy()
                q_off[joint] += JOINT_OFFSET_RAD
                T = fk_tool(true, np.stack([q, q_off]))
                got = {"unchanged": seen(T[0]), "tool": seen(T[0] @ shift), "joint": seen(T[1])}
                if any(g is None for g in got.values()):
                    continue
                for k, g in got.items():
                    assert g is not None
                    views[k].append((len(q_new), *g))
                q_new.append(q)
            if len(q_new) < drawn:
                raise InternalError(f"no {drawn} postures near the calibration's see the board")
            if choose:
                pool = calibration_views(cal, em, read_joints(robot, np.array(q_new)),
                                         views["unchanged"])  # fmt: skip
                pick = chosen_views(C, pool, new_views, eye_to_hand=e2h)
                q_new = [q_new[i] for i in pick]
                views = {k: [(j, *views[k][i][1:]) for j, i in enumerate(pick)] for k in KINDS}
            qs = read_joints(robot, np.array(q_new))
            for k in KINDS:
                vj = calibration_views(cal, em, qs, views[k])
                res = image_drift_check(C, vj, eye_to_hand=e2h, camera_names=cal.cameras[0].free,
                                        exact=exact)  # fmt: skip
                res = fold_recheck(res, wide, partial(calibration_views, cal, q=qs, views=views[k]),
                                   C, eye_to_hand=e2h)  # fmt: skip
                out[f"{k}_cannot_tell"] += res.undecided
                if k == "tool":  # the shift's own pixels' noncentrality: mu^T Sigma^-1 mu
                    F = change_information(C, vj, np.concatenate([v.tool[:, :3] for v in vj]))
                    lam2 = float(shift[:3, 3] @ F @ shift[:3, 3])
                    out["tool_oracle"] += float(known_change_power(lam2, ALPHA))
                    out["tool_size"] += known_size_power(F, shift[:3, 3], ALPHA)
                    out["tool_axes"] += float(known_change_power(lam2, ALPHA, dof=3))
                    out["tool_power"] += shift_power(C, vj, eye_to_hand=e2h, alpha=ALPHA,
                                                     search=False).power  # fmt: skip
                out[k] += res.changed
                if k != "unchanged" and res.attribution is not None:
                    right = "hand-eye" if k == "tool" else f"joint {joint + 1}"
                    cause = res.attribution.cause
                    if cause is not None:
                        ok = right in res.attribution.explaining
                        out[f"{k}_right" if ok else f"{k}_wrong"] += 1
            out["checks"] += 1
        return out
    except Exception as exc:  # noqa: BLE001 - a benchmark counts failed draws
        return {"status": f"failed: {type(exc).__name__}: {str(exc)[:200]}"}


def journaled_checks(todo: list[tuple], jobs: int, code: str | None, journal: Path | None,
                     measure: Callable[[tuple], dict] | None = None) -> list[dict]:  # fmt: skip
    """``measure`` (default :func:`calibration_checks`; another's items are keyed by its name
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
    per check (``exact``, ``choose``: :func:`calibration_checks`; each calibration's counts
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


def table(rows: list[dict], checks: int) -> str:
    """The Markdown table of :func:`run`'s rows."""
    head = (
        "| setup | noise (px) | calibrations | checks | 'changed' on unchanged data (target < 2 %) | "
        "0.2 mm mount shift found (target >= 95 %) | a test knowing its direction / its size / "
        "its 3 axes | "
        "named the mount / wrong | 0.05 deg joint offset found (target >= 95 %) | named the joint "
        "/ wrong | 'cannot tell' verdicts: unchanged / shift / offset |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {r['setup']} | {r['noise_px']:g} | {r['calibrations']} | {r['checks']} | "
        f"{100 * r['unchanged']:.1f} % | {100 * r['tool']:.1f} % | "
        f"{100 * r['tool_oracle']:.1f} % / {_size(r)} / {100 * r['tool_axes']:.1f} % | "
        f"{100 * r['tool_right']:.0f} % / {100 * r['tool_wrong']:.0f} % | "
        f"{100 * r['joint']:.1f} % | {100 * r['joint_right']:.0f} % / "
        f"{100 * r['joint_wrong']:.0f} % | {_undecided(r)} |"
        for r in rows
    ]
    failed = sum(r["failed"] for r in rows)
    views = rows[0].get("views", NEW_VIEWS)
    choose = rows[0].get("choose", 0)
    docs = views == NEW_VIEWS and not rows[0].get("exact", False) and not choose
    noise = list(dict.fromkeys(r["noise_px"] for r in rows))
    extra = "" if noise == list(NOISE_PX) else " --noise-px " + " ".join(f"{s:g}" for s in noise)
    extra += "" if views == NEW_VIEWS else f" --views {views}"
    extra += " --min-p" if rows[0].get("exact", False) else ""
    extra += f" --choose {choose}" if choose else ""
    return (head + "\n".join(lines) + f"\n\n{checks} checks per calibration ({failed} "
            f"calibrations failed in all), {views} new views per check, alpha = 0.01; "
            "a test knowing: the mean power at alpha of a test that knew the shift's direction "
            "(the most powerful), only its size, 0.2 mm of the mount's translation in a direction "
            "it is not told (the likelihood ratio averaged over the directions: no test of the "
            "mount's translation alone does better on average; - : not recorded) or only its 3 "
            "axes (their chi-square), from the check's own covariance; named: of the changes found, the share whose cause the "
            "check named (right / wrong; the rest: cause not named); 'cannot tell' verdicts: "
            "of the checks of unchanged data, of the shifted mount and of the offset joint, "
            "how many said neither 'changed' nor 'unchanged' (not counted as "
            "changed; - : not recorded). `nice -n 10 uv run python -m "
            f"selfcal.benchmarks.drift.images --calibrations {rows[0]['calibrations'] + rows[0]['failed']} "
            f"--setup {' '.join(dict.fromkeys(r['setup'].split(',')[0] for r in rows))}"
            f"{robots_arg(rows)}{extra}{' --write-docs' if docs else ''}`"
            f"{codes_note(rows, CODE_KEYS)}.")  # fmt: skip


def _size(r: dict) -> str:
    """A row's power of the test knowing the shift's size alone, "-" when its run did not
    record it."""
    return "-" if "tool_size" not in r else f"{100 * r['tool_size']:.1f} %"


def _undecided(r: dict) -> str:
    """A row's 'cannot tell' counts per kind (unchanged / shift / offset), "-" when its
    run did not record them."""
    if f"{KINDS[0]}_cannot_tell" not in r:
        return "-"
    return " / ".join(str(r[f"{k}_cannot_tell"]) for k in KINDS)


def _percent(cell: str) -> float:
    return float(cell.strip().removesuffix("%")) / 100.0


def parse_block(text: str) -> tuple[list[dict], int, int]:
    """The rows of a table :func:`table` wrote (``text``, the docs block), the calibrations
    each row asked for and the checks per calibration (from its footnote): what
    :func:`merge_rows` keeps of the rows a run did not redo."""
    asked = re.search(r"--calibrations (\d+)", text)
    per = re.search(r"(\d+) checks per calibration", text)
    if asked is None or per is None:
        raise SystemExit(f"{DOC}: the {BLOCK} block names no --calibrations or checks per "
                         "calibration: run every setup and robot to rewrite it whole")  # fmt: skip
    rows = []
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) != 11 or not cells[1].replace(".", "", 1).isdigit():
            continue  # the header, its rule, the footnote
        *oracle, axes = cells[6].split("/")
        tool_right, tool_wrong = cells[7].split("/")
        joint_right, joint_wrong = cells[9].split("/")
        rows.append({
            "setup": cells[0], "noise_px": float(cells[1]), "calibrations": int(cells[2]),
            "failed": int(asked.group(1)) - int(cells[2]), "checks": int(cells[3]),
            "unchanged": _percent(cells[4]), "tool": _percent(cells[5]),
            "tool_oracle": _percent(oracle[0]), "tool_axes": _percent(axes),
            "tool_right": _percent(tool_right), "tool_wrong": _percent(tool_wrong),
            "joint": _percent(cells[8]), "joint_right": _percent(joint_right),
            "joint_wrong": _percent(joint_wrong),
        })  # fmt: skip
        if len(oracle) == 2 and oracle[1].strip() != "-":
            rows[-1]["tool_size"] = _percent(oracle[1])
        if cells[10] != "-":
            rows[-1] |= {
                f"{k}_cannot_tell": int(n) for k, n in zip(KINDS, cells[10].split("/"), strict=True)
            }
    for r, code in zip(rows, codes_of(text, rows, CODE_KEYS), strict=True):
        if code is not None or "measured by" in text:
            r["code"] = code
    return rows, int(asked.group(1)), int(per.group(1))


def merge_rows(old: list[dict], new: list[dict]) -> list[dict]:
    """``old``'s rows with those of the same setup (robot included) and noise level replaced
    by ``new``'s, in place; ``new``'s other rows after them."""
    fresh = {(r["setup"], r["noise_px"]): r for r in new}
    out = [fresh.pop((r["setup"], r["noise_px"]), r) for r in old]
    return out + list(fresh.values())


def docs_rows(rows: list[dict], calibrations: int, checks: int) -> list[dict]:
    """The rows the docs block should hold after a run of ``rows`` (``calibrations`` asked per
    row, ``checks`` per calibration): the block's rows of the setups, robots and noise levels
    the run did not cover are kept (:func:`merge_rows`).

    Raises:
        SystemExit: the block was measured with another ``--calibrations`` or ``--checks``
            (its rows would not be alike), naming the doc and the options to give.
    """
    old, asked, per = parse_block(read_block(DOC, BLOCK))
    if (asked, per) != (calibrations, checks):
        raise SystemExit(f"{DOC}: the {BLOCK} block's rows were measured with --calibrations "
                         f"{asked} --checks {per}, this run with --calibrations {calibrations} "
                         f"--checks {checks}: give those, or run every setup and robot")  # fmt: skip
    return merge_rows(old, rows)


def robots_arg(rows: list[dict]) -> str:
    """`` --robot ...`` of the eye-in-hand rows when they are not the scenario's robot alone."""
    names = list(dict.fromkeys(r["setup"].split(", ")[1] for r in rows
                               if r["setup"].startswith("eye-in-hand")))  # fmt: skip
    default = load_scenario(SCENARIOS["eye-in-hand"]).robot.model
    return "" if names in ([], [default]) else " --robot " + " ".join(names)


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
