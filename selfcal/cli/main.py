"""``selfcal``: the command line of scorbot-selfcal.

Millimetres and degrees at this edge, SI inside. Every command exits non-zero with a one-line
message naming the problem (and how to fix it) on bad input.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

from selfcal.cli.check import register as register_check
from selfcal.cli.deploy import register as register_deploy
from selfcal.cli.handeye import add_pose_noise_arg
from selfcal.cli.hw import register as register_hw
from selfcal.cli.kinematics import _joints_rad, cmd_fk, cmd_ik
from selfcal.cli.montecarlo import register as register_montecarlo
from selfcal.cli.own_data import register as register_own_data
from selfcal.cli.plan import register as register_plan
from selfcal.cli.pose import POSE_HELP, add_pose_args
from selfcal.cli.ros import export_run
from selfcal.cli.spread import add_spread_args, bootstrap_option
from selfcal.cli.tracker import add_tracker_args
from selfcal.cli.tracker import register as register_tracker
from selfcal.config.defaults import DEFAULT_ROBOT
from selfcal.config.shipped import register as register_shipped
from selfcal.console.common import (
    EXIT_USAGE,
    CliError,
    SelfcalParser,
    add_deprecated,
    add_json,
    add_scenario_arg,
    add_verbosity,
    leaf_parsers,
    note_written,
    run_command,
    writing,
)
from selfcal.console.numpy_extras import defer_numpy_extras
from selfcal.console.progress import Progress
from selfcal.plots.rerun_log import register as register_record
from selfcal.studies.diagnose_render import register as register_diagnose
from selfcal.studies.paper.repro import register as register_paper
from selfcal.studies.study import register as register_study
from selfcal.threads import DEFAULT_THREADS, THREADS_ENV, limit_threads

# The modules a command runs are imported by that command (`selfcal --help` and `selfcal fk`
# stay fast): scipy, OpenCV, MuJoCo, matplotlib load only where used.

__all__ = ["main", "build_parser", "CliError"]


def _existing(root: Path, *names: str) -> list[Path]:
    """The files ``root/NAME`` that exist (what a command wrote among those it may write)."""
    return [root / n for n in names if (root / n).is_file()]


def cmd_render(args: argparse.Namespace) -> int:
    from selfcal.acquisition.backends import render_posture
    from selfcal.config.scenario import load_scenario
    from selfcal.robot.definition import load_robot

    scenario = args.scenario
    model = args.robot or (load_scenario(scenario).robot.model if scenario else DEFAULT_ROBOT)
    robot = load_robot(model)
    q = _joints_rad(robot, args.joints)
    bar = Progress("render", enabled=not args.quiet)
    with bar.step("render the cameras") as st:
        paths = render_posture(robot, q, Path(args.out), config=scenario, model=model)
        st.result(", ".join(p.name for p in paths))
    note_written(args, *paths)
    print(json.dumps({p.stem: str(p) for p in paths}))
    return 0


def _scenario_out(args: argparse.Namespace, s) -> Path:
    """``--out`` or ``runs/<scenario file stem>``."""
    return Path(args.out) if args.out else Path("runs") / Path(s.source).stem


def cmd_acquire(args: argparse.Namespace) -> int:
    from selfcal.config.scenario import load_scenario
    from selfcal.io.dataset import Dataset
    from selfcal.pipeline.run import run_acquire

    s = load_scenario(args.config)
    out = _scenario_out(args, s)
    with writing(args, out):
        run_acquire(s, out, resume=args.resume, quiet=args.quiet)
    note_written(args, out)
    if args.json:
        print(json.dumps({"dataset": str(out), "frames": len(Dataset.open(out).indices)}))
    return 0


def _calibration_json(path: Path) -> dict:
    """The headline numbers of a written calibration.json (``--json`` of calibrate and run)."""
    doc = json.loads(path.read_text())
    ident = doc.get("identification") or {}
    return {
        "calibration": str(path),
        "robot_model": doc.get("robot_model"),
        "method": doc.get("method"),
        "reprojection_rms_px": doc.get("reprojection_rms_px"),
        "rank": ident.get("rank"),
        "n_params": ident.get("n_params"),
        "warnings": doc.get("warnings", []),
        "seconds": doc.get("seconds"),
        "sources": doc.get("sources", ["images"]),
    }


def cmd_calibrate(args: argparse.Namespace) -> int:
    from selfcal.cli.own_data import calibrate_any

    root = Path(args.dataset)
    with writing(args, root, "DATASET", create=False), _stdout_to_stderr(args.json):
        calibrate_any(root, quiet=args.quiet, method=args.method,
                      allow_missing_frames=args.allow_missing_frames, figures=True,
                      tracker_args=args, joint_sigma_deg=args.joint_sigma_deg,
                      pose_noise=args.pose_noise, camera=args.camera,
                      deviation_mm_deg=(args.deviation_mm, args.deviation_deg),
                      bootstrap=bootstrap_option(args))  # fmt: skip
    note_written(args, root / "calibration.json")
    if args.json:
        print(json.dumps(_calibration_json(root / "calibration.json")))
    return 0


def report_label(root: Path) -> str:
    """The progress line of ``selfcal report`` of the calibration in ``root``: a simulated
    dataset (``truth.json``) is checked against the truth on its validation postures, the
    user's own data by its held-out check (:func:`selfcal.pipeline.run.run_report`)."""
    if (root / "truth.json").is_file():
        return "report (validation, figures)"
    return "report (held-out check, figures)"


