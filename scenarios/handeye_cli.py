"""The flange-pose side of ``selfcal import`` (``--poses``): images and a robot's flange poses
(no joint readings) as a pose dataset (:mod:`calib.pose_import`), eye-in-hand or eye-to-hand.
See docs/handeye.md.
"""

from __future__ import annotations

import argparse
import json

from scenarios.cli_common import CliError, note_written

# OpenCV, scipy and the calibration load in the commands that use them (`selfcal --help` stays fast).

__all__ = ["add_pose_import_args", "check_pose_only_args", "cmd_import_poses"]

ROTATIONS = ("quaternion-xyzw", "abb-quaternion", "kuka-abc", "fanuc-wpr", "ur-rotvec")
"""``--rotation``: :data:`calib.pose_conventions.CONVENTIONS` (kept here so --help needs no scipy)."""
SETUP_CHOICES = ("eye-in-hand", "eye-to-hand")
"""``--setup``: :data:`calib.io.pose_dataset.SETUPS`."""
_POSE_ONLY = ("pose_units", "rotation", "setup")


def add_pose_import_args(sp: argparse.ArgumentParser) -> None:
    """``--poses``, ``--pose-units``, ``--rotation`` and ``--setup`` of ``selfcal import``."""
    sp.add_argument(
        "--poses", default=None, metavar="FILE",
        help="flange poses (robot base -> flange) instead of joints: a CSV with x_mm,y_mm,z_mm "
        "(or x,y,z with --pose-units) and the orientation columns of --rotation, or "
        "industrial_calibration's cal_data.yaml (it names the images) or its poses/ folder; "
        "no --robot needed (docs/handeye.md)",
    )  # fmt: skip
    sp.add_argument("--pose-units", default=None, choices=("mm", "m"),
                    help="unit of the pose file's x,y,z when its header does not say")  # fmt: skip
    sp.add_argument(
        "--rotation", default=None, choices=ROTATIONS,
        help="orientation convention of the pose file: quaternion-xyzw (qx,qy,qz,qw), "
        "abb-quaternion (q1..q4 = w,x,y,z), kuka-abc (A,B,C deg, intrinsic Z-Y'-X''), fanuc-wpr "
        "(W,P,R deg, fixed X-Y-Z), ur-rotvec (rx,ry,rz rad); default: from the column names",
    )  # fmt: skip
    sp.add_argument(
        "--setup", default=None, choices=SETUP_CHOICES,
        help="with --poses: eye-in-hand (camera on the flange, board static) or eye-to-hand "
        "(camera static, board on the flange)",
    )  # fmt: skip


def check_pose_only_args(args: argparse.Namespace) -> None:
    """A :class:`CliError` for the pose options given without ``--poses``."""
    given = [f"--{k.replace('_', '-')}" for k in _POSE_ONLY if getattr(args, k, None)]
    if given:
        raise CliError(f"{', '.join(given)} apply to --poses",
                       fix="give the flange poses with --poses FILE, or leave them out")  # fmt: skip


def cmd_import_poses(args: argparse.Namespace) -> int:
    """``selfcal import --poses FILE --setup SETUP --target T [--images GLOB]``."""
    from calib.import_dataset import CameraImages
    from calib.pose_import import import_pose_dataset

    if args.joints or args.bag:
        raise CliError("--poses replaces --joints and --bag", fix="give one of them")
    if args.joint_units:
        raise CliError("--joint-units applies to --joints", fix="leave it out with --poses")
    if not args.setup:
        raise CliError("--poses needs --setup eye-in-hand | eye-to-hand",
                       fix="eye-in-hand: the camera rides on the flange; eye-to-hand: the camera "
                       "is static and the board rides on the flange")  # fmt: skip
    if args.robot or args.base_link or args.tool_link:
        raise CliError("--robot, --base-link and --tool-link describe the joints of --joints",
                       fix="leave them out with --poses: flange poses need no robot model")  # fmt: skip
    if args.images and len(args.images) > 1:
        raise CliError("--poses takes one camera's images",
                       fix="import each camera as its own pose dataset")  # fmt: skip
    if args.camera_model and len(args.camera_model) > 1 or args.free and len(args.free) > 1:
        raise CliError("--poses takes one camera: one --camera-model and one --free")
    cam = CameraImages.parse(args.images[0]) if args.images else None
    model = (
        (args.camera_model[0].partition("=")[2] or args.camera_model[0])
        if args.camera_model
        else None
    )
    free = (args.free[0].partition("=")[2] or args.free[0]).split(",") if args.free else None
    kwargs = {"camera_model": model} if model else {}
    ds = import_pose_dataset(cam, args.poses, args.target, args.out, args.setup,
                             rotation=args.rotation, units=args.pose_units, link=args.link,
                             free=free, **kwargs)  # fmt: skip
    n = len(ds.T_base_flange)
    note_written(args, args.out)
    if args.json:
        print(json.dumps({"dataset": str(args.out), "frames": n, "setup": ds.setup}))
    else:
        print(f"imported {n} frames ({ds.setup}, flange poses) into {args.out}")
    return 0
