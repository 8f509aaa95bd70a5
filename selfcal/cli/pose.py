"""The tool pose on the command line of ``selfcal fk`` and ``selfcal ik`` (with or without
``--calibration``): millimetres and degrees here, metres and radians inside.

An orientation is given in one of four ways (``ik``; ``fk`` prints the first three):

- ``--rpy-deg R,P,Y``: roll, pitch, yaw about the fixed base axes x, y, z (the URDF/ROS
  convention: ``R = Rz(Y) Ry(P) Rx(R)``), any robot;
- ``--quat W,X,Y,Z``: a unit quaternion (scalar first), any robot;
- ``--pitch P [--roll R]``: the ER-4u controller's Cartesian pitch and roll
  (:mod:`selfcal.kinematics.tool_pose`), only for a 5-axis ER-type arm (:func:`selfcal.kinematics.ik.check_er_structure`),
  solved in closed form;
- ``--position-only``: the tool point alone (orientation free).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from selfcal.console.common import CliError, parse_floats

if TYPE_CHECKING:
    from selfcal.robot.definition import RobotDef

# scipy (Rotation) and selfcal.kinematics.ik are imported where used: `selfcal --help` loads this module

__all__ = ["POSE_HELP", "PoseArgs", "add_pose_args", "parse_pose_args", "is_er", "orientation_json"]

POSE_HELP = """\
tool orientation (exactly one):
  --rpy-deg R,P,Y   roll, pitch, yaw (deg) about the fixed base axes x, y, z: R = Rz(Y) Ry(P) Rx(R)
                    (URDF/ROS convention); any robot; solved numerically (damped least squares;
                    an ER-type arm tries its closed form first)
  --quat W,X,Y,Z    unit quaternion, scalar first; any robot; solved like --rpy-deg
  --pitch P [--roll R]  the ER-4u controller's Cartesian pitch and roll (deg); 5-axis ER-type arms
                    only (closed-form IK)
  --position-only   the tool point alone, any orientation