def cmd_report(args: argparse.Namespace) -> int:
    from selfcal.calibration.field.calibrate import CalibrationFailedError
    from selfcal.calibration.handeye.calibration_file import is_handeye
    from selfcal.calibration.tracker.calibration_file import is_tracker_calibration
    from selfcal.pipeline.handeye_report import handeye_report, handeye_summary

    root = Path(args.dataset)
    as_json = getattr(args, "json", False)  # a namespace built by a caller may lack it
    quiet = args.quiet or as_json
    if is_tracker_calibration(root / "calibration.json"):  # selfcal identify's DIR
        from selfcal.pipeline.tracker_report import tracker_report, tracker_report_summary

        report = tracker_report(root)
        summary = tracker_report_summary(report, root)
    elif is_handeye(root):  # a pose dataset's calibration: the hand-eye, no kinematics
        report = handeye_report(root)
        summary = handeye_summary(report, root)
    else:
        from selfcal.pipeline.run import report_summary, run_report

        with Progress("report", enabled=not quiet).step(report_label(root)) as st:
            report = run_report(root, quiet=quiet, figures=True)
            st.result(report["status"])
        summary = report_summary(report, root)
    note_written(args, *_existing(root, "report.json", "report.md", "table_iv.md"))
    if as_json:
        print(json.dumps(report))
    else:
        print(summary, flush=True)
    if report["failures"]:
        raise CalibrationFailedError.of(tuple(report["failures"]), root / "report.json")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    from selfcal.config.scenario import load_scenario
    from selfcal.plots.figure_pool import run_figure_pool

    s = load_scenario(args.config)
    out = _scenario_out(args, s)
    if args.spawn and not args.rrd:
        raise CliError("--spawn needs --rrd FILE.rrd", fix="add --rrd run.rrd")
    if args.bag and not s.noise.render:
        raise CliError(f"--bag: {s.source} takes no images ([noise] render = false), a bag needs "
                       "them; set render = true")  # fmt: skip
    # A run continues the dataset already in --out when it was taken with the same scenario.
    with writing(args, out):
        # the figure worker forks before the run's imports (0.7 s on one core) and loads
        # matplotlib on the other core meanwhile (selfcal/plots/figure_pool.py)
        with run_figure_pool(s) as pool, _stdout_to_stderr(args.json):
            from selfcal.pipeline.run import run_all

            result = run_all(s, out, resume=True, quiet=args.quiet, method=args.method, pool=pool)
        if args.bag:
            with _stdout_to_stderr(args.json):
                export_run(out, args.bag, args.quiet)
            note_written(args, args.bag)
    note_written(args, out)
    doc: dict = {"out": str(out), **_calibration_json(out / "calibration.json")}
    if "report" in result:
        doc["validation"] = result["report"]["validation"]
    if args.rrd:
        from selfcal.plots.rerun_log import record_run

        rrd = Path(args.rrd)
        record_run(out, rrd, spawn=args.spawn)  # writes rrd (returns None only without one)
        note_written(args, rrd)
        doc["rrd"] = str(rrd)
        if not args.json:
            print(f"Rerun recording: {rrd} (open it with `rerun {rrd}`)")
    if args.json:
        print(json.dumps(doc))
    return 0


