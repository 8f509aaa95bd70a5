"""``selfcal plan``: the postures to record for your own arm, wrist camera and board (issue #30):
the command of :mod:`selfcal.calibration.board.plan.planner` (and, with ``--add K DATASET``, of
:mod:`selfcal.calibration.board.plan.add`), writing PLAN/joints.csv, trajectory.yaml,
scenario.toml (with target.toml beside it; replay.csv with --add), plan.json and plan.png (a
camera plan's forecast over draws, :mod:`selfcal.cli.plan_forecast`)."""

from __future__ import annotations

import argparse
import json
import shutil
import warnings
from pathlib import Path

import numpy as np

from selfcal.calibration.board.folds import MIN_FRAMES
from selfcal.calibration.field.failures import MIN_POSTURES
from selfcal.choices import SETUPS
from selfcal.cli import plan_field
from selfcal.cli.plan_add import cmd_add
from selfcal.cli.plan_args import (
    check_common,
    deviation,
    keep_out_boxes,
    plan_inputs,
    trajectory_joint_names,
)
from selfcal.cli.plan_check import CHECK_EPILOG, cmd_check_plan
from selfcal.cli.plan_tracker_add import cmd_tracker_add, is_tracker_dataset
from selfcal.console.common import CliError, add_json, note_written, parse_floats, writing
from selfcal.errors import SelfCalWarning

__all__ = ["register"]

EPILOG = """\
--mount eye-in-hand (default): the camera sits on the flange where the robot file's
[camera_mount] puts it, the board lies still.
--board-pose X,Y,Z[,RX,RY,RZ]: the centre of the printed board in the robot's base frame (mm) and
its rotation from lying printed face up with its columns along the base's x axis (deg, fixed axes
x, y, z: R = Rz Ry Rx); without the rotation the board lies face up.
--mount eye-to-hand: the camera stands still and the board rides on the flange, printed face out
along the flange's z axis, the centre of its features on the flange's axis 50 mm in front of the
flange (as `selfcal run eye-to-hand` mounts it); the calibration then fits base -> camera and
flange -> board.
--camera-pose X,Y,Z[,RX,RY,RZ]: the camera's centre in the base frame (mm) and the rotation of
its OpenCV axes (x right, y down, z along the view) from the base's axes (deg, fixed axes x, y, z:
R = Rz Ry Rx); without the rotation it looks at the board's centre at the robot's home, its
image rows level. The arm keeps 80 mm from the camera and out of its lines of sight to the board;
the board's normal within 45 deg of the optical axis and a feature pitch of at least 24 px (what
the rendered eye-to-hand replay needs to find every corner).
--keep-out XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (mm, base frame; repeat for more boxes): no part of the
arm, the camera on it or the board on it enters the box, and no line of sight crosses it (but a box
around the camera itself). The table the robot stands on (z = 0)
is always kept out.
The plan's postures show the whole board inside the image, the board's normal within 60 deg of the
optical axis, a feature pitch of at least 12 px and every cell of its markers at least 2.5 px across
(eye-in-hand; what the rendered replays need to find every corner), the arm and the keep-out boxes
out of the camera's lines of sight to the board; they are chosen from --candidates random ones to
minimise the board calibration's predicted (Cramer-Rao) tool-point error over the workspace, and
ordered for a short joint path from home. The prediction is that of the calibration with the
parameters its selection's cross-validation is forecast to keep (and, where its one-standard-
error rule may keep the next smaller set, that set's: a range), every other one held at the
drawing and erring by --deviation-mm / --deviation-deg; beside it the prediction with every
parameter the postures identify and that of a random plan of the same size so. The second line
gives the error without calibrating the kinematics for the same postures (the smaller of the
chain as drawn and the fair nominal: eye-in-hand the hand-eye and the board pose fitted to the
pixels, eye-to-hand the camera's pose in the base and the board's on the flange) and says
whether the calibration with the parameters the selection is forecast to keep beats it clearly
(at most 0.7 times it), with the smaller set's figure as a caveat; if not, the count of
postures that would (within 4 times --count). The third line gives the median and the 90th
percentile of the calibration's error over 400 draws of the arm within the deviation and of the
noise, the selection's cross-validation deciding in each, for the plan and the random plan
(seeded with --seed; their Monte Carlo error is 2 - 4 %, plan.json gives it); plan.png draws
both distributions beside the error without calibrating the kinematics. plan.json holds every
figure.
--add K DATASET: instead, the K postures that most lower the predicted error of the calibrated
DATASET of one camera, either mount (its robot file and calibration.json's camera and mounts:
the board pose and the hand-eye, or eye-to-hand the camera's pose in the base and the board's on
the flange, with that mount's view rules; --robot, --target, --mount, --board-pose,
--camera-pose, --count and the camera options are refused), predicted with the parameters the
selection's cross-validation is forecast to keep; PLAN/joints.csv and trajectory.yaml hold the
added postures in the order to record them (it sets the cross-validation's folds), replay.csv the
dataset's and the added ones (scenario.toml replays them); the sixth line and plan.png give the
draws (as above) of the dataset's frames alone and with the added ones; when their medians do
not halve the error with K, a seventh line says so: up to 3 larger counts are planned in turn,
each costing about as much as the plan itself, and the first that does is named (plan.json
halved_with). The error is averaged over
the robot file's planning window, or without one over the dataset's joint region grown by 10 % of
each joint's range; the held parameters' deviation, unless --deviation-mm / --deviation-deg are
given, is sized so that the forecast expects the fair nominal's folds at the misfit the dataset's
calibration measured on them (the third line says which and why; the second the corner noise:
the calibration's estimate from its residuals unless --pixel-sigma is given).
--measure tracker: instead, the postures at which a laser tracker measures a tool point (the
reflector at --tool-point on the flange) for `selfcal identify`: reachable and free of collision
and the keep-out boxes (the tracker's line of sight is not checked), chosen to minimise the
tracker route's predicted tool-point error over the workspace in the tracker frame (its
covariance with the parameters its rank and conditioning tests keep, noise --sigma-mm per
coordinate, exact joints); PLAN/joints.csv (add the measured x_mm,y_mm,z_mm to each row for identify),
trajectory.yaml and plan.json. No camera, board or mount options.
--add K DIR with DIR the folder `selfcal identify` wrote (a tracker calibration; or with
--measure tracker): the K postures, from the same candidates, that most lower its predicted
tool-point error given the rows it has (their joints from its calibration.json), by the same
criterion (before: the parameters it estimated; after: those the route's tests keep at all the
rows), the tracker noise its (--sigma-mm overrides it), the held parameters erring by
--deviation-mm/--deviation-deg; PLAN/joints.csv and trajectory.yaml hold the added postures
(measure them, append the rows to the measurements and identify again), plan.json the
prediction before and after.
"""


