"""``selfcal plan --measure tracker``: the postures at which to measure a tool point with a laser
tracker for the tracker route (``selfcal identify``), the command of
:mod:`selfcal.calibration.tracker.plan`; writes PLAN/joints.csv, trajectory.yaml and plan.json."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from selfcal.cli.plan_args import (
    check_common,
    keep_out_boxes,
    plan_inputs,
    trajectory_joint_names,
    write_postures,
)
from selfcal.console.common import CliError, note_written, parse_floats, writing

__all__ = ["CAMERA_OPTIONS", "cmd_tracker", "greedy_note"]

CAMERA_OPTIONS = (
    ("--target", "target"),
    ("--camera", "camera"),
    ("--fov-deg", "fov_deg"),
    ("--resolution", "resolution"),
    ("--mount", "mount"),
    ("--board-pose", "board_pose"),
    ("--camera-pose", "camera_pose"),
    ("--pixel-sigma", "pixel_sigma"),
)
"""What a camera plan takes and a tracker plan refuses (it has no camera and no board)."""


def greedy_note(chosen_by: str, greedy_m: float, what: str) -> str:
    """Why ``what`` (e.g. "the plan is") is a set of the pool, not the greedy choice, whose
    prediction ``greedy_m`` (m) was worse (:class:`selfcal.calibration.tracker.plan.Choice`);
    empty when the greedy choice won."""
    if chosen_by.startswith("greedy"):
        return ""
    return (f"the greedy choice predicted {greedy_m * 1000:.3f} mm, so {what} the pool's "
            f"{chosen_by}")  # fmt: skip


def _check(args: argparse.Namespace) -> None:
    given = [o for o, k in CAMERA_OPTIONS if getattr(args, k) not in (None, [])]  # 0 is given
    if given:
        raise CliError(
            f"--measure tracker plans the postures of a tool point a laser tracker measures: "
            f"{', '.join(given)} describe{'s' if len(given) == 1 else ''} a camera and a board",
            fix="leave out the camera's and the board's options, or plan for a camera "
            "(--measure camera)",
        )
    if not args.robot:
        raise CliError("give --robot (a model name, robot TOML or URDF)")
    args.count = 12 if args.count is None else args.count
    if args.count < 3:
        raise CliError(f"--count {args.count}: a plan needs at least 3 postures")
    check_common(args, args.count)
    args.tool_point = "0,0,0" if args.tool_point is None else args.tool_point
    args.sigma_mm = 0.1 if args.sigma_mm is None else args.sigma_mm  # identify's default
    if not args.sigma_mm > 0:
        raise CliError(f"--sigma-mm {args.sigma_mm}: the tracker's noise must be > 0 mm")


def cmd_tracker(args: argparse.Namespace, deviation) -> int:
    """Plan, write and print (module docstring); ``deviation`` the arm's deviation from its
    drawing (:class:`selfcal.calibration.board.deviation.Deviation`)."""
    from selfcal.acquisition.backends import robot_reference
    from selfcal.calibration.tracker.plan import TrackerPlanSetup, plan_tracker
    from selfcal.io.plan_files import write_plan
    from selfcal.robot.definition import load_robot

    _check(args)
    robot = load_robot(args.robot)
    names = trajectory_joint_names(args, robot.joint_names)
    tool = parse_floats(args.tool_point, 3, "--tool-point (mm)")
    boxes = keep_out_boxes(args)
    setup = TrackerPlanSetup(robot, tool / 1000.0, boxes, args.sigma_mm / 1000.0)
    plan = plan_tracker(setup, args.count, seed=args.seed, candidates=args.candidates,
                        deviation=deviation)  # fmt: skip
    out = Path(args.out)
    ref = robot_reference(args.robot)
    with writing(args, out):
        write_postures(args, out, names, plan.q, robot)
        body = {
            "robot": ref,
            "count": len(plan.q),
            "predicted_tool_rms_mm": round(plan.predicted_m * 1000, 4),
            "random_tool_rms_mm": round(plan.random_m * 1000, 4),
            "greedy_tool_rms_mm": round(plan.greedy_m * 1000, 4),
            "chosen_by": plan.chosen_by,
            "kinematic_parameters": plan.kept,
            "minimal_parameters": plan.parameters,
            "criterion": (
                "tracker route (positions of the tool point, exact joints) covariance with the "
                "parameters its rank and conditioning tests keep, the others held at the drawing, deviating "
                f"uniformly within +-{args.deviation_mm:g} mm and +-{args.deviation_deg:g} deg: "
                f"RMS of the tool point's position error over {len(plan.workspace)} random "
                f"workspace postures in the tracker frame, tracker noise {args.sigma_mm:g} mm "
                "per coordinate"
            ),
            "candidates": plan.candidates,
            "path_deg": round(float(np.degrees(plan.path_rad)), 3),
            "random_path_deg": round(float(np.degrees(plan.random_path_rad)), 3),
            "seed": args.seed,
            "tool_point_mm": tool.tolist(),
            **plan_inputs(args, boxes, robot.edge_unit, plan.q, plan.q_random),
        }
        doc = write_plan(out / "plan.json", "tracker", body)
    note_written(args, out)
    line = (f"tracker plan of {len(plan.q)} postures: predicted tool-point error "
            f"{plan.predicted_m * 1000:.3f} mm RMS (a random plan of {len(plan.q)}: "
            f"{plan.random_m * 1000:.3f} mm; {plan.kept} of {plan.parameters} parameters "
            f"identified); joint path {np.degrees(plan.path_rad):.0f} deg")  # fmt: skip
    if note := greedy_note(plan.chosen_by, plan.greedy_m, "the plan is"):
        line += "; " + note
    print(json.dumps(doc) if args.json else line)
    return 0
