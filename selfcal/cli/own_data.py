"""``selfcal import`` and ``selfcal evaluate``, and the target dispatch of ``selfcal calibrate``.

Your own data (docs/own-data.md): images of N >= 1 cameras, joint readings and a printed board
become a dataset folder (:mod:`selfcal.importing.dataset`); ``calibrate`` runs the self-calibration
for the ArUco field and the board calibration (:mod:`selfcal.calibration.board.dataset`) for a board;
``evaluate`` predicts a held-out dataset with the calibration (:mod:`selfcal.calibration.board.evaluate`).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from selfcal.cli.handeye import (
    add_pose_import_args,
    calibrate_poses,
    check_pose_only_args,
    cmd_import_poses,
    evaluate_poses,
)
from selfcal.cli.ros import add_import_args as add_bag_import_args
from selfcal.cli.ros import cmd_import_bag, cmd_import_bag_poses
from selfcal.console.common import CliError, add_json, note_written, writing
from selfcal.console.progress import Progress

if TYPE_CHECKING:
    from selfcal.pipeline.board_spread import BootstrapRun

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.

__all__ = ["calibrate_any", "deviation_option", "register"]


def _say(quiet: bool, text: str) -> None:
    if not quiet:
        print(text, file=sys.stderr)


def deviation_option(root: Path, route: str, mm: float | None, deg: float | None):
    """The board route's :class:`selfcal.calibration.board.deviation.Deviation` of
    ``--deviation-mm``/``--deviation-deg`` (None when neither is given).

    Raises:
        CliError: given for another route, or negative or not finite.
    """
    if mm is None and deg is None:
        return None
    if route != "board":
        raise CliError(f"{root}: --deviation-mm/--deviation-deg apply to a board dataset's "
                       "predicted accuracy (the parameters it holds at the drawing)",
                       fix="leave them out")  # fmt: skip
    import numpy as np

    from selfcal.calibration.board.deviation import Deviation

    d = Deviation()
    mm = 1e3 * d.translation_m if mm is None else mm
    deg = float(np.degrees(d.rotation_rad)) if deg is None else deg
    if not (np.isfinite(mm) and np.isfinite(deg) and mm >= 0 and deg >= 0):
        raise CliError(f"--deviation-mm {mm:g} and --deviation-deg {deg:g} must be finite and "
                       ">= 0", fix="e.g. --deviation-mm 1 --deviation-deg 0.5")  # fmt: skip
    return Deviation(mm / 1e3, float(np.radians(deg)))


def calibrate_any(
    root: Path,
    *,
    quiet: bool = False,
    method: str = "joint",
    allow_missing_frames: bool = False,
    figures: bool = False,
    tracker_args: argparse.Namespace | None = None,
    joint_sigma_deg: float | None = None,
    pose_noise: str | None = None,
    camera: str | None = None,
    deviation_mm_deg: tuple[float | None, float | None] = (None, None),
    bootstrap: BootstrapRun | None = None,
) -> None:
    """Calibrate the dataset in ``root`` by its target and write ``root/calibration.json``:
    the field -> :func:`selfcal.pipeline.run.run_calibrate`; a board -> the board calibration.
    ``figures``: also ``root/figures/reprojection.png``. ``tracker_args``: the parsed
    measurement options of ``selfcal calibrate`` (:func:`selfcal.cli.tracker.add_tracker_args`:
    ``--tracker ...`` and ``--term KIND=FILE[,NAME=VALUE ...]``, any kind of
    :mod:`selfcal.terms.registry`): measurements estimated with the images of the field or of a
    board dataset with joint readings. ``joint_sigma_deg``: the standard deviation
    of a joint reading, deg (mm for a prismatic joint), modelled instead of the robot file's
    encoder resolution. ``pose_noise``, ``camera``: ``--pose-noise`` and ``--camera`` of a pose
    dataset (errors for the others). ``deviation_mm_deg``: ``--deviation-mm`` and
    ``--deviation-deg`` of a board dataset (None: the default; errors for the others).
    ``bootstrap``: ``--spread N`` of a board dataset (:mod:`selfcal.cli.spread`; an error for
    the others)."""
    specs = list(getattr(tracker_args, "term", None) or [])
    from selfcal.terms.registry import parse_term_spec

    parsed = [parse_term_spec(spec) for spec in specs]  # a bad kind or name stops before any work
    from selfcal.calibration.routes import dataset_route
    from selfcal.io.dataset import Dataset
    from selfcal.pipeline.board_run import calibrate_board_run
    from selfcal.pipeline.run import run_calibrate

    route = dataset_route(root)  # the choice the public API's calibrate makes
    if route == "handeye" and specs:  # before the terms' values, which it makes moot
        raise CliError(f"{root} is a pose dataset (flange poses, no joint readings): --term "
                       "needs the joints of a chain",
                       fix="leave out --term, or calibrate a dataset with joint readings")  # fmt: skip
    units = {"joint_units": getattr(tracker_args, "joint_units", None)}
    for p in parsed:  # the values next (units, numbers), still before any work
        p.options(units)
    deviation = deviation_option(root, route, *deviation_mm_deg)
    if bootstrap is not None and route != "board":
        raise CliError(f"{root}: --spread N refits a board dataset; this one is a {route} "
                       "dataset", fix="leave out --spread")  # fmt: skip
    if route == "handeye":
        calibrate_poses(root, quiet=quiet, figures=figures, method=method,
                        joint_sigma_deg=joint_sigma_deg, tracker_args=tracker_args,
                        pose_noise=pose_noise, camera=camera)  # fmt: skip
        return
    if pose_noise is not None:
        raise CliError(f"{root}: --pose-noise applies to a pose dataset (flange poses); this one "
                       "has joint readings", fix="leave --pose-noise out")  # fmt: skip
    if camera is not None:
        raise CliError(f"{root}: --camera (held or refined) applies to a pose dataset's hand-eye "
                       "(flange poses); this one has joint readings and its camera is estimated "
                       "with the rest", fix="leave --camera out")  # fmt: skip
    ds = Dataset.open(root)
    if bootstrap is not None and len(ds.info.cameras) > 1:
        raise CliError(f"{root}: --spread N refits one camera's images; this dataset has "
                       f"{len(ds.info.cameras)} cameras (a rig's refit is not written yet)",
                       fix="leave out --spread: calibration.json accuracy.spread holds the "
                       "jackknife over the folds")  # fmt: skip
    joint_sigma = None
    if joint_sigma_deg is not None:
        import numpy as np

        from selfcal.robot.definition import load_robot

        if not (np.isfinite(joint_sigma_deg) and joint_sigma_deg > 0):
            raise CliError(f"--joint-sigma-deg must be a finite number > 0, got {joint_sigma_deg}",
                           fix="give the read-back noise of a joint, e.g. 0.003")  # fmt: skip
        if route == "field" and method != "joint":
            raise CliError("--joint-sigma-deg is modelled by the one-step method of the field",
                           fix="leave out --method two-stage")  # fmt: skip
        types = load_robot(ds.robot_source).joint_types
        joint_sigma = np.array([np.radians(joint_sigma_deg) if t == "revolute"
                                else joint_sigma_deg / 1000.0 for t in types])  # fmt: skip
    terms = []
    if tracker_args is not None and (tracker_args.tracker or specs):
        from selfcal.cli.tracker import tracker_input
        from selfcal.robot.definition import load_robot
        from selfcal.terms.registry import term_from_spec

        if route == "field" and method != "joint":
            raise CliError(
                "--tracker and --term need the one-step method (--method joint, the default)",
                fix="leave out --method two-stage",
            )
        robot = load_robot(ds.robot_source)
        if tracker_args.tracker:
            terms.append(tracker_input(tracker_args, robot))
        else:
            tracker_input(tracker_args, None)  # options that need --tracker are errors
        units = {"joint_units": tracker_args.joint_units}
        terms += [term_from_spec(spec, robot, units) for spec in specs]
    elif tracker_args is not None:
        from selfcal.cli.tracker import tracker_input

        tracker_input(tracker_args, None)  # options that need --tracker are errors
    if route == "field":
        res = run_calibrate(root, quiet=quiet, method=method,
                            allow_missing_frames=allow_missing_frames, figures=figures,
                            terms=terms, joint_sigma=joint_sigma)  # fmt: skip
        for section in res.terms:
            _say(quiet, section.summary())
        return
    board = calibrate_board_run(root, quiet=quiet, allow_missing_frames=allow_missing_frames,
                                figures=figures, joint_sigma=joint_sigma, terms=terms,
                                deviation=deviation, bootstrap=bootstrap)  # fmt: skip
    for section in board.terms:
        _say(quiet, section.summary())


def cmd_import(args: argparse.Namespace) -> int:
    source = args.bag[0] if args.bag else (args.joints or args.poses)
    args.out = args.out or (f"runs/import-{Path(source).stem}" if source else None)
    if args.out is None:
        return _import(args)
    with writing(args, args.out):  # one writer per dataset folder (a second import stops, exit 2)
        return _import(args)


def _import(args: argparse.Namespace) -> int:
    if args.poses:
        return cmd_import_poses(args)
    if args.tf_parent or args.tf_child:
        if not args.bag:
            raise CliError("--tf-parent and --tf-child read the flange poses of a --bag",
                           fix="give the bag with --bag, or the poses as a file with --poses")  # fmt: skip
        return cmd_import_bag_poses(args)
    # --setup with --joints too: where the camera is (the board route's chain)
    check_pose_only_args(args, allowed=() if args.bag else ("setup",))
    if not args.robot:
        raise CliError(f"import {'--bag' if args.bag else '--joints'} needs --robot",
                       fix="name the robot: --robot ur5e, a robot TOML or a URDF (or give "
                       "flange poses with --poses)")  # fmt: skip
    if args.bag:
        return cmd_import_bag(args)
    if not args.images or not args.joints or not args.joint_units:
        raise CliError("import needs --images, --joints and --joint-units (or --poses, or --bag)")

    from selfcal.importing.camera_choice import camera_options
    from selfcal.importing.dataset import CameraImages, detection_summary, import_dataset

    cams = [CameraImages.parse(s, default_name=f"cam{k}") for k, s in enumerate(args.images)]
    models, frees = camera_options(args.camera_model, args.free, [c.name for c in cams], "--images")
    info = import_dataset(
        args.robot, cams, args.joints, args.joint_units, args.target, args.out,
        base_link=args.base_link, tool_link=args.tool_link, link=args.link,
        trust_units=args.trust_units, camera_model=models, free=frees,
        progress=Progress("detect", enabled=not (args.quiet or args.json)),
        setup=args.setup or "eye-in-hand",
    )  # fmt: skip
    n = len(info.planned_joints_deg)
    note_written(args, args.out)
    if args.json:
        print(json.dumps({"dataset": str(args.out), "frames": n, "cameras": list(info.cameras),
                          "detection": info.provenance.get("detection")}))  # fmt: skip
    else:
        print(f"{detection_summary(info)}; imported {n} frames of {len(info.cameras)} camera(s) "
              f"into {args.out}")  # fmt: skip
    return 0


def cmd_evaluate(args: argparse.Namespace) -> int:
    from selfcal.calibration.board.evaluate import Evaluation, write_evaluation
    from selfcal.calibration.field.calibrate import CalibrationFailedError
    from selfcal.calibration.routes import calibration_route, evaluate

    cal_path = Path(args.calibration)
    cal_dir = cal_path if cal_path.is_dir() else cal_path.parent
    if calibration_route(cal_path) == "handeye":
        evaluate_poses(args)
        return 0
    ev = evaluate(cal_path, args.dataset)  # the public API's evaluate: the same choice
    assert isinstance(ev, Evaluation)  # a joint dataset's calibration
    _warn_shared_postures(cal_dir, Path(args.dataset))
    out = Path(args.out) if args.out else Path(args.dataset) / "evaluation.json"
    write_evaluation(out, ev)
    note_written(args, out)
    print(json.dumps({"evaluation": str(out), **ev.to_json()}) if args.json else ev.line())
    beside = cal_dir / "evaluation.json"
    if out.resolve() != beside.resolve():  # the README's commands wrote it elsewhere: not used
        _say(getattr(args, "quiet", False),
             f"note: selfcal report and export read {beside}, not {out}; for them to use this "
             f"held-out check: selfcal evaluate {args.calibration} {args.dataset} --out {beside}")  # fmt: skip
    if ev.failures:
        raise CalibrationFailedError.of(ev.failures, out)
    return 0


def _warn_shared_postures(cal_dir: Path, held_out: Path) -> None:
    """An :class:`selfcal.calibration.board.evaluate.EvaluationWarning` when the held-out dataset repeats postures
    of the calibration's own dataset (``cal_dir``, when it is one)."""
    import warnings

    from selfcal.calibration.board.evaluate import EvaluationWarning, shared_postures
    from selfcal.io.dataset import Dataset

    if not (cal_dir / "dataset.json").is_file():
        return
    q_cal, q_held = Dataset.open(cal_dir).joints_deg, Dataset.open(held_out).joints_deg
    n = shared_postures(q_cal, q_held)
    if n:
        warnings.warn(
            f"{n} of {len(q_held)} postures of {held_out} are postures of the calibration's own "
            f"dataset {cal_dir}: on them the evaluation measures the fit, not the prediction of "
            "new postures; a held-out check needs postures the calibration did not see",
            EvaluationWarning,
            stacklevel=2,
        )