BOARD_ON_FLANGE = (
    "printed face out along the flange's z axis, the centre of its features on the flange's "
    "axis 50 mm in front of the flange, its columns along the flange's x axis"
)
"""Where an eye-to-hand plan puts the board (:func:`selfcal.target.placement.board_on_flange`,
as the simulated eye-to-hand cell does)."""


ADD_TAKES_FROM_DATASET = (
    ("--robot", "robot"),
    ("--target", "target"),
    ("--camera", "camera"),
    ("--fov-deg", "fov_deg"),
    ("--resolution", "resolution"),
    ("--board-pose", "board_pose"),
    ("--camera-pose", "camera_pose"),
    ("--count", "count"),
)
"""What a new plan takes and ``--add`` refuses (the dataset and its calibration give them)."""


def _parse_size(text: str) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise CliError(
            f"--resolution {text!r}: expected WIDTHxHEIGHT in px, e.g. 1280x720"
        ) from None
    return w, h


def _camera(args: argparse.Namespace):
    from selfcal.io.camera_file import camera_from_fov, read_camera_file

    if args.camera:
        return read_camera_file(args.camera)
    if args.fov_deg is not None and args.resolution:
        return camera_from_fov(args.fov_deg, *_parse_size(args.resolution))
    raise CliError("give --camera CAMERA.yaml, or --fov-deg DEG and --resolution WxH")


