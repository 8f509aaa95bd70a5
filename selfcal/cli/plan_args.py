"""What ``selfcal plan``'s commands share (:mod:`selfcal.cli.plan`, :mod:`selfcal.cli.plan_tracker`):
the keep-out boxes of the command line, trajectory.yaml's joint names and plan.json's last
keys."""

from __future__ import annotations

import argparse

import numpy as np

from selfcal.console.common import CliError, parse_floats

__all__ = ["check_common", "deviation", "keep_out_boxes", "plan_inputs", "trajectory_joint_names",
           "write_postures"]  # fmt: skip


def plan_inputs(args: argparse.Namespace, boxes: np.ndarray, edge_unit: np.ndarray,
                q: np.ndarray, q_random: np.ndarray | None = None) -> dict:  # fmt: skip
    """plan.json's last keys: the deviation (mm, deg), the keep-out ``boxes`` (b, 6) m as mm,
    the postures ``q`` (m, n) SI and, when given, the random plan's, in edge units (deg, mm)."""
    doc = {
        "deviation_mm_deg": [args.deviation_mm, args.deviation_deg],
        "keep_out_mm": (np.asarray(boxes) * 1000).tolist(),
        "joints_deg": np.round(q / edge_unit, 6).tolist(),
    }
    if q_random is not None:
        doc["random_joints_deg"] = np.round(q_random / edge_unit, 6).tolist()
    return doc


def keep_out_boxes(args: argparse.Namespace) -> np.ndarray:
    """The ``--keep-out`` boxes (b, 6) m."""
    from selfcal.kinematics.keep_out import check_boxes

    return check_boxes(
        np.array([parse_floats(b, 6, "--keep-out (mm)") for b in args.keep_out]).reshape(-1, 6)
        / 1000.0
    )


def check_common(args: argparse.Namespace, count: int) -> None:
    """A clear error for the options every plan takes, before any planning: the trajectory's
    timing (``--speed-deg-s`` > 0, ``--dwell-s`` >= 0) and a pool of ``--candidates`` at least
    the ``count`` postures to choose (fewer were silently made up to ``count``: the plan was then
    the random plan)."""
    if not args.speed_deg_s > 0:
        raise CliError(f"--speed-deg-s {args.speed_deg_s:g}: the fastest joint's speed must be "
                       "> 0 deg/s", fix="e.g. --speed-deg-s 10 (the default)")  # fmt: skip
    if not args.dwell_s >= 0:
        raise CliError(f"--dwell-s {args.dwell_s:g}: the rest at each posture must be >= 0 s",
                       fix="e.g. --dwell-s 2 (the default)")  # fmt: skip
    if args.candidates < count:
        raise CliError(f"--candidates {args.candidates}: fewer than the {count} postures to "
                       "choose from them", fix=f"give --candidates of at least {count} (the "
                       "default 400)")  # fmt: skip


def trajectory_joint_names(args: argparse.Namespace, robot_names: tuple[str, ...]) -> list[str]:
    """trajectory.yaml's ``joint_names``: ``--joint-names`` (the controller's, one per joint of
    the robot file in its order) or the robot file's ``robot_names``."""
    if args.joint_names is None:
        return list(robot_names)
    names = [n.strip() for n in args.joint_names.split(",")]
    if len(names) != len(robot_names) or not all(names) or len(set(names)) != len(names):
        raise CliError(
            f"--joint-names {args.joint_names}: give {len(robot_names)} different names, one per "
            f"joint of the robot file in its order ({', '.join(robot_names)})",
            fix="e.g. a UR ROS driver's: --joint-names shoulder_pan_joint,shoulder_lift_joint,"
            "elbow_joint,wrist_1_joint,wrist_2_joint,wrist_3_joint",
        )
    return names


def write_postures(args: argparse.Namespace, out, names: list[str], q: np.ndarray, robot) -> None:
    """PLAN/joints.csv (the import's format, edge units) and trajectory.yaml (the controller's
    joint ``names``, ``--speed-deg-s`` and ``--dwell-s``) of postures ``q`` (m, n) SI of the
    ``robot`` (a :class:`selfcal.robot.definition.RobotDef`) into the folder ``out``."""
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.plan_files import joints_csv, trajectory_yaml

    write_text_atomic(out / "joints.csv", joints_csv(q, robot.edge_unit))
    write_text_atomic(out / "trajectory.yaml", trajectory_yaml(
        names, q, robot.home, speed=args.speed_deg_s * robot.edge_unit, dwell_s=args.dwell_s))  # fmt: skip


def deviation(args: argparse.Namespace):
    """The arm's deviation from its drawing the plan is made for (``--deviation-mm`` /
    ``--deviation-deg``, SI inside: m, rad)."""
    from selfcal.calibration.board.deviation import Deviation

    if args.deviation_mm < 0 or args.deviation_deg < 0:
        raise CliError("--deviation-mm and --deviation-deg must be >= 0")
    if args.deviation_mm == 0 and args.deviation_deg == 0:
        raise CliError("--deviation-mm 0 --deviation-deg 0 says the arm is exactly its drawing: "
                       "there is no kinematic error for a plan to reduce or a nominal to compare "
                       "with; give how far your arm may lie from its drawing (e.g. "
                       "--deviation-mm 0.2 --deviation-deg 0.05)")  # fmt: skip
    return Deviation(args.deviation_mm / 1000.0, float(np.radians(args.deviation_deg)))
