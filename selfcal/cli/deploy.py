"""``selfcal export`` and ``selfcal ik --calibration``: deploy a calibrated model.

- ``selfcal export DIR --format mjcf|urdf|toml --out FILE``: the calibration in ``DIR``
  (``DIR/calibration.json``, or that file itself) as a MuJoCo model, a URDF or a parameter table,
  all in the robot's base frame with the tool tip as tool (:mod:`selfcal.export.deploy`).
- ``selfcal ik --calibration FILE --xyz X,Y,Z --pitch P [--roll R]`` (an ER-type arm) or
  ``--rpy-deg R,P,Y`` / ``--quat W,X,Y,Z`` / ``--position-only`` (any arm,
  :mod:`selfcal.cli.pose`): joint commands (deg) that reach the target with the calibrated
  model (:mod:`selfcal.export.compensate`); ``FILE`` is a
  ``calibration.json``, its dataset folder or a TOML written by ``selfcal export --format toml``.

:func:`register` adds ``export`` and extends an existing ``ik`` command with ``--calibration``
(keeping its nominal behaviour without it), or adds ``ik`` when there is none.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from selfcal.cli.calibration_files import (
    _calibration_file,
    _refuse_no_gain,
    _refuse_pose_calibration,
    _usable,
    calibration_robot,
    load_calibration,
    load_handeye,
)
from selfcal.cli.pose import add_pose_args, parse_pose_args
from selfcal.cli.ros import BAG_FORMATS, cmd_export_bag
from selfcal.cli.ros import add_export_args as add_bag_export_args
from selfcal.console.common import CliError, add_json, note_written

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = [
    "register",
    "cmd_export",
    "cmd_ik_calibrated",
    "calibration_robot",
    "load_calibration",
    "FORMATS",
    "CALIBRATED_FRAME",
]

CALIBRATED_FRAME = "robot base frame (DH frame 0 of the identified joint axes 1 and 2), tool tip"
"""The frame of a calibrated model's tool pose (``fk``/``ik --calibration``)."""

FORMATS = {"mjcf": "calibrated.xml", "urdf": "calibrated.urdf", "toml": "calibrated.toml",
           "opencv": "calibrated.yml", "camera_info": "calibrated.yaml",
           "tf": "hand_eye_tf.yaml", "easy_handeye": "hand_eye_easy_handeye.yaml",
           "matrix": "hand_eye_matrix.yaml"}  # fmt: skip
"""Each format and its default file (beside the calibration); the format itself is chosen by
``--format`` only, never by a file's suffix."""
CAMERA_FORMATS = ("opencv", "camera_info")
HANDEYE_FORMATS = ("tf", "easy_handeye", "matrix")
WRITTEN = {
    "mjcf": "the calibrated robot as a MuJoCo model (MJCF)",
    "urdf": "the calibrated robot as a URDF (kinematics only)",
    "toml": "the calibrated robot's parameter table (TOML, mm and deg)",
    "opencv": "OpenCV YAML for cv2.FileStorage (camera_matrix, distortion_coefficients)",
    "camera_info": "ROS camera_info YAML (camera_calibration's convention: K, D, R = I, "
    "P = [K' | 0] with K' the rectified camera matrix)",
    "tf": "ROS static transforms (static_transform_publisher arguments for ROS 2 and ROS 1, "
    "launch snippets) in YAML",
    "easy_handeye": "easy_handeye's calibration YAML (parameters, transformation)",
    "matrix": "4x4 matrices with translation, quaternion (xyzw) and Euler angles in YAML",
}
"""What each format writes, in the words ``selfcal export`` says after writing it."""