def _pose6(text: str, option: str) -> np.ndarray:
    """X,Y,Z[,RX,RY,RZ] as (6,) mm and deg (a NaN rotation when only the centre is given)."""
    p = parse_floats(text, None, f"{option} (mm, deg)")
    if len(p) not in (3, 6):
        raise CliError(f"{option}: give X,Y,Z (mm) or X,Y,Z,RX,RY,RZ (mm, deg)")
    return np.concatenate([p, np.full(6 - len(p), np.nan)])


def _setup(args: argparse.Namespace, robot, camera, board, boxes):
    """The plan's cell and the pose the user gave, resolved (6,) mm and deg: the board's
    (eye-in-hand, face up without a rotation) or the static camera's (eye-to-hand, looking at
    the board's centre at home without a rotation)."""
    from selfcal.calibration.board.plan.views import PlanSetup
    from selfcal.kinematics.forward import fk_tool
    from selfcal.kinematics.mcpc import nominal_mcpc
    from selfcal.target.placement import (
        board_centre,
        board_on_flange,
        board_pose,
        camera_pose,
        camera_pose_values,
        look_at,
    )

    if args.mount == "eye-in-hand":
        bp = _pose6(args.board_pose, "--board-pose")
        bp = np.where(np.isnan(bp), 0.0, bp)
        T = board_pose(board, bp[:3] / 1000, np.radians(bp[3:]))
        return PlanSetup(robot, camera, board, T, boxes), bp
    cp = _pose6(args.camera_pose, "--camera-pose")
    T_fb = board_on_flange(board)
    if np.isnan(cp[3:]).any():  # look at the board's centre at home, rows level
        T_home = fk_tool(nominal_mcpc(robot).with_tool(T_fb), robot.home[None])[0]
        centre = T_home[:3, :3] @ board_centre(board) + T_home[:3, 3]
        T_bc = look_at(cp[:3] / 1000, centre)
        cp = np.concatenate([cp[:3], np.degrees(camera_pose_values(T_bc)[1])])
    T_bc = camera_pose(cp[:3] / 1000, np.radians(cp[3:]))
    return PlanSetup.eye_to_hand_setup(robot, camera, board, T_bc, T_fb, boxes), cp


def _check_mount(args: argparse.Namespace, mount: str | None) -> None:
    """A clear error for an option the mount does not take, or one it needs (``mount`` the
    ``--mount`` given, None: none), or that ``--add`` takes from the dataset."""
    if args.add:
        given = [o for o, k in ADD_TAKES_FROM_DATASET if getattr(args, k) is not None]
        given = (["--mount"] if mount is not None else []) + given
        if given:
            raise CliError(f"--add takes the robot, the mount, the camera, the board and their "
                           f"poses from the dataset and K as the count: {', '.join(given)} "
                           "would not be used", fix=f"leave out {', '.join(given)} with --add")  # fmt: skip
        return
    e2h = args.mount == "eye-to-hand"
    wrong = [o for o, v in (("--board-pose", args.board_pose if e2h else None),
                            ("--camera-pose", None if e2h else args.camera_pose)) if v]  # fmt: skip
    if wrong:
        raise CliError(
            f"{wrong[0]} does not go with --mount {args.mount}: "
            + ("the board rides on the flange and the camera stands still (--camera-pose)"
               if e2h else "the camera rides on the flange and the board lies still (--board-pose)"),
            fix="give --board-pose with --mount eye-in-hand, --camera-pose with --mount eye-to-hand",
        )  # fmt: skip
    args.count = 12 if args.count is None else args.count
    pose = "--camera-pose" if e2h else "--board-pose"
    missing = [o for o, v in (("--robot", args.robot), ("--target", args.target),
                              (pose, args.camera_pose if e2h else args.board_pose)) if not v]  # fmt: skip
    if missing:
        raise CliError(f"give {', '.join(missing)} (or --add K DATASET to extend a dataset)")