@contextlib.contextmanager
def _stdout_to_stderr(active: bool) -> Iterator[None]:
    """With ``--json`` stdout carries the JSON alone: the human summary lines go to stderr."""
    if not active:
        yield
        return
    with contextlib.redirect_stdout(sys.stderr):
        yield


METHODS = ("joint", "two-stage")
METHOD_HELP = (
    "joint (default): the paper's two-stage result refined by one-step maximum likelihood over "
    "all images with the poses from the kinematic chain; two-stage: the paper's method alone"
)

CONFIG_HELP = """\
scenario keys (TOML; every key has a default, units in the names):
  [robot]        model = a robot of models/<folder>/ (er4u-paper, er4u-vendor, ur5e, kr6-r900);
                 backend = "sim" | "hardware"
  [robot.hardware] port (pyserial URL), baudrate, xonxoff, cameras = [left, right], options
                 (see docs/hardware.md; `selfcal emulate SCENARIO` prints a ready snippet)
  [camera]       resolution = [640, 480]; fx = 800.0 (px); mu = 1.0; baseline_mm = 60.0; count = 2;
                 model = "pinhole" | "opencv" | "fisheye"; free = [...]; cx, cy, k1 ... (docs/cameras.md);
                 principal_point_offset_px, skew_px, distortion = {k1 = ...}: the true camera (sim)
  [camera.right] the right camera's own fx, mu, model, principal_point_offset_px, skew_px,
                 distortion, free (its own lens, estimated on its own; scenarios/stereo-lenses.toml)
  [target]       markers = 20; scale_length_mm = 200.0; marker_size_mm = 30.0; seed = 1;
                 board = "TARGET.toml" (a printed board instead of the markers, path relative to
                 the scenario: docs/scenarios.md; example scenarios/mono-charuco.toml);
                 board_pose = [x, y, z, rx, ry, rz] (mm, deg; default: where home looks)
  [perturbation] seed = 1; translation_mm = 1.0; rotation_deg = 0.5; [perturbation.table] name = value
  [trajectory]   poses = 30; seed = 1; min_markers = 6; kind = "random" | "optimal" |
                 "file" with joints = "joints.csv" (the postures of a file, e.g. `selfcal plan`'s)
  [noise]        render = true; image_sigma = 2.0 (0-255); pixel_sigma = 0.5 (px); seed = 1;
                 quantize_joints = true (encoder resolution of the simulated read-back);
                 msaa = 4 (anti-aliasing samples of the rendered images; 0: off, faster)
  [validation]   poses = 20; seed = 2
every key and its valid range: docs/scenarios.md; default scenario: scenarios/paper.toml
"""