the tool is the last DH frame (flange) of --robot; xyz in mm in the robot's base frame.
a list starting with a minus sign works as typed: --xyz -400,-133,400 --rpy-deg -180,0,90.
"""


@dataclass(frozen=True)
class PoseArgs:
    """A parsed tool target: ``xyz_m`` (3,), then either ``pitch_rad``/``roll_rad`` (ER
    convention) or ``rotation`` (3, 3) or neither (position only); ``reference`` (n,) rad or None."""

    xyz_m: np.ndarray
    pitch_rad: float | None
    roll_rad: float | None
    rotation: np.ndarray | None
    reference: np.ndarray | None

    @property
    def pitch_roll(self) -> tuple[float, float] | None:
        """``(pitch_rad, roll_rad)`` of an ER-convention target (``--pitch [--roll]``), or
        None: a rotation or the position only."""
        if self.pitch_rad is None or self.roll_rad is None:
            return None
        return self.pitch_rad, self.roll_rad


def add_pose_args(sp: argparse.ArgumentParser, *, xyz_help: str) -> None:
    """Add ``--xyz``, the orientation options and ``--reference`` to an ``ik`` parser."""
    sp.add_argument("--xyz", required=True, help=xyz_help)
    sp.add_argument("--rpy-deg", default=None, metavar="R,P,Y", help="fixed-axis roll, pitch, yaw")
    sp.add_argument("--quat", default=None, metavar="W,X,Y,Z", help="unit quaternion, w first")
    sp.add_argument("--pitch", type=float, default=None, help="ER-4u tool pitch in deg")
    sp.add_argument("--roll", type=float, default=None, help="ER-4u tool roll in deg (default 0)")
    sp.add_argument("--position-only", action="store_true", help="tool point only")
    sp.add_argument(
        "--reference",
        default=None,
        metavar="J1,...,Jn",
        help="current joint angles in deg: the solution nearest them is preferred (default home)",
    )


def is_er(robot: RobotDef) -> bool:
    """Whether the robot has the 5-axis ER structure of the closed-form IK."""
    from selfcal.kinematics.ik import IKStructureError, check_er_structure  # lazy: see the imports

    try:
        check_er_structure(robot)
    except IKStructureError:
        return False
    return True


def parse_pose_args(args: argparse.Namespace, robot: RobotDef) -> PoseArgs:
    """The target of an ``ik`` command line (module docstring).

    Raises:
        CliError: not exactly one orientation, malformed numbers, a non-unit quaternion, or
            pitch/roll for a robot that is not an ER-type arm.
    """
    xyz = parse_floats(args.xyz, 3, "--xyz (mm)") / 1000.0
    # a parser built elsewhere (only --xyz/--pitch/--roll) keeps working
    for key in ("rpy_deg", "quat", "roll", "reference"):
        if not hasattr(args, key):
            setattr(args, key, None)
    args.position_only = getattr(args, "position_only", False)
    given = [
        name
        for name, v in (
            ("--pitch", args.pitch),
            ("--rpy-deg", args.rpy_deg),
            ("--quat", args.quat),
            ("--position-only", args.position_only or None),
        )
        if v is not None
    ]
    if args.roll is not None and args.pitch is None:
        raise CliError("--roll needs --pitch (the ER-4u convention); or give --rpy-deg / --quat")
    if len(given) != 1:
        raise CliError(
            "give exactly one tool orientation: --rpy-deg, --quat, --pitch [--roll] or "
            f"--position-only (got {', '.join(given) or 'none'})",
            fix="see `selfcal ik --help`",
        )
    ref = None
    if args.reference is not None:
        ref = parse_floats(args.reference, robot.n, "--reference (deg)")
        ref = ref * robot.edge_unit
        try:
            robot.check_joints(ref)
        except ValueError as exc:
            raise CliError(f"--reference: {exc}") from None
    if args.pitch is not None:
        roll = 0.0 if args.roll is None else args.roll
        for name, val in (("--pitch", args.pitch), ("--roll", roll)):
            if not (np.isfinite(val) and abs(val) <= 720.0):
                raise CliError(f"{name}: expected an angle in deg within +-720, got {val}")
        if not is_er(robot):
            raise CliError(
                f"--pitch/--roll are the ER-4u controller's convention; {robot.name} is not a "
                "5-axis ER-type arm",
                fix="give the orientation with --rpy-deg R,P,Y or --quat W,X,Y,Z",
            )
        return PoseArgs(xyz, float(np.radians(args.pitch)), float(np.radians(roll)), None, ref)
    from scipy.spatial.transform import Rotation  # lazy: see the imports

    rotation = None
    if args.rpy_deg is not None:
        rpy = parse_floats(args.rpy_deg, 3, "--rpy-deg")
        rotation = Rotation.from_euler("xyz", rpy, degrees=True).as_matrix()
    elif args.quat is not None:
        w, x, y, z = parse_floats(args.quat, 4, "--quat")
        norm = float(np.sqrt(w * w + x * x + y * y + z * z))
        if abs(norm - 1.0) > 1e-6:
            raise CliError(f"--quat: expected a unit quaternion, got norm {norm:.9g}")
        rotation = Rotation.from_quat([x, y, z, w]).as_matrix()
    return PoseArgs(xyz, None, None, rotation, ref)


def orientation_json(R: np.ndarray) -> dict:
    """``rpy_deg`` (fixed-axis x, y, z, as ``--rpy-deg``) and ``quat_wxyz`` of a rotation."""
    # numpy only (selfcal.transforms), so that `selfcal fk` loads no scipy (issue 17)
    from selfcal.transforms import quat_from_matrix, rpy_from_matrix

    return {
        "rpy_deg": np.round(np.degrees(rpy_from_matrix(R)), 6).tolist(),
        "quat_wxyz": np.round(quat_from_matrix(R), 9).tolist(),
    }