EXPORT_HELP = """\
frames and units:
  world / base_link = the robot's base frame: DH frame 0 of the IDENTIFIED joint axes 1 and 2
  (z along joint 1's axis; for the nominal robot this is the nominal model's world);
  tool = the tool tip (identified camera + the known camera-to-tip transform), z = tool axis;
  joint values = the controller's joint readings. MJCF/URDF in m and rad, TOML in mm and deg.
formats (chosen by --format only, never by the --out file's suffix):
  mjcf  the robot of models/scorbot_er4u/<robot>.xml with calibrated frames (same names)
  urdf  base_link, link1..link<n>, tool_tip and the camera's optical frame:
        camera_optical_frame (one camera) or cam_left, cam_right (a pair); kinematics only
  toml  MCPC parameters with std, joint offsets and the DH table where one exists
  opencv       the estimated camera as cv2.FileStorage YAML (camera_matrix,
               distortion_coefficients, image_width, image_height, distortion_model)
  tf            the hand-eye (and board mount) as ROS static transforms: frames, translation,
                quaternion, sigmas, static_transform_publisher arguments (ROS 2 and 1) and
                launch snippets
  easy_handeye  the hand-eye as easy_handeye's saved calibration YAML (parameters,
                transformation x y z qx qy qz qw; sigmas and board mount under scorbot_selfcal)
  matrix        the hand-eye (and board mount) as 4x4 matrices (m), translation (mm), quaternion
                (xyzw) and Euler roll, pitch, yaw (deg, R = Rz(yaw) Ry(pitch) Rx(roll)) with sigmas
  hand-eye transforms: a pose dataset's calibration: eye-in-hand flange -> camera and base ->
  board, eye-to-hand base -> camera and flange -> board; a calibration with joints: flange ->
  camera (and base -> board for a board calibration, unless joint 1 or 2 is prismatic or their
  axes are parallel: no base frame can be rebuilt then, the file says so); an eye-to-hand board
  calibration with joints: base -> camera and flange -> board with sigmas. ROS frame names
  (--frames): base_link, tool0 (the flange as the controller reports it), camera_optical_frame
  (z forward, x right, y down), board; see docs/handeye.md
  camera_info  the estimated camera as ROS camera_info YAML in ROS camera_calibration's
               convention: camera_matrix K, distortion_coefficients D (distortion_model
               plumb_bob / rational_polynomial / equidistant), rectification_matrix R = I,
               projection_matrix P = [K' | 0] with K' the rectified camera matrix
               (getOptimalNewCameraMatrix, alpha 0; K without distortion); read it with a
               YAML reader (camera_calibration_parsers, PyYAML), not cv2.FileStorage
see docs/deploy.md
"""


def cmd_export(args: argparse.Namespace) -> int:
    """``selfcal export``: write the calibrated model in the chosen format."""
    if args.bag:
        return cmd_export_bag(args)
    from selfcal.export.deploy import BASE_FRAME, TOOL_FRAME
    from selfcal.export.robot_toml import to_toml
    from selfcal.export.urdf import to_urdf
    from selfcal.io.atomic import write_text_atomic
    from selfcal.sim.export_mjcf import calibrated_mjcf

    fmt = args.format
    if fmt in BAG_FORMATS:
        raise CliError(f"--format {fmt} writes a ROS bag: give --bag OUT instead of --out")
    if fmt is None:
        raise CliError(
            "give --format: the format is never taken from the --out file's name "
            f"({' | '.join(FORMATS)}), or --bag OUT to write a dataset as a ROS bag",
            fix="e.g. --format urdf (writes DIR/calibrated.urdf without --out)",
        )
    if args.out is None:
        args.out = str(_calibration_file(args.calibration).parent / FORMATS[fmt])
    out = Path(args.out)
    if fmt in HANDEYE_FORMATS:
        return _export_handeye(args, fmt, out)
    if args.frames is not None:
        raise CliError(f"--frames names the frames of --format {' | '.join(HANDEYE_FORMATS)}",
                       fix="leave it out")  # fmt: skip
    if fmt in CAMERA_FORMATS:
        note_written(args, out)
        return _export_camera(args, fmt, out)
    _refuse_pose_calibration(args.calibration, fmt)
    _refuse_no_gain(args.calibration, args.force)
    dep = load_calibration(args.calibration)
    robot = calibration_robot(args.calibration, dep.robot_name)
    if fmt == "mjcf":
        text = calibrated_mjcf(dep, robot)
    elif fmt == "urdf":
        text = to_urdf(dep)
    else:
        text = to_toml(dep, robot)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, text)
    note_written(args, out)
    written = f"{WRITTEN[fmt]} of {dep.robot_name}"
    _say(args, out, written)
    print(
        json.dumps(
            {
                "out": str(out),
                "format": fmt,
                "written": written,
                "robot_model": dep.robot_name,
                "base_frame": BASE_FRAME,
                "tool_frame": TOOL_FRAME,
            }
        )
    )
    return 0


def _export_handeye(args: argparse.Namespace, fmt: str, out: Path) -> int:
    """``--format tf | easy_handeye | matrix``: the calibration's hand-eye and board mount."""
    from selfcal.errors import InputError
    from selfcal.export.handeye import (
        frame_names,
        to_easy_handeye_yaml,
        to_matrix_yaml,
        to_tf_yaml,
    )
    from selfcal.io.atomic import write_text_atomic

    try:
        frames = frame_names(args.frames)
    except InputError as exc:
        raise CliError(str(exc), fix=exc.fix) from None
    ex = load_handeye(args.calibration)
    write = {"tf": to_tf_yaml, "easy_handeye": to_easy_handeye_yaml, "matrix": to_matrix_yaml}
    text = write[fmt](ex, frames)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, text)
    note_written(args, out)
    whats = [f"{t.what} ({frames[t.parent]} -> {frames[t.child]})" for t in ex.transforms]
    shown = whats[:1] if fmt == "easy_handeye" else whats
    written = f"{' and '.join(shown)} of the {ex.setup} calibration as {WRITTEN[fmt]}"
    _say(args, out, written)
    print(json.dumps({"out": str(out), "format": fmt, "written": written, "setup": ex.setup,
                      "frames": frames}))  # fmt: skip
    return 0


