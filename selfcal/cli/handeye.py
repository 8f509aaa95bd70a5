"""The flange-pose side of ``selfcal import`` (``--poses``), ``calibrate`` and ``evaluate``:
images and a robot's flange poses (no joint readings) as a pose dataset
(:mod:`selfcal.importing.poses`), eye-in-hand or eye-to-hand; its hand-eye calibration
(:mod:`selfcal.calibration.handeye.calibrate`) and the held-out prediction from the poses alone. See docs/handeye.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from selfcal.choices import HANDEYE_CAMERA, SETUPS
from selfcal.console.common import CliError, note_written
from selfcal.errors import SelfCalError

# OpenCV, scipy and the calibration load in the commands that use them (`selfcal --help` stays fast).

__all__ = [
    "add_pose_import_args",
    "add_pose_noise_arg",
    "calibrate_poses",
    "check_pose_only_args",
    "cmd_import_poses",
    "evaluate_poses",
]

ROTATIONS = ("quaternion-xyzw", "abb-quaternion", "kuka-abc", "fanuc-wpr", "ur-rotvec")
"""``--rotation``: :data:`selfcal.io.poses.conventions.CONVENTIONS` (kept here so --help needs no scipy)."""
_POSE_ONLY = ("pose_units", "rotation", "setup")
POSE_NOISE_HELP = (
    "pose datasets: the flange poses' noise per axis, MM,DEG (e.g. 0.5,0.05: each pose then gets "
    "a correction with that prior, estimated with the hand-eye); 'exact': the poses as reported; "
    "'estimate': the noise estimated from the residuals; 'auto' (default): estimated, and the "
    "corrections dropped when they predict left-out images worse than the exact poses "
    "(docs/handeye.md)"
)


CAMERA_HELP = (
    "pose datasets: the camera in the answer; 'held': the board calibration's (like for like "
    "with OpenCV's hand-eye methods, which take the camera as given); 'refined': refined with "
    "the hand-eye (few board images but a rich pose set); 'auto' (default): held unless "
    "refining predicts left-out images better by more than 1 %% (docs/handeye.md)"
)


def add_pose_noise_arg(sp: argparse.ArgumentParser) -> None:
    """``--pose-noise`` and ``--camera`` of ``selfcal calibrate`` (a pose dataset's)."""
    sp.add_argument("--pose-noise", default=None, metavar="MM,DEG|auto|estimate|exact",
                    help=POSE_NOISE_HELP)  # fmt: skip
    sp.add_argument("--camera", default=None, choices=HANDEYE_CAMERA, help=CAMERA_HELP)


def parse_pose_noise(text: str | None):  # -> PoseNoise | str (the import waits for the command)
    """``--pose-noise``'s value: ``"auto"`` (None), ``"estimate"``, a
    :class:`selfcal.calibration.handeye.eiv.PoseNoise` (``exact``: both 0). Raises
    :class:`CliError` naming the value."""
    from selfcal.calibration.handeye.eiv import EXACT, PoseNoise

    t = "auto" if text is None else text.strip().lower()
    if t in ("auto", "estimate"):
        return t
    if t == "exact":
        return EXACT
    try:
        mm, deg = (float(v) for v in t.split(","))
        return PoseNoise(mm, deg)
    except (ValueError, SelfCalError):
        raise CliError(f"--pose-noise {text!r}",
                       fix="give MM,DEG (two sigmas > 0, e.g. 0.5,0.05), exact, estimate or "
                       "auto") from None  # fmt: skip


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
        "--setup", default=None, choices=SETUPS,
        help="eye-in-hand (camera on the flange, board static) or eye-to-hand (camera static, "
        "board on the flange): needed with --poses and a --bag's --tf-parent/--tf-child; with "
        "--joints default eye-in-hand, recorded in dataset.json so calibrate takes the board "
        "route's chain the right way round",
    )  # fmt: skip


def check_pose_only_args(args: argparse.Namespace, allowed: tuple[str, ...] = ()) -> None:
    """A :class:`CliError` for the pose options given without ``--poses`` (but ``allowed``)."""
    given = [f"--{k.replace('_', '-')}" for k in _POSE_ONLY
             if k not in allowed and getattr(args, k, None)]  # fmt: skip
    if given:
        raise CliError(f"{', '.join(given)} apply to --poses",
                       fix="give the flange poses with --poses FILE, or leave them out")  # fmt: skip


def cmd_import_poses(args: argparse.Namespace) -> int:
    """``selfcal import --poses FILE --setup SETUP --target T [--images GLOB]``."""
    from selfcal.importing.dataset import CameraImages
    from selfcal.importing.poses import import_pose_dataset

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