def _cmd(args: argparse.Namespace) -> int:
    from selfcal.acquisition.backends import robot_reference
    from selfcal.calibration.board.folds import PLACEMENT_FRAMES
    from selfcal.calibration.board.plan.planner import plan_recording
    from selfcal.cli.plan_forecast import DrawSet, forecast_draws, write_figure
    from selfcal.cli.plan_scenario import scenario_text
    from selfcal.cli.plan_text import criterion, plan_lines, plan_sections
    from selfcal.config.scenario import load_scenario
    from selfcal.console.progress import Progress
    from selfcal.estimation.joint_report import encoder_sigma
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.plan_files import joints_csv, trajectory_yaml, write_plan
    from selfcal.io.target_toml import load_target
    from selfcal.robot.definition import load_robot
    from selfcal.target.boards import Board

    if args.check is not None:
        return cmd_check_plan(args)
    args.candidates = 400 if args.candidates is None else args.candidates
    args.deviation_given = args.deviation_mm is not None or args.deviation_deg is not None
    args.deviation_mm = 1.0 if args.deviation_mm is None else args.deviation_mm
    args.deviation_deg = 0.5 if args.deviation_deg is None else args.deviation_deg
    if args.add and (args.measure == "tracker" or is_tracker_dataset(args.add[1])):
        return cmd_tracker_add(args, deviation(args))
    if args.measure == "tracker":
        from selfcal.cli.plan_tracker import cmd_tracker

        return cmd_tracker(args, deviation(args))
    given = [o for o, v in (("--tool-point", args.tool_point), ("--sigma-mm", args.sigma_mm))
             if v is not None]  # fmt: skip
    if given:
        raise CliError(f"{', '.join(given)} describe{'s' if len(given) == 1 else ''} a laser "
                       "tracker's measurement, not a camera's",
                       fix="add --measure tracker, or leave them out")  # fmt: skip
    mount, args.mount = args.mount, args.mount or "eye-in-hand"
    args.pixel_sigma_given = args.pixel_sigma is not None  # --add: else the calibration's
    args.pixel_sigma = 0.5 if args.pixel_sigma is None else args.pixel_sigma
    if not args.pixel_sigma > 0:
        raise CliError(f"--pixel-sigma {args.pixel_sigma:g}: the corner noise must be > 0 px",
                       fix="e.g. --pixel-sigma 0.5 (the default)")  # fmt: skip
    if args.target and not args.add and plan_field.is_field(args.target):
        return plan_field.cmd_field(args, _camera, deviation)
    plan_field.check_field_options(args)
    _check_mount(args, mount)
    if args.add:
        return cmd_add(args)
    robot = load_robot(args.robot)
    if args.mount == "eye-in-hand" and not robot.camera_mount_given:
        warnings.warn(
            f"{args.robot}: no [camera_mount] (a URDF never has one), so the plan puts the camera "
            "at the flange, looking along its z axis; a camera mounted elsewhere sees the board "
            "from other postures than planned: give its mount ([camera_mount] xyz_mm, x_axis, "
            "z_axis) in a robot TOML that wraps the URDF ([urdf] file = ...) and plan with that "
            "--robot",
            SelfCalWarning,
            stacklevel=2,
        )
    names = trajectory_joint_names(args, robot.joint_names)
    camera = _camera(args)
    board = load_target(args.target)
    assert isinstance(board, Board)  # a marker field took cmd_field above
    boxes = keep_out_boxes(args)
    if args.count < MIN_FRAMES:
        raise CliError(f"--count {args.count}: a board calibration needs at least {MIN_FRAMES} "
                       f"postures that show the board: {PLACEMENT_FRAMES} place the camera and "
                       "the board (two turns about different axes), and one more lets its "
                       "cross-validation fit them without each posture, so that a kinematic "
                       "parameter can be checked on a posture it was not fitted to",
                       fix=f"give --count {MIN_FRAMES} or more")  # fmt: skip
    check_common(args, args.count)
    setup, pose = _setup(args, robot, camera, board, boxes)
    e2h = setup.eye_to_hand
    js = encoder_sigma(robot)  # the board calibration's default read-back noise
    with Progress("plan", enabled=not (args.quiet or args.json)).step(
        f"choosing {args.count} postures"
    ) as st:
        plan = plan_recording(setup, args.count, seed=args.seed, candidates=args.candidates,
                              pixel_sigma_px=args.pixel_sigma, joint_sigma=js,
                              deviation=deviation(args))  # fmt: skip
        st.result(f"from {plan.candidates} candidates")
    n = len(plan.q)
    fc = forecast_draws(args, setup, plan.workspace, [
        DrawSet("plan", f"the plan of {n}", plan.q),
        DrawSet("random", f"a random plan of {n}", plan.q_random)], js, deviation(args))  # fmt: skip
    # not when the plan is the random plan (the pool's first set, chosen over the greedy choice
    # by the selection's forecast): its draws are the random plan's, equal medians by construction
    behind = None if plan.is_the_random_plan else fc.behind("plan", "random")
    if behind is not None:
        warnings.warn(behind, SelfCalWarning, stacklevel=2)

    out = Path(args.out)
    with writing(args, out):
        write_text_atomic(out / "joints.csv", joints_csv(plan.q, robot.edge_unit))
        speed = args.speed_deg_s * robot.edge_unit  # rad/s, m/s for a prismatic joint
        write_text_atomic(out / "trajectory.yaml", trajectory_yaml(
            names, plan.q, robot.home, speed=speed, dwell_s=args.dwell_s))  # fmt: skip
        shutil.copyfile(args.target, out / "target.toml")
        ref = robot_reference(args.robot)
        write_text_atomic(out / "scenario.toml", scenario_text(
            ref, camera, None if e2h else pose, len(plan.q),
            camera_pose=pose if e2h else None, deviation=deviation(args),
            pixel_sigma=args.pixel_sigma))  # fmt: skip
        load_scenario(out / "scenario.toml")  # what we wrote reads back
        write_figure(fc, plan.reference, f"{robot.name}, {args.mount}: the plan of {n} postures "
                     f"against a random plan of {n}, predicted over {fc.draws} draws of the arm "
                     "and the noise", out / "plan.png")  # fmt: skip
        body = {
            "robot": ref,
            "mount": args.mount,
            "count": len(plan.q),
            "predicted_tool_rms_mm": round(plan.predicted_m * 1000, 4),
            "random_tool_rms_mm": round(plan.random_m * 1000, 4),
            "criterion": criterion(len(plan.workspace), plan.pixel_sigma_px, js, args),
            **plan_sections(plan),
            "forecast_draws": fc.section(),
            "candidates": plan.candidates,
            "candidates_from": plan.drawn_from,
            "path_deg": round(float(np.degrees(plan.path_rad)), 3),
            "random_path_deg": round(float(np.degrees(plan.random_path_rad)), 3),
            "seed": args.seed,
            ("camera_pose_mm_deg" if e2h else "board_pose_mm_deg"): np.round(pose, 6).tolist(),
            **({"board_on_flange": BOARD_ON_FLANGE} if e2h else {}),
            **plan_inputs(args, boxes, robot.edge_unit, plan.q, plan.q_random),
        }
        doc = write_plan(out / "plan.json", "camera", body)
    note_written(args, out)
    print(json.dumps(doc) if args.json else plan_lines(plan) + "\n" + fc.line())
    return 0