def _say(args: argparse.Namespace, out: Path, written: str) -> None:
    """Say in words on stderr what was written where (not with -q)."""
    if not getattr(args, "quiet", False):
        print(f"wrote {out}: {written}", file=sys.stderr)


def _export_camera(args: argparse.Namespace, fmt: str, out: Path) -> int:
    """Write the calibration's estimated camera as ``fmt``: a self-calibration's (shared by the
    rig's cameras), a board calibration's camera ``--camera`` (None: the first) under its
    model."""
    from selfcal.calibration.handeye.calibration_file import is_handeye, read_handeye
    from selfcal.camera import Pinhole
    from selfcal.export.camera import to_camera_info_yaml, to_opencv_yaml
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.board_calibration import calibration_kind, read_board_calibration
    from selfcal.io.calibration import read_calibration

    path, camera_name, camera = args.calibration, args.camera_name, args.camera
    p = _calibration_file(path)
    if p.suffix == ".toml":
        raise CliError(f"{p}: --format {fmt} needs a calibration.json (a .toml holds no camera)")
    if is_handeye(p):
        if camera is not None:
            raise CliError(f"--camera {camera}: {p} calibrates one camera", fix="leave it out")
        cam = read_handeye(p)[1].camera
        which = "the calibrated camera"
    elif calibration_kind(p) == "board":
        board = read_board_calibration(p)
        if camera is not None and camera not in board.camera_names:
            raise CliError(f"--camera {camera}: {p} calibrates the cameras "
                           f"{', '.join(board.camera_names)}")  # fmt: skip
        camera = camera or board.camera_names[0]  # named as the message and a bag's topics name it
        cam = board.cameras[board.camera_names.index(camera)]
        which = f"camera {camera}"
    else:
        cam = _field_camera(_usable(read_calibration(p), p), p, camera)
        which = f"camera {camera}" if camera else "the calibrated camera"
    if not isinstance(cam, Pinhole):  # pragma: no cover - every model of selfcal.camera is one
        raise CliError(f"{p}: {which} ({cam.model_name} model) has no pinhole camera matrix K "
                       f"for --format {fmt}")  # fmt: skip
    name = camera_name or camera or "camera"  # camera_info's camera_name: the camera exported
    text = to_opencv_yaml(cam) if fmt == "opencv" else to_camera_info_yaml(cam, name)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out, text)
    written = f"{which} ({cam.model_name} model) as {WRITTEN[fmt]}"
    _say(args, out, written)
    print(json.dumps({"out": str(out), "format": fmt, "written": written,
                      "camera_model": cam.model_name}))  # fmt: skip
    return 0


def _field_camera(cal, p: Path, camera: str | None):
    """The camera ``camera`` (default: the first) of a field calibration: its own intrinsics
    when the rig's cameras have their own (``cameras``), else the shared ones."""
    names = [c.name for c in cal.cameras]
    if camera is None or not names:
        return cal.intrinsics.camera()
    if camera not in names:
        raise CliError(f"--camera {camera}: {p} calibrates the cameras {', '.join(names)}")
    return cal.intrinsics_of(names.index(camera)).camera()


def cmd_ik_calibrated(args: argparse.Namespace) -> int:
    """``selfcal ik --calibration FILE``: joint commands from the calibrated model, as JSON."""
    from selfcal.export.compensate import solve_compensated, solve_compensated_pose
    from selfcal.kinematics.ik import UnreachableError
    from selfcal.kinematics.ik_numeric import ToolTarget

    dep = load_calibration(args.calibration)
    robot = calibration_robot(args.calibration, dep.robot_name)
    pose = parse_pose_args(args, robot)
    try:
        er = pose.pitch_roll
        if er is not None:
            res = solve_compensated(
                dep,
                robot,
                pose.xyz_m,
                er[0],
                er[1],
                reference=pose.reference,
                branch=getattr(args, "branch", None) or None,
            )
        else:
            target = ToolTarget.checked(pose.xyz_m, pose.rotation)
            res = solve_compensated_pose(dep, robot, target, reference=pose.reference)
    except UnreachableError as exc:
        raise CliError(f"unreachable: {exc}") from None
    except ValueError as exc:
        raise CliError(str(exc)) from None
    nominal = None if res.nominal_joints is None else np.degrees(res.nominal_joints)
    print(
        json.dumps(
            {
                "model": robot.name,
                "calibration": str(args.calibration),
                "joints_deg": np.round(np.degrees(res.joints), 6).tolist(),
                "nominal_joints_deg": None if nominal is None else np.round(nominal, 6).tolist(),
                "branch": res.branch,
                "residual_mm": res.position_error_m * 1000.0,
                "residual_deg": float(np.degrees(res.angle_error_rad)),
                "frame": CALIBRATED_FRAME,
            }
        )
    )
    return 0


