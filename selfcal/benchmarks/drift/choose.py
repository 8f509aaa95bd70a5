"""Benchmark: does a drift check at ``selfcal plan --check``'s postures find what the command
states? (issue #29)

Per calibration, drawn as :mod:`selfcal.benchmarks.drift.images` draws them (the setup's
analytic scenario, ``--noise-px``, seeded by the draw; eye-in-hand on ``--robot``), the
command's own choice (:func:`selfcal.calibration.drift.choose.choose_check_postures`:
``--views`` of ``--candidates`` of the recording plan's candidates, by the check's stated power)
and the random set it is set beside (the first ``--views`` candidates) are each checked
``--checks`` times with new images at those postures: the arm unchanged, and its mount (eye-in-hand
the camera's, eye-to-hand the board's) moved 0.2 mm in a random direction without turning; the
corners projected through the true chain and camera with the same pixel noise, the joints read
back at the robot file's encoder resolution
(:func:`selfcal.benchmarks.drift.image_checks.read_joints`), tested as the drift benchmark tests them
(:func:`selfcal.calibration.drift.images.image_drift_check` and its second null). Reported per
set: the mean stated power (what the command's line says), the share of shifts found (target
>= 95 %), the share of unchanged checks that say "changed" (target < 2 %) and the "cannot tell"
counts. A view keeps the corners the command's rule says a detector finds there, by the TRUE
chain and camera (:func:`view_corners`: :func:`selfcal.calibration.board.plan.views.
seen_features`, the four cells about each corner in the image with the rule's margin; the slow
render test ``test_the_chosen_postures_render_with_the_corners_the_plan_expects`` detects every
such corner), the corners the stated power counts, so the check is tested with the data the power
was stated for; ``--all-in-image`` keeps every corner the true chain puts in the image instead
(those by the margin and the cut markers too: the table's "corners" column says which). A view
with fewer than the board's least is left out of its check (counted), and a view missing a
corner the command expected it to detect (by the calibration's chain) is counted. Each row names the robot; a
stated power that is an upper bound (:attr:`selfcal.calibration.drift.power.ShiftPower.upper`:
the command says "at most") is printed so.

Run: ``nice -n 10 uv run python -m selfcal.benchmarks.drift.choose [--calibrations 30]
[--checks 10] [--setup eye-in-hand] [--robot er4u-paper] [--noise-px 0.2] [--views 5]
[--candidates 30] [--joint-offset] [--all-in-image] [--jobs 1] [--journal FILE]
[--write-docs]`` (prints the
rows; ``--write-docs`` puts them in docs/tool-accuracy.md's ``benchmark_drift_choose`` block). ``--joint-offset``: each set is also checked with one random joint's zero moved by
0.05 deg (the issue's other change, which the stated power does not weigh), with draws of its
own.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from functools import partial
from pathlib import Path

import numpy as np

from selfcal.benchmarks.doc_blocks import code_version, codes_note, print_table
from selfcal.benchmarks.drift.image_checks import (
    JOINT_OFFSET_RAD,
    SCENARIOS,
    TOOL_SHIFT_M,
    drawn_calibration,
    read_joints,
)
from selfcal.benchmarks.drift.image_table import DOC
from selfcal.benchmarks.drift.images import journaled_checks
from selfcal.benchmarks.usage import benchmark_parser
from selfcal.calibration.board.plan.views import PlanSetup, seen_features
from selfcal.calibration.drift.choose import choose_check_postures, expected_features
from selfcal.calibration.drift.images import (
    calibration_views,
    fold_recheck,
    image_drift_check,
)
from selfcal.camera import CameraModel
from selfcal.kinematics.forward import fk_tool
from selfcal.sim.analytic import project_board
from selfcal.target.boards import Board
from selfcal.threads import limit_threads
from selfcal.transforms import inv_pose

__all__ = ["SETS", "chosen_checks", "main", "table", "view_corners"]

SETS = ("chosen", "random")
COUNTS = (
    "unchanged",
    "tool",
    "unchanged_cannot_tell",
    "tool_cannot_tell",
    "views_left_out",
    "views_missing_expected",
)


BLOCK = "benchmark_drift_choose"
"""The table's block in docs/tool-accuracy.md (``--write-docs``)."""
JOINT_COUNTS = ("joint", "joint_cannot_tell")
"""With ``--joint-offset``: the checks of a random joint's zero moved by 0.05 deg."""
CORNERS = {False: "expected (true chain)", True: "all in the image"}
"""The table's "corners" column: per view the corners :func:`view_corners` keeps (by
``all_in_image``)."""