def register(subparsers) -> argparse.ArgumentParser:
    """Add ``selfcal plan``."""
    sp = subparsers.add_parser(
        "plan",
        help="plan the postures to record for your own arm, camera and board (or tracker)",
        description="Plan the postures to record for your own arm, camera (on the flange or "
        "still) and board, or for a laser tracker: writes PLAN/joints.csv (selfcal import's "
        "format, deg), trajectory.yaml (a ROS trajectory_msgs/JointTrajectory), scenario.toml "
        "(selfcal run replays a camera plan in simulation), plan.json (the predicted "
        "tool-point error against a random plan) and plan.png (its spread over draws of the "
        "arm and the noise against a random plan's).",
        epilog=EPILOG + CHECK_EPILOG + plan_field.FIELD_EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.add_argument("--robot", default=None,
                    help="robot model name, robot TOML or URDF file (a new plan)")  # fmt: skip
    sp.add_argument("--target", default=None, metavar="TARGET.toml",
                    help="the board's target TOML (docs/targets.md)")  # fmt: skip
    sp.add_argument("--camera", default=None, metavar="CAMERA.yaml",
                    help="the camera: OpenCV or ROS camera_info YAML")  # fmt: skip
    sp.add_argument("--fov-deg", type=float, default=None, metavar="DEG",
                    help="instead of --camera: the horizontal field of view (deg)")  # fmt: skip
    sp.add_argument("--resolution", default=None, metavar="WxH",
                    help="with --fov-deg: the image size in px, e.g. 1280x720")  # fmt: skip
    sp.add_argument("--measure", default="camera", choices=["camera", "tracker"],
                    help="what measures the arm: a camera seeing a board (default) or a laser "
                    "tracker measuring a tool point (selfcal identify); see below")  # fmt: skip
    sp.add_argument("--mount", default=None, choices=SETUPS,
                    help="where the camera is (default eye-in-hand: on the flange, the board "
                    "still; eye-to-hand: still, the board on the flange)")  # fmt: skip
    sp.add_argument("--board-pose", default=None, metavar="X,Y,Z[,RX,RY,RZ]",
                    help="eye-in-hand: the board in the base frame: centre (mm), rotation (deg); "
                    "see below")  # fmt: skip
    sp.add_argument("--camera-pose", default=None, metavar="X,Y,Z[,RX,RY,RZ]",
                    help="eye-to-hand: the static camera in the base frame: centre (mm), "
                    "rotation (deg); see below")  # fmt: skip
    sp.add_argument("--tool-point", default=None, metavar="X,Y,Z",
                    help="--measure tracker: the reflector's centre in the flange frame, mm "
                    "(default 0,0,0)")  # fmt: skip
    sp.add_argument("--sigma-mm", type=float, default=None,
                    help="--measure tracker: the tracker's noise per coordinate, mm (default 0.1; "
                    "with --add to a tracker calibration, the calibration's)")  # fmt: skip
    sp.add_argument("--count", type=int, default=None,
                    help=f"postures to plan (default 12; at least {MIN_FRAMES} with a board, "
                    f"{MIN_POSTURES} with a marker field; not with --add)")  # fmt: skip
    sp.add_argument("--keep-out", action="append", default=[], metavar="BOX",
                    help="XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (mm, base frame); repeatable")  # fmt: skip
    sp.add_argument("--add", nargs=2, default=None, metavar=("K", "DATASET"),
                    help="instead of a new plan: the K postures that most improve the calibrated "
                    "DATASET (its robot, camera, board and calibration.json); see below")  # fmt: skip
    sp.add_argument("--check", nargs=2, default=None, metavar=("K", "CALIBRATION"),
                    help="instead of a new plan: the K postures a drift check (selfcal check) of "
                    "the board calibration CALIBRATION finds most with, by its stated power; "
                    "see below")  # fmt: skip
    sp.add_argument("--out", required=True, metavar="PLAN", help="output folder")
    sp.add_argument("--seed", type=int, default=1, help="seed of the candidates (default 1)")
    sp.add_argument("--candidates", type=int, default=None,
                    help="random candidate postures to choose from (default 400; --check 30)")  # fmt: skip
    sp.add_argument("--pixel-sigma", type=float, default=None,
                    help="a camera plan: the corner noise the prediction assumes, px "
                    "(default 0.5; with --add the dataset's calibration's, from its residuals)")  # fmt: skip
    sp.add_argument("--deviation-mm", type=float, default=None,
                    help="how far the arm's lengths, the mount on the flange's included, may lie "
                    "from its drawing, mm (default 1; with --add sized from the dataset's "
                    "cross-validation, see below; scenario.toml's [perturbation] draws the "
                    "replayed arm from it)")  # fmt: skip
    sp.add_argument("--deviation-deg", type=float, default=None,
                    help="how far its angles may lie from it, deg (default 0.5; with --add "
                    "sized with --deviation-mm)")  # fmt: skip
    sp.add_argument("--speed-deg-s", type=float, default=10.0,
                    help="trajectory.yaml: the fastest joint's speed, deg/s (mm/s for a "
                         "prismatic joint; default 10)")  # fmt: skip
    sp.add_argument("--joint-names", default=None, metavar="N1,N2,...",
                    help="trajectory.yaml: the controller's joint names, one per joint of the "
                    "robot file in its order (default: the robot file's; a FollowJointTrajectory "
                    "goal with names the controller does not know is refused)")  # fmt: skip
    sp.add_argument("--dwell-s", type=float, default=2.0,
                    help="trajectory.yaml: rest at each posture, s (default 2)")  # fmt: skip
    plan_field.add_field_options(sp)
    add_json(sp)
    sp.set_defaults(func=_cmd)
    return sp