def calibrate_poses(root: Path, *, quiet: bool = False, figures: bool = False,
                    method: str = "joint", joint_sigma_deg: float | None = None,
                    tracker_args: argparse.Namespace | None = None,
                    pose_noise: str | None = None, camera: str | None = None) -> None:  # fmt: skip
    """``selfcal calibrate`` of a pose dataset: write ``root/calibration.json`` (the hand-eye
    and board mount with sigmas, the camera, the nominal beside:
    :func:`selfcal.calibration.routes.calibrate_pose_dataset`). The options of the joint
    datasets (``--method two-stage``, ``--joint-sigma-deg``, ``--tracker``) are errors here;
    ``pose_noise``: ``--pose-noise`` (:func:`parse_pose_noise`); ``camera``: ``--camera``
    (:data:`selfcal.choices.HANDEYE_CAMERA`, default ``"auto"``)."""
    from selfcal.calibration.handeye.calibrate import FRAMES
    from selfcal.calibration.handeye.calibration_file import (
        camera_section,
        camera_text,
        flange_poses_section,
        flange_poses_text,
    )
    from selfcal.calibration.routes import calibrate_pose_dataset

    if method != "joint" or joint_sigma_deg is not None or (tracker_args and tracker_args.tracker):
        raise CliError(f"{root} is a pose dataset (flange poses, no joints): --method, "
                       "--joint-sigma-deg and --tracker do not apply",
                       fix="leave them out")  # fmt: skip
    cal = calibrate_pose_dataset(root, pose_noise=parse_pose_noise(pose_noise),
                                 camera=camera or "auto")  # fmt: skip
    if not quiet:
        x_what, b_what = FRAMES[cal.setup]
        c, n = cal.calibrated, cal.nominal
        say = lambda t: print(t, file=sys.stderr)  # noqa: E731
        say(f"{cal.setup}, {int(cal.used.sum())} frames: no kinematics to identify (flange poses "
            "as the robot reports them); camera, hand-eye and board mount fitted on corner "
            "reprojection")  # fmt: skip
        say(f"  {flange_poses_text(flange_poses_section(cal))}")
        say(f"  {camera_text(camera_section(cal))}")
        for what, T, s in ((x_what, c.X, c.X_std), (b_what, c.B, c.B_std)):
            xyz = ", ".join(f"{v:.2f}" for v in T[:3, 3] * 1000)
            sig = ", ".join(f"{v:.2f}" for v in s[3:] * 1000)
            say(
                f"  {what}: xyz ({xyz}) mm +- ({sig}) mm, rotation +- "
                f"{max(s[:3]) * 180 / 3.141592653589793:.3f} deg"
            )
        say(
            f"  fit: calibrated {c.rms_px:.3f} px, nominal (camera stage's camera held) "
            f"{n.rms_px:.3f} px"
        )


def evaluate_poses(args: argparse.Namespace) -> None:
    """``selfcal evaluate`` of a hand-eye calibration: predict every corner of the held-out pose
    dataset from its flange poses alone with the calibrated and the nominal model
    (:func:`selfcal.calibration.routes.evaluate_pose_dataset`); write evaluation.json and print
    both."""
    from selfcal.calibration.field.calibrate import CalibrationFailedError
    from selfcal.calibration.handeye.calibration_file import held_out_verdict, read_handeye
    from selfcal.calibration.routes import evaluate_pose_dataset
    from selfcal.io.jsonfile import write_json_atomic

    doc = check = evaluate_pose_dataset(args.calibration, args.dataset)
    out = Path(args.out) if args.out else Path(args.dataset) / "evaluation.json"
    write_json_atomic(out, doc)
    note_written(args, out)
    if args.json:
        print(json.dumps({"evaluation": str(out), **doc}))
    else:
        rms, behind = check["held_out_rms_px"], check["behind_camera"]

        def px(k: str) -> str:
            r = "none in front of the camera" if rms[k] is None else f"{rms[k]:.3f} px"
            return r + (f" ({behind[k]} corners behind the camera)" if behind[k] else "")

        doc = read_handeye(args.calibration)[3]
        verdict = held_out_verdict(check["calibration_better_than_nominal"],
                                   doc.get("camera_choice"))  # fmt: skip
        print(
            f"held-out {check['frames']} frames, {check['corners']} corners predicted from the "
            f"flange poses: nominal {px('nominal')}, calibrated {px('calibrated')} ({verdict})"
        )
    if check["failures"]:
        raise CalibrationFailedError.of(tuple(check["failures"]), out)