def view_corners(setup: PlanSetup, camera: CameraModel, board: Board, T_world_cam: np.ndarray,
                 T_world_board: np.ndarray, *, sigma_px: float, rng: np.random.Generator,
                 all_in_image: bool = False) -> dict[int, np.ndarray]:  # fmt: skip
    """The corners of one check image: ``{feature id: (1, 2) px}`` of ``board`` (at
    ``T_world_board``, board -> world, m) seen by ``camera`` at ``T_world_cam`` (camera ->
    world, m), the true chain's poses, with pixel noise ``sigma_px`` from ``rng``
    (:func:`selfcal.sim.analytic.project_board`). Kept: the corners the cell ``setup``'s rule
    says a detector finds (:func:`selfcal.calibration.board.plan.views.seen_features` with the
    true ``camera``: the corners the command's stated power counts), or with ``all_in_image``
    every corner in the image. Fewer than the board's ``min_features``: none."""
    pix = project_board(T_world_cam, camera, board, T_world_board, pixel_sigma=sigma_px,
                        rng=rng)  # fmt: skip
    if all_in_image:
        return pix
    T_cam_board = inv_pose(np.asarray(T_world_cam, float)) @ np.asarray(T_world_board, float)
    seen = seen_features(replace(setup, camera=camera), T_cam_board)[0]
    kept = {int(i): pix[int(i)] for i in board.layout()[0][seen] if int(i) in pix}
    return kept if len(kept) >= board.min_features else {}


def chosen_checks(args: tuple) -> dict:
    """One calibration (noise ``sigma_px``, ``seed``, ``checks``, ``setup``, ``robot`` or None,
    ``views``, ``candidates``, optionally ``joint`` and ``all_in_image`` of :func:`view_corners`):
    the robot's name; per set (:data:`SETS`) the stated power, whether it is an upper bound and
    the counts of "changed" and "cannot tell" verdicts of its ``checks`` checks unchanged and
    shifted; with ``joint`` also of checks with one random joint's zero moved by
    :data:`selfcal.benchmarks.drift.image_checks.JOINT_OFFSET_RAD` (:data:`JOINT_COUNTS`; their own
    draws, so the other counts are those of a run without)."""
    sigma_px, seed, checks, setup, robot_name, views, candidates = args[:7]
    joint = bool(args[7]) if len(args) > 7 else False
    all_in_image = bool(args[8]) if len(args) > 8 else False
    e2h = setup == "eye-to-hand"
    try:
        cal, truth, robot, board, em, C, wide = drawn_calibration(sigma_px, seed, setup,
                                                                  robot_name)  # fmt: skip
        got = choose_check_postures(cal, robot, views, candidates=candidates, seed=seed)
        camera, true = truth.intrinsics_left, truth.true_model
        board_doc = truth.board or {}
        T_static = np.asarray(board_doc.get("T_world_cam" if e2h else "T_world_board"), float)
        rng = np.random.default_rng(seed + 9000)
        rng_joint = np.random.default_rng(seed + 9500)
        out: dict = {"status": "ok", "checks": checks, "robot": robot.name}
        ids_all = board.layout()[0]
        for name, q, power in (("chosen", got.q, got.power), ("random", got.q_random,
                                                               got.random_power)):  # fmt: skip
            out[f"{name}_power"] = power.power
            out[f"{name}_upper"] = bool(power.upper)
            counts = dict.fromkeys(COUNTS, 0)
            T_true = fk_tool(true, q)
            qs = read_joints(robot, q)
            expected = expected_features(cal, got.setup, q)  # as the command expects them

            def verdict(T_tools: np.ndarray, draw: np.random.Generator, counts: dict = counts,
                        expected: np.ndarray = expected, qs: np.ndarray = qs):  # fmt: skip
                """The check of views with the chain's tool at ``T_tools`` (world frame)."""
                seen = []
                for f, T in enumerate(T_tools):
                    T_cam, T_board = (T_static, T) if e2h else (T, T_static)
                    pix = view_corners(got.setup, camera, board, T_cam, T_board,
                                       sigma_px=sigma_px, rng=draw, all_in_image=all_in_image)  # fmt: skip
                    ids = np.array(sorted(pix))
                    counts["views_missing_expected"] += int(
                        not set(ids_all[expected[f]]) <= set(ids.tolist())
                    )
                    if not len(pix):
                        counts["views_left_out"] += 1
                        continue
                    seen.append((f, board.points(ids), np.concatenate([pix[i] for i in ids])))
                vj = calibration_views(cal, em, qs, seen)
                res = image_drift_check(C, vj, eye_to_hand=e2h, camera_names=cal.cameras[0].free)
                return fold_recheck(res, wide, partial(calibration_views, cal, q=qs, views=seen),
                                    C, eye_to_hand=e2h)  # fmt: skip

            for _ in range(checks):
                u = rng.normal(size=3)
                shift = np.eye(4)
                shift[:3, 3] = TOOL_SHIFT_M * u / np.linalg.norm(u)
                for kind, move in (("unchanged", np.eye(4)), ("tool", shift)):
                    res = verdict(T_true @ move, rng)
                    counts[kind] += int(res.changed)
                    counts[f"{kind}_cannot_tell"] += int(res.undecided)
                if joint:  # the arm at q + offset reads q (its zero moved)
                    q_off = q.copy()
                    q_off[:, int(rng_joint.integers(q.shape[1]))] += JOINT_OFFSET_RAD
                    res = verdict(fk_tool(true, q_off), rng_joint, dict(counts))  # own tally
                    counts["joint"] = counts.get("joint", 0) + int(res.changed)
                    counts["joint_cannot_tell"] = counts.get("joint_cannot_tell", 0) + int(
                        res.undecided
                    )
            out |= {f"{name}_{k}": v for k, v in counts.items()}
        out["unseen"] = got.unseen
        return out
    except Exception as exc:  # noqa: BLE001 - a benchmark counts failed draws
        return {"status": f"failed: {type(exc).__name__}: {str(exc)[:200]}"}