def build_parser() -> argparse.ArgumentParser:
    """The ``selfcal`` argument parser."""
    p = SelfcalParser(
        prog="selfcal",
        description="Vision-based self-calibration testbench for camera-equipped robot arms "
        "(SCORBOT ER-4u). Millimetres and degrees on the command line.",
    )
    p.add_argument(
        "--threads",
        type=int,
        default=None,
        metavar="N",
        help=f"BLAS/OpenMP threads per process, also per worker of --jobs (default ${THREADS_ENV} "
        f"or {DEFAULT_THREADS})",
    )
    add_verbosity(p, top=True)
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, func, help_: str, epilog: str | None = None) -> argparse.ArgumentParser:
        sp = sub.add_parser(
            name,
            help=help_,
            description=help_,
            epilog=epilog,
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        sp.set_defaults(func=func)
        return sp

    robot_help = (
        f"robot model name, robot TOML or URDF file (default {DEFAULT_ROBOT}: the [robot] model "
        "of the default scenario)"
    )
    sp = add(
        "fk",
        cmd_fk,
        "forward kinematics: print the tool pose as JSON (xyz_mm, rpy_deg, quat_wxyz; pitch_deg "
        "and roll_deg for an ER-type arm)",
        POSE_HELP,
    )
    sp.add_argument("--robot", default=None, help=robot_help)
    add_deprecated(sp, "--model", "--robot", dest="robot")
    sp.add_argument(
        "--joints",
        required=True,
        help="joint values in deg (mm for a prismatic joint), e.g. 38.15,-30,45,-63.54,0",
    )
    sp.add_argument(
        "--calibration",
        default=None,
        metavar="DIR",
        help="the calibrated model of DIR (calibration.json, its dataset folder or an exported "
        ".toml) instead of the nominal one: the tool tip in the robot's base frame",
    )
    add_json(sp, always=True)

    sp = add("ik", cmd_ik, "inverse kinematics: print joint angles (deg) as JSON", POSE_HELP)
    sp.add_argument("--robot", default=None, help=robot_help)
    add_deprecated(sp, "--model", "--robot", dest="robot")
    add_pose_args(sp, xyz_help="tool point in mm, e.g. 320.8,252.0,182.8")
    sp.add_argument(
        "--branch", default=None, help="with --pitch: a specific solution branch (default: nearest)"
    )
    add_json(sp, always=True)

    sp = add(
        "render",
        cmd_render,
        "render the flange cameras at a posture: OUT/left.png, OUT/right.png (a one-camera "
        "scenario: OUT/left.png alone); prints their paths as JSON (an eye-to-hand scenario is "
        "refused)",
    )
    add_scenario_arg(sp, "for the robot, camera and target")
    sp.add_argument("--robot", default=None, help="robot model (default: the scenario's)")
    add_deprecated(sp, "--model", "--robot", dest="robot")
    sp.add_argument(
        "--joints", required=True, help="joint values in deg (mm for a prismatic joint)"
    )
    sp.add_argument("--out", default="render", help="output folder (default ./render)")
    add_json(sp, always=True)

    sp = add(
        "acquire",
        cmd_acquire,
        "drive the robot along the trajectory into a dataset folder",
        CONFIG_HELP,
    )
    sp.add_argument(
        "config", metavar="SCENARIO", help="scenario TOML or a shipped name (`selfcal scenarios`)"
    )
    sp.add_argument(
        "--out", default=None, help="dataset folder (default runs/<scenario file name>)"
    )
    sp.add_argument("--resume", action="store_true", help="continue an interrupted acquisition")
    add_json(sp)

    sp = add(
        "run",
        cmd_run,
        "acquire, calibrate and report in one go (the main job); continues the dataset already "
        "in --out if it was taken with the same scenario",
        CONFIG_HELP,
    )
    sp.add_argument(
        "config",
        nargs="?",
        default=None,
        metavar="SCENARIO",
        help="scenario TOML or a shipped name (`selfcal scenarios`; default paper)",
    )
    sp.add_argument("--out", default=None, help="output folder (default runs/<scenario file name>)")
    sp.add_argument("--method", choices=METHODS, default="joint", help=METHOD_HELP)
    sp.add_argument("--rrd", default=None, metavar="FILE.rrd", help="record the run for Rerun")
    add_deprecated(sp, "--rerun", "--rrd", dest="rrd")
    sp.add_argument("--spawn", action="store_true", help="with --rrd: also open the viewer")
    add_json(sp)
    sp.add_argument("--bag", default=None, metavar="OUT",
                    help="also write the dataset as a ROS bag (docs/ros.md)")  # fmt: skip

    sp = add(
        "calibrate",
        cmd_calibrate,
        "dataset -> DIR/calibration.json (never reads truth.json); the ArUco field: "
        "self-calibration and its predicted tool-point accuracy (the covariance alone: its model "
        "error is not measured), a board: the board calibration, its predicted tool-point "
        "accuracy and the tool point's run-to-run spread over its folds (docs/tool-accuracy.md; "
        "--method applies to the field)",
    )
    sp.add_argument("dataset", help="dataset folder (the output goes into it)")
    sp.add_argument("--method", choices=METHODS, default="joint", help=METHOD_HELP)
    sp.add_argument(
        "--allow-missing-frames",
        action="store_true",
        help="calibrate without the planned frames that have no whole joints.csv row (listed in "
        "a warning); without it they are an error",
    )
    sp.add_argument(
        "--joint-sigma-deg",
        type=float,
        default=None,
        metavar="SIGMA",
        help="standard deviation of a joint reading, deg (mm for a prismatic joint): the "
        "read-back errors are estimated with the rest instead of taken as exact (default: the "
        "robot file's encoder resolution; none for a URDF, where noisy readings bias the camera)",
    )
    sp.add_argument("--deviation-mm", type=float, default=None, metavar="MM",
                    help="a board dataset: how far the arm's lengths may lie from its drawing, "
                    "mm (default 1): the predicted accuracy counts the parameters the calibration "
                    "holds at the robot file's values as uniform within +-MM "
                    "(docs/tool-accuracy.md); as `selfcal plan --deviation-mm`")  # fmt: skip
    sp.add_argument("--deviation-deg", type=float, default=None, metavar="DEG",
                    help="a board dataset: how far its angles may lie from it, deg (default 0.5)")  # fmt: skip
    add_pose_noise_arg(sp)
    add_spread_args(sp)
    add_tracker_args(sp)
    add_json(sp)

    sp = add(
        "report",
        cmd_report,
        "calibration (+ truth.json in simulation) -> DIR/report.json, report.md, validation.csv "
        "and DIR/figures/*.png; without truth (real data): the fit, a held-out check (DIR/"
        "evaluation.json or leave every 5th pose out), the sigmas and the identifiability; of a "
        "pose dataset: the hand-eye and board mount with sigmas beside the nominal, the fit and "
        "DIR/evaluation.json's held-out check (no kinematics identified); of `selfcal "
        "identify`'s DIR: the predicted tool-point error over the workspace; a field or board "
        "calibration's too (DIR/figures/workspace_accuracy.png, docs/tool-accuracy.md)",
    )
    sp.add_argument("dataset", help="dataset folder (or the DIR of `selfcal identify`)")
    add_json(sp)

    for register in (
        register_hw,
        register_paper,
        register_study,
        register_record,
        register_deploy,
        register_montecarlo,
        register_tracker,
        register_check,
        register_own_data,
        register_plan,
        register_diagnose,
        register_shipped,
    ):
        register(sub)
    for leaf in leaf_parsers(p):
        add_verbosity(leaf)
    return p


def main(argv: list[str] | None = None) -> int:
    """The command line ``argv`` (default ``sys.argv[1:]``) run; returns the exit code (README
    "Exit codes": 0 ok, 1 internal error, 2 bad input or usage, 3 cannot calibrate, 4 hardware,
    5 / 6 ``selfcal check``'s changed / cannot tell, 130 Ctrl-C, 141 the output's reader gone).
    The console script is :func:`script`."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or a usage error (2, printed by SelfcalParser)
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    args.argv = list(sys.argv[1:] if argv is None else argv)  # names the writer in a lock
    return run_command(_limited(args.func), args)


def _limited(
    func: Callable[[argparse.Namespace], int | None],
) -> Callable[[argparse.Namespace], int | None]:
    """``func`` after limiting the BLAS/OpenMP threads to ``--threads`` (a bad value is an
    ``InputError`` that :func:`run_command` reports like any other) and deferring numpy's
    subpackages that scipy's import would load unused
    (:func:`selfcal.console.numpy_extras.defer_numpy_extras`)."""

    def run(args: argparse.Namespace) -> int | None:
        defer_numpy_extras()
        limit_threads(args.threads)
        return func(args)

    return run


def script() -> int:
    """The ``selfcal`` console script: :func:`main`, then every object left moved to the garbage
    collector's permanent generation (:func:`gc.freeze`), which the interpreter's exit then does
    not walk (after ``selfcal run`` its collections took 0.12 s of CPU, 0.025 s frozen, at the
    end of the command's wall time; issue 32). Exit handlers and flushes run as before; a
    caller of :func:`main` in its own process (tests, studies) keeps collecting."""
    code = main()
    gc.freeze()
    return code


if __name__ == "__main__":
    sys.exit(script())
