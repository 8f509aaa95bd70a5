"""``selfcal fk`` and ``selfcal ik``: the nominal (or calibrated, ``--calibration``) model's
forward and inverse kinematics on the command line. Degrees and millimetres at this edge."""

from __future__ import annotations

import argparse
import json

import numpy as np

from selfcal.cli.deploy import CALIBRATED_FRAME, calibration_robot, load_calibration
from selfcal.cli.pose import is_er, orientation_json, parse_pose_args
from selfcal.config.defaults import DEFAULT_ROBOT
from selfcal.console.common import CliError, parse_floats

__all__ = ["cmd_fk", "cmd_ik"]


def _joints_rad(robot, text: str) -> np.ndarray:
    """``--joints`` (deg, mm for a prismatic joint) in SI (rad, m), checked against the ranges."""
    q = parse_floats(text, robot.n, "--joints (deg, mm for a prismatic joint)") * robot.edge_unit
    try:
        robot.check_joints(q)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    return q


def _robot_name(args: argparse.Namespace) -> str:
    """``--robot`` or the default robot (:data:`selfcal.config.scenario.DEFAULT_ROBOT`)."""
    return args.robot or DEFAULT_ROBOT


def cmd_fk(args: argparse.Namespace) -> int:
    from selfcal.kinematics.forward import fk_tool
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.kinematics.tool_pose import tool_pose
    from selfcal.robot.definition import load_robot

    if args.calibration:
        dep = load_calibration(args.calibration)
        if args.robot and args.robot != dep.robot_name:
            raise CliError(
                f"--robot {args.robot} contradicts the calibration's robot {dep.robot_name} "
                f"({args.calibration})",
                fix="leave out --robot: the calibration names its robot",
            )
        robot, model = calibration_robot(args.calibration, dep.robot_name), dep.model
    else:
        robot = load_robot(_robot_name(args))
        model = nominal_mcpc(robot)
    q = _joints_rad(robot, args.joints)
    T = fk_tool(model, q[None])[0]
    out = {
        "model": robot.name,
        "joints_deg": np.round(q / robot.edge_unit, 6).tolist(),
        "xyz_mm": np.round(T[:3, 3] * 1000, 4).tolist(),
    }
    if is_er(robot):
        _, pitch, roll = tool_pose(T)
        out["pitch_deg"] = round(float(np.degrees(pitch)), 4)
        out["roll_deg"] = round(float(np.degrees(roll)), 4)
    out.update(orientation_json(T[:3, :3]))
    if args.calibration:
        out["calibration"] = str(args.calibration)
        out["frame"] = CALIBRATED_FRAME
    print(json.dumps(out))
    return 0


def _ik_er(robot, pose, branch: str | None) -> np.ndarray:
    """The closed-form IK of a 5-axis ER-type arm (pitch and roll)."""
    from selfcal.kinematics.ik import ik, ik_nearest

    xyz, pitch, roll = pose.xyz_m, pose.pitch_rad, pose.roll_rad
    if not branch:
        return ik_nearest(robot, xyz, pitch, roll, reference=pose.reference)
    sols = ik(robot, xyz, pitch, roll, reference=pose.reference)
    pick = [s for s in sols if s.branch == branch]
    if not pick:
        names = sorted({s.branch for s in sols})
        raise CliError(f"--branch {branch!r}: no such solution; available: {names}")
    if not pick[0].in_range:
        raise CliError(f"branch {branch}: {'; '.join(pick[0].violations)}")
    return pick[0].joints


def cmd_ik(args: argparse.Namespace) -> int:
    from selfcal.kinematics.ik import UnreachableError
    from selfcal.kinematics.ik_numeric import ToolTarget, ik_robot
    from selfcal.robot.definition import load_robot

    robot = load_robot(_robot_name(args))
    pose = parse_pose_args(args, robot)
    out: dict = {"model": robot.name}
    try:
        if pose.pitch_rad is not None:
            q = _ik_er(robot, pose, args.branch)
            out["solver"] = "analytic"
        else:
            if args.branch:
                raise CliError("--branch needs --pitch (the ER-4u's closed-form IK branches)")
            res = ik_robot(
                robot, ToolTarget.checked(pose.xyz_m, pose.rotation), reference=pose.reference
            )
            q = res.joints
            out["solver"] = "numeric"
            out["position_error_mm"] = res.position_error_m * 1000.0
            out["angle_error_deg"] = float(np.degrees(res.angle_error_rad))
    except UnreachableError as exc:
        raise CliError(f"unreachable: {exc}") from None
    out["joints_deg"] = np.round(q / robot.edge_unit, 6).tolist()
    print(json.dumps(out))
    return 0