def power_text(row: dict, s: str) -> str:
    """The mean stated power of the set ``s`` in the ``row``, "at most" where every calibration's
    is an upper bound (the command's line says so), else how many of them are."""
    upper, n = row.get(f"{s}_upper", 0), row["calibrations"]
    text = f"{100 * row[f'{s}_power']:.1f} %"
    if upper and upper == n:
        return f"at most {text}"
    return f"{text} ({upper} of {n} at most)" if upper else text


def table(rows: list[dict]) -> str:
    """The Markdown table of the rows (one per setup, robot and noise level) and the line after
    it naming the command and the code that measured them."""
    head = ("| setup | noise (px) | calibrations | checks | corners | set | stated power (mean) "
            "| 0.2 mm mount shift found (target >= 95 %) | 'changed' on unchanged data (target "
            "< 2 %) | 'cannot tell': unchanged / shift |\n"
            "|---|---|---|---|---|---|---|---|---|---|\n")  # fmt: skip
    lines = []
    for r in rows:
        for s in SETS:
            m = max(r["checks"], 1)
            lines.append(f"| {r['setup']} | {r['noise_px']:g} | {r['calibrations']} | {r['checks']} "
                         f"| {r.get('corners', CORNERS[False])} | {s} | {power_text(r, s)} | "
                         f"{100 * r[f'{s}_tool'] / m:.1f} % | {100 * r[f'{s}_unchanged'] / m:.1f} % "
                         f"| {r[f'{s}_unchanged_cannot_tell']} / {r[f'{s}_tool_cannot_tell']} |")  # fmt: skip
    setups = " ".join(dict.fromkeys(r["setup"].split(",")[0] for r in rows))
    cals = max((r["calibrations"] for r in rows), default=0)
    noise = " ".join(dict.fromkeys(f"{r['noise_px']:g}" for r in rows))
    every = " --all-in-image" if any(r.get("corners") == CORNERS[True] for r in rows) else ""
    return (head + "\n".join(lines) + f"\n\n(`MUJOCO_GL=egl nice -n 10 uv run python -m "
            f"selfcal.benchmarks.drift.choose --calibrations {cals} --setup {setups} --noise-px "
            f"{noise}{every} --jobs 1 --write-docs`{codes_note(rows, ('setup', 'noise_px'))}.)")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark (one BLAS thread per process) and print the table."""
    limit_threads(1)
    ap = benchmark_parser(__file__, description=__doc__.splitlines()[0])
    ap.add_argument("--calibrations", type=int, default=30, help="per row (default 30)")
    ap.add_argument("--checks", type=int, default=10, help="per calibration and set (default 10)")
    ap.add_argument("--setup", nargs="+", default=["eye-in-hand"], choices=tuple(SCENARIOS))
    ap.add_argument(
        "--robot", default=None, help="eye-in-hand: this robot (default the scenario's)"
    )
    ap.add_argument("--noise-px", type=float, nargs="+", default=[0.2])
    ap.add_argument("--views", type=int, default=5, help="postures per check (default 5)")
    ap.add_argument("--candidates", type=int, default=30, help="the command's pool (default 30)")
    ap.add_argument("--joint-offset", action="store_true",
                    help="also check each set with one random joint's zero moved by 0.05 deg "
                    "(its own draws; printed after the table)")  # fmt: skip
    ap.add_argument("--all-in-image", action="store_true",
                    help="check with every corner the true chain puts in the image, not only "
                    "those the command's rule expects a detector to find (the table's 'corners' "
                    "column)")  # fmt: skip
    ap.add_argument("--jobs", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--write-docs", action="store_true",
                    help="put the table in docs/tool-accuracy.md (its benchmark_drift_choose "
                    "block; the default views, candidates and checks only)")  # fmt: skip
    ap.add_argument("--journal", type=Path, default=None, metavar="FILE",
                    help="keep each calibration's counts in FILE (JSON lines) and reuse them")  # fmt: skip
    args = ap.parse_args(argv)
    if args.write_docs and (args.views, args.candidates, args.checks) != (5, 30, 10):
        ap.error("--write-docs writes the table of the command's defaults: leave out --views, "
                 "--candidates and --checks, or --write-docs")  # fmt: skip
    rows, code = [], code_version()
    for setup in args.setup:
        robot = args.robot if setup == "eye-in-hand" else None
        for s in args.noise_px:
            todo = [(s, seed, args.checks, setup, robot, args.views, args.candidates)
                    + (args.joint_offset, args.all_in_image)
                    for seed in range(1, args.calibrations + 1)]  # fmt: skip
            ok = [g for g in journaled_checks(todo, args.jobs, code, args.journal, chosen_checks)
                  if g["status"] == "ok"]  # fmt: skip
            names = ", ".join(sorted({g["robot"] for g in ok})) or (robot or "no calibration")
            row = {"setup": f"{setup}, {names}", "noise_px": s, "code": code,
                   "calibrations": len(ok), "checks": sum(g["checks"] for g in ok),
                   "corners": CORNERS[args.all_in_image]}  # fmt: skip
            for k in SETS:
                row[f"{k}_power"] = float(np.mean([g[f"{k}_power"] for g in ok])) if ok else 0.0
                row[f"{k}_upper"] = sum(bool(g[f"{k}_upper"]) for g in ok)
                row |= {f"{k}_{c}": sum(g.get(f"{k}_{c}", 0) for g in ok)
                        for c in COUNTS + JOINT_COUNTS}  # fmt: skip
            row["unseen"] = sum(g["unseen"] for g in ok)
            rows.append(row)
            print(f"{setup} {s} px: {len(ok)}/{args.calibrations} calibrations; chosen "
                  f"postures at unseen configurations {row['unseen']}; views left out "
                  f"{row['chosen_views_left_out']} / {row['random_views_left_out']}; views "
                  f"missing a corner the command expected {row['chosen_views_missing_expected']}"
                  f" / {row['random_views_missing_expected']}", file=sys.stderr)  # fmt: skip
    print_table(table(rows), DOC, BLOCK, write=args.write_docs)
    for r in rows if args.joint_offset else []:
        m = max(r["checks"], 1)
        print(f"{r['setup']} {r['noise_px']:g} px: a 0.05 deg offset of one random joint found "
              + "; ".join(f"{s} {100 * r[f'{s}_joint'] / m:.1f} % ('cannot tell' "
                          f"{r[f'{s}_joint_cannot_tell']})" for s in SETS)
              + f" of {r['checks']} checks (target >= 95 %)")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
