"""``selfcal plan --check K CALIBRATION`` (issue #29): the K postures a drift check (``selfcal
check``) of a board calibration images, chosen by the check's stated power
(:mod:`selfcal.calibration.drift.choose`), written as PLAN/joints.csv, trajectory.yaml and
plan.json."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from selfcal.cli.plan_args import (
    check_common,
    keep_out_boxes,
    trajectory_joint_names,
    write_postures,
)
from selfcal.console.common import CliError, note_written, writing

__all__ = ["CHECK_CANDIDATES", "CHECK_EPILOG", "CHECK_REFUSES", "cmd_check_plan"]

CHECK_CANDIDATES = 30
"""``--check``'s candidates when ``--candidates`` is not given: the pool the drift benchmark
measured the choice with (``python -m selfcal.benchmarks.drift.images --choose 30``)."""

CHECK_REFUSES = (
    ("--robot", "robot"), ("--target", "target"), ("--camera", "camera"),
    ("--fov-deg", "fov_deg"), ("--resolution", "resolution"), ("--board-pose", "board_pose"),
    ("--camera-pose", "camera_pose"), ("--count", "count"), ("--add", "add"),
    ("--pixel-sigma", "pixel_sigma"), ("--deviation-mm", "deviation_mm"),
    ("--deviation-deg", "deviation_deg"), ("--tool-point", "tool_point"),
    ("--sigma-mm", "sigma_mm"),
)  # fmt: skip
"""What a plan of a check refuses (the calibration gives the cell, K the count; the power
needs no forecast of an arm)."""

CHECK_EPILOG = """\
--check K CALIBRATION: instead, the K postures at which a morning drift check (`selfcal check
CALIBRATION NEW`) of a board calibration (`selfcal calibrate` on images of a board, either mount,
one camera) finds most: chosen one by one from --candidates (default 30) of the plan's candidate
postures in the calibration's cell (its robot file, calibrated camera, board and mounts; the
collision checks above, --keep-out), half of them within 10 deg of the calibration's postures
on every joint; a view may show part of the board (at least 12 features, each with the squares
about it in the image, spanning a quarter of the image each way; the power counts only the
features each view would detect), each the one that raises the check's stated power most (the power `selfcal check` states: how often images like these find a 0.2 mm move of
the camera's, eye-to-hand the board's, mount on the flange, not turned, in a random direction,
from calibration.json's covariance). It weighs that change alone: a joint's offset is tested by
the check but has no stated power. PLAN/joints.csv (for `selfcal import --joints`) and
trajectory.yaml hold the postures, plan.json the stated power of the chosen set and of the first
K candidates (random postures) beside it; the line says both. Record images there, import them
and run `selfcal check CALIBRATION NEW` (docs/tool-accuracy.md). A tracker calibration is
refused (its check states no power).
"""


def _calibration_path(text: str) -> Path:
    src = Path(text)
    path = src / "calibration.json" if src.is_dir() else src
    if not path.is_file():
        raise CliError(f"--check: {path} not found", fix="give the DIR `selfcal calibrate` wrote "
                       "(or its calibration.json)")  # fmt: skip
    return path


def _board_calibration(path: Path):
    """The board calibration at ``path``, or a :class:`CliError` saying what ``--check``
    chooses for (naming the file)."""
    from selfcal.calibration.handeye.calibration_file import is_handeye
    from selfcal.calibration.tracker.calibration_file import is_tracker_calibration
    from selfcal.io.board_calibration import calibration_kind, read_board_calibration

    if is_tracker_calibration(path):
        raise CliError(f"--check: {path} is a tracker calibration: its check (new tracker rows, "
                       "`selfcal check --joint-units`) states no power to choose postures by; "
                       "--check chooses the postures of a board calibration's check (images)",
                       fix="give a calibration of `selfcal calibrate` on images of a board, or "
                       "plan tracker postures with `selfcal plan --measure tracker`")  # fmt: skip
    if calibration_kind(path) != "board" or is_handeye(path):
        raise CliError(f"--check: {path} is not a board calibration with joints: --check "
                       "chooses the postures of a board calibration's check (images; `selfcal "
                       "check` tests no other with images)",
                       fix="give a calibration of `selfcal calibrate` on images of a board and "
                       "joint readings")  # fmt: skip
    return read_board_calibration(path)


def cmd_check_plan(args: argparse.Namespace) -> int:
    """``selfcal plan --check K CALIBRATION``: the K postures chosen by the check's stated power,
    written to PLAN/ with the power of the chosen and of K random candidates."""
    from selfcal.calibration.drift.choose import choose_check_postures
    from selfcal.cli.calibration_files import robot_of_calibration
    from selfcal.console.progress import Progress
    from selfcal.io.plan_files import write_plan

    k_text, src = args.check
    given = [o for o, key in CHECK_REFUSES if getattr(args, key, None) is not None]
    given += ["--mount"] if args.mount is not None else []
    given += ["--measure tracker"] if args.measure == "tracker" else []
    if given:
        raise CliError(f"--check takes the robot, the mount, the camera, the board and their "
                       f"poses from the calibration and K as the count: {', '.join(given)} would "
                       "not be used", fix=f"leave out {', '.join(given)} with --check")  # fmt: skip
    try:
        count = int(k_text)
    except ValueError:
        raise CliError(f"--check {k_text} {src}: K must be a whole number of postures") from None
    if count < 1:
        raise CliError(f"--check {count}: choose at least 1 posture", fix="e.g. --check 5")
    args.candidates = CHECK_CANDIDATES if args.candidates is None else args.candidates
    check_common(args, count)
    path = _calibration_path(src)
    cal = _board_calibration(path)
    robot = robot_of_calibration(path, cal.robot_model)
    names = trajectory_joint_names(args, robot.joint_names)
    boxes = keep_out_boxes(args)
    with Progress("plan", enabled=not (args.quiet or args.json)).step(
        f"choosing {count} check postures"
    ) as st:
        got = choose_check_postures(cal, robot, count, candidates=args.candidates, seed=args.seed,
                                    boxes=boxes, where=str(path))  # fmt: skip
        st.result(f"from {got.candidates} candidates")
    unit = robot.edge_unit
    out = Path(args.out)
    with writing(args, out):
        write_postures(args, out, names, got.q, robot)
        body = {
            "calibration": str(path),
            "robot": cal.robot_model,
            "mount": cal.setup,
            "count": len(got.q),
            "change": {
                "kind": "mount translation",
                "size_mm": got.power.size_mm,
                "words": f"a {got.power.size_mm:g} mm move of the {got.power.mount}'s mount on "
                "the flange without turning, in a random direction (the power `selfcal check` "
                "states); a joint's offset is tested by the check but not weighed here (it has "
                "no stated power)",
            },
            "power": got.power.to_json(),
            "random_power": got.random_power.to_json(),
            "random_is": f"the first {count} of the candidates (drawn at random as they are)",
            "line": got.line(),
            "unseen_configurations": got.unseen,
            "candidates": got.candidates,
            "candidates_from": got.drawn_from,
            "seed": args.seed,
            "keep_out_mm": (np.asarray(boxes) * 1000).tolist(),
            "joints_deg": np.round(got.q / unit, 6).tolist(),
            "random_joints_deg": np.round(got.q_random / unit, 6).tolist(),
        }
        doc = write_plan(out / "plan.json", "check", body)
    note_written(args, out)
    line = got.line()
    if got.unseen:
        from selfcal.calibration.drift.verdict import UNSEEN_NOTE

        line += (f"\n{got.unseen} of {len(got.q)} at arm configurations the calibration did not "
                 f"see: {UNSEEN_NOTE}")  # fmt: skip
    line += (f"\nrecord images there, `selfcal import --joints {out / 'joints.csv'} ...`, then "
             f"`selfcal check {src} NEW`")  # fmt: skip
    print(json.dumps(doc) if args.json else line)
    return 0