def _ik_dispatch(original):
    def run(args: argparse.Namespace) -> int:
        if getattr(args, "calibration", None):
            return cmd_ik_calibrated(args)
        if original is None:
            raise CliError("--calibration is required (a calibration.json or exported .toml)")
        return original(args)

    return run


def register(subparsers) -> None:
    """Add ``export`` to the ``selfcal`` subcommands and ``--calibration`` to ``ik``.

    Call it after the ``ik`` command exists (its nominal behaviour is kept without
    ``--calibration``); without one, an ``ik`` command taking only ``--calibration`` is added.
    """
    sp = subparsers.add_parser(
        "export",
        help="calibrated model -> MJCF, URDF or TOML in the robot's base frame; camera -> OpenCV "
        "or ROS camera_info YAML",
        description="Export the calibrated robot (tool = tool tip, world = the robot's base "
        "frame) for MuJoCo, URDF/ROS or as a parameter table.",
        epilog=EXPORT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.add_argument(
        "calibration", help="dataset folder with calibration.json, or the file (or exported .toml)"
    )
    sp.add_argument(
        "--format",
        choices=tuple(FORMATS) + BAG_FORMATS,
        default=None,
        help="mjcf | urdf | toml | opencv | camera_info | tf | easy_handeye | matrix: what to "
        "write, whatever --out's suffix (required without --bag); with --bag: ros1 | ros2 | mcap",
    )
    sp.add_argument(
        "--camera-name",
        default=None,
        help="camera_name of a camera_info file (default: the exported camera's name, --camera's "
        "or a board calibration's first camera's, as a bag's topics name it; else camera)",
    )
    sp.add_argument(
        "--camera", default=None, metavar="NAME",
        help="with --format opencv | camera_info: the camera of a board calibration's rig, or "
        "of a field calibration whose cameras have their own intrinsics, to export, under its "
        "own model (default: the first)",
    )  # fmt: skip
    sp.add_argument(
        "--out",
        default=None,
        help="output file (default by --format, next to the calibration.json: calibrated.xml "
        "/ .urdf / .toml / .yml / .yaml, hand_eye_tf.yaml, hand_eye_easy_handeye.yaml, "
        "hand_eye_matrix.yaml); its name does not choose the format",
    )
    sp.add_argument(
        "--force",
        action="store_true",
        help="export a calibration even when it is no gain over its fair nominal (a board's "
        "cross-validation, or for a board or the marker field the held-out check in "
        "CAL/evaluation.json: `selfcal evaluate CAL DATASET2 --out CAL/evaluation.json`; an "
        "evaluation of another calibration is not used)",
    )
    sp.add_argument(
        "--frames", metavar="BASE,FLANGE,CAMERA,BOARD", help="with --format tf | easy_handeye | matrix: the ROS frame names (default "
        "base_link,tool0,camera_optical_frame,board); BASE and FLANGE are the frames the robot "
        "reports its flange poses in (a UR controller's base is `base`, not `base_link`)",
    )  # fmt: skip
    add_bag_export_args(sp)
    add_json(sp, always=True)
    sp.set_defaults(func=cmd_export)

    ik = subparsers.choices.get("ik")
    original = None
    if ik is None:
        ik = subparsers.add_parser(
            "ik",
            help="inverse kinematics with a calibrated model: joint commands (deg) as JSON",
        )
        add_pose_args(ik, xyz_help="tool point in mm (robot base frame)")
        ik.add_argument("--branch", default=None, help="with --pitch: start from this branch")
    else:
        original = ik.get_default("func")
    ik.add_argument(
        "--calibration",
        default=None,
        metavar="FILE",
        help="solve with the calibrated model of FILE (calibration.json, its dataset folder or an "
        "exported .toml) instead of --robot: joint commands that put the real tool tip on the "
        "target (xyz in the robot's base frame, see docs/deploy.md)",
    )
    ik.set_defaults(func=_ik_dispatch(original))