IMPORT_HELP = """\
joints file: CSV with the header j1,...,jn (optionally an image column with the file name), or
n numbers per row without a header (comma or whitespace); rows match the images in sorted
file-name order, or by the image column. Target TOML: docs/targets.md. See docs/own-data.md.
poses file (--poses, instead of joints): base -> flange per image, x_mm,y_mm,z_mm + the columns
of --rotation, or industrial_calibration's cal_data.yaml; with --setup. See docs/handeye.md.
"""


def register(subparsers) -> None:
    """Add ``import`` and ``evaluate`` to the ``selfcal`` subcommands."""
    from selfcal.choices import CAMERA_MODELS, DEFAULT_FREE, JOINT_UNITS

    sp = subparsers.add_parser(
        "import",
        help="your own images + joint readings (or flange poses) + board -> a dataset folder "
        "(no truth)",
        description="Check and import your own data as a dataset folder.",
        epilog=IMPORT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.add_argument(
        "--robot",
        default=None,
        help="model name, robot TOML or URDF file (needed with --joints or --bag)",
    )
    sp.add_argument("--base-link", default=None, help="a URDF's base link (default: its root)")
    sp.add_argument("--tool-link", default=None, help="a URDF's tool link (default: its leaf)")
    sp.add_argument(
        "--images", action="append", default=None, metavar="NAME=GLOB",
        help="one camera's images, e.g. 'cam0=DIR/*.png' (quote it; repeat per camera)",
    )  # fmt: skip
    sp.add_argument("--joints", default=None, help="joints file (CSV)")
    sp.add_argument("--joint-units", default=None, choices=JOINT_UNITS)
    sp.add_argument("--target", required=True, help="target TOML (docs/targets.md)")
    sp.add_argument(
        "--out", default=None, help="new dataset folder (default runs/import-<joints file name>)"
    )
    sp.add_argument("--link", action="store_true", help="link the images instead of copying")
    sp.add_argument(
        "--trust-units", action="store_true",
        help="degrees that stay within +-6.3 deg are degrees (skip the radians-looking check)",
    )  # fmt: skip
    sp.add_argument(
        "--camera-model", action="append", default=None, metavar="[NAME=]MODEL",
        help=f"the cameras' model, one of {', '.join(CAMERA_MODELS)} (default opencv: "
        "Brown-Conrady distortion, what a real lens needs; a pinhole fitted to a distorting "
        "lens is biased; fisheye for wide angles; with --bag: from a calibrated camera_info if "
        "there is one); NAME= sets one camera's (repeat per camera, e.g. cam1=fisheye), a bare "
        "MODEL every camera not named",
    )  # fmt: skip
    sp.add_argument(
        "--free", action="append", default=None, metavar="[NAME=]NAMES",
        help="comma list of the camera parameters to estimate, OpenCV names (default: "
        + "; ".join(f"{m}: {','.join(f)}" for m, f in DEFAULT_FREE.items())
        + "; k3 only on request); NAME= sets one camera's (repeat per camera, e.g. "
        "'cam1=fx,mu,cx,cy,k1,k2,k3,k4'), a bare list every camera not named; fy may stand for mu",
    )  # fmt: skip
    add_pose_import_args(sp)
    add_bag_import_args(sp)
    add_json(sp)
    sp.set_defaults(func=cmd_import)

    sp = subparsers.add_parser(
        "evaluate",
        help="held-out check: predict DATASET2's features with the calibration",
        description="Predict every detected feature of DATASET2 from its joint readings (or its "
        "flange poses) with the calibrated model and with the nominal; write evaluation.json.",
    )
    add_json(sp)
    sp.add_argument("calibration", help="calibrated dataset folder (or its calibration.json)")
    sp.add_argument("dataset", help="held-out dataset folder (same robot, camera and board)")
    sp.add_argument(
        "--out", default=None,
        help="default DATASET/evaluation.json; selfcal report and export read "
        "CALIBRATION/evaluation.json: --out there for them to use this check",
    )  # fmt: skip
    sp.set_defaults(func=cmd_evaluate)
