"""``selfcal identify`` and ``selfcal predict``: kinematic calibration from tracker measurements.

- ``selfcal identify MEASUREMENTS.csv --robot ROBOT --joint-units deg|rad --out DIR
  [--distances FILE]``: fit the robot's MCPC chain, the tracker-to-base transform and the tool
  point to the measured tool-point positions (or poses); writes ``DIR/calibration.json``
  (:mod:`selfcal.calibration.tracker.calibration_file`) and ``DIR/residuals.csv``; prints the fit RMS beside the
  fair nominal's (:mod:`selfcal.calibration.tracker.nominal`) and both k-fold held-out RMS
  (:mod:`selfcal.calibration.tracker.cross_validation`).
- ``selfcal predict DIR --joints FILE --joint-units deg|rad [--out predicted.csv]``: the tool
  point in the tracker frame for every joints row (stdout without ``--out``), and the tool
  orientation when the fit used poses; ``--measurements FILE`` instead of ``--joints``: held-out
  rows, each with the error of the calibration and of the fair nominal
  (:mod:`selfcal.calibration.tracker.nominal`), their RMS on stderr.

File formats: :mod:`selfcal.io.tracker` and docs/tracker.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from selfcal.console.common import CliError, add_json, note_written
from selfcal.console.log import get_logger

if TYPE_CHECKING:
    from selfcal.calibration.tracker.identify import TrackerMeasurements

# Heavy modules (scipy, OpenCV, MuJoCo, the pipeline) are imported by the functions that use
# them, so that `selfcal --help` builds every command's parser without loading them.
__all__ = [
    "register",
    "cmd_identify",
    "cmd_predict",
    "add_tracker_args",
    "tracker_input",
]

IDENTIFY_HELP = """\
MEASUREMENTS.csv: header j1..jn,x_mm,y_mm,z_mm (tool point in the tracker frame, mm), optionally
qw,qx,qy,qz (tool orientation, unit quaternion; columns in any order, e.g. qx,qy,qz,qw): one row
per measured configuration (a pose sensor's rows are poses).
--distances FILE: header a_j1..a_jn,b_j1..b_jn,d_mm: the distance between the tool point at two
configurations (ball bar, a known length).
--joint-units deg: revolute joints in degrees, prismatic in mm; rad: radians and metres.
writes DIR/calibration.json (estimates with std, the identifiable set, rank, condition number,
and the fair nominal: the robot file's chain with the tracker frame and the tool fitted) and
DIR/residuals.csv; prints both fits and their k-fold held-out RMS (one configuration left out
at a time, up to 10 folds; NO GAIN when the calibration predicts no better); see docs/tracker.md
"""


UNITS_HELP = "deg: revolute joints in degrees, prismatic in mm; rad: radians and metres"
TRUST_HELP = (
    "skip the check that degrees look like radians (every revolute reading within +-2 pi): "
    "for data whose joints really stay within +-6.3 deg; the range check stays"
)


def _out_dir(path: str) -> Path:
    from selfcal.calibration.tracker.calibration_file import is_tracker_calibration
    from selfcal.io.outlock import prepare_folder

    out = Path(path)
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out}: exists and is not a folder", fix="give a folder")
    cal = out / "calibration.json"
    if cal.exists() and not is_tracker_calibration(cal):
        raise CliError(
            f"{cal} exists and is not a tracker calibration (it would be overwritten)",
            fix="give another --out folder",
        )
    return prepare_folder(out)  # below a file, or where no folder can be made: named


def _residuals_csv(table, res, meas: TrackerMeasurements) -> str:
    """Model minus measurement of every position / pose row, tracker frame, mm."""

    r = (res.predict(meas.q) - meas.xyz) * 1e3
    lines = ["row,line,dx_mm,dy_mm,dz_mm,error_mm"]
    for i, (line, e) in enumerate(zip(table.lines, r)):
        lines.append(f"{i + 1},{line},{e[0]:.6f},{e[1]:.6f},{e[2]:.6f},{np.linalg.norm(e):.6f}")
    return "\n".join(lines) + "\n"


def _check_sigmas(*named: tuple[str, float]) -> None:
    for name, v in named:
        if not (np.isfinite(v) and v > 0):
            raise CliError(f"{name} must be a positive number, got {v}")


def add_tracker_args(sp: argparse.ArgumentParser) -> None:
    """``selfcal calibrate``'s options for tracker measurements estimated with the images."""
    from selfcal.choices import JOINT_UNITS

    sp.add_argument(
        "--tracker",
        default=None,
        metavar="FILE",
        help="tracker measurements of the same robot to estimate with the images in one "
        "calibration (method joint): header j1..jn,x_mm,y_mm,z_mm (tool point in the tracker "
        "frame), optionally qw,qx,qy,qz (poses), one row per measured configuration, as "
        "`selfcal identify` reads (docs/tracker.md); calibration.json then records both sources "
        "and the tracker frame and tool point estimated with the kinematics",
    )
    sp.add_argument(
        "--tracker-distances",
        default=None,
        metavar="FILE",
        help="ball-bar distances too (header a_j1..a_jn,b_j1..b_jn,d_mm; docs/tracker.md)",
    )
    sp.add_argument(
        "--joint-units",
        default=None,
        choices=JOINT_UNITS,
        help=f"of the tracker files' joints (needed with --tracker; --term's joint_units "
        f"unless it gives its own): {UNITS_HELP}",
    )
    sp.add_argument(
        "--term",
        action="append",
        default=None,
        metavar="KIND=FILE[,NAME=VALUE...]",
        help="further measurements of the same robot estimated with the images (field or "
        "board dataset with joint readings), any registered kind with its own options, e.g. "
        "--term probe=touches.csv,sigma_mm=0.02 (touch-probe points) or --term "
        "tracker=positions.csv,distances=bar.csv (--tracker's spelling); repeat for more "
        "kinds; the kinds, their files and options: docs/terms.md; calibration.json records "
        "each one's section",
    )
    sp.add_argument(
        "--tracker-sigma-mm",
        type=float,
        default=None,
        metavar="MM",
        help="tracker position / distance noise, mm (0.1); weighs the tracker against the images",
    )
    sp.add_argument(
        "--tracker-sigma-deg",
        type=float,
        default=None,
        metavar="DEG",
        help="orientation noise of tracker poses, deg (0.01)",
    )


def tracker_input(args: argparse.Namespace, robot):
    """The :class:`selfcal.terms.tracker.TrackerTerm` of ``selfcal calibrate``'s tracker options
    for ``robot``, or None without ``--tracker``.

    Raises:
        CliError: ``--tracker-distances`` or ``--joint-units`` without ``--tracker``, no
            ``--joint-units`` with it, or a noise that is not a positive number.
        InputError: a file that cannot be read (named with row and column).
    """
    from selfcal.terms.tracker import TrackerTerm

    if not args.tracker:
        units = None if getattr(args, "term", None) else args.joint_units  # --term's default
        for opt, v in (("--tracker-distances", args.tracker_distances),
                       ("--joint-units", units)):  # fmt: skip
            if v:
                raise CliError(
                    f"{opt} needs --tracker FILE", fix=f"add --tracker or leave out {opt}"
                )
        for opt, v, name in (("--tracker-sigma-mm", args.tracker_sigma_mm, "sigma_mm"),
                             ("--tracker-sigma-deg", args.tracker_sigma_deg, "sigma_deg")):  # fmt: skip
            if v is not None:  # it would weigh nothing: say so rather than ignore it
                raise CliError(
                    f"{opt} needs --tracker FILE (a --term takes its noise as its own option)",
                    fix=f"add --tracker, or give --term tracker=FILE,{name}={v:g}",
                )
        return None
    if args.joint_units is None:
        raise CliError(
            "--tracker needs --joint-units deg|rad (the units of the tracker file's joints)",
            fix="add --joint-units deg (degrees, prismatic mm) or --joint-units rad",
        )
    default = {o.name: o.default for o in TrackerTerm.OPTIONS}  # the term's own defaults
    sigma = {name: float(str(default[name]) if given is None else given)
             for name, given in (("sigma_mm", args.tracker_sigma_mm),
                                 ("sigma_deg", args.tracker_sigma_deg))}  # fmt: skip
    _check_sigmas(("--tracker-sigma-mm", sigma["sigma_mm"]),
                  ("--tracker-sigma-deg", sigma["sigma_deg"]))  # fmt: skip
    # --tracker is a spelling of --term tracker=FILE: the term reads its file the same way
    return TrackerTerm.from_file(args.tracker, robot, {"joint_units": args.joint_units,
                                                       "distances": args.tracker_distances,
                                                       **sigma})  # fmt: skip


def cmd_identify(args: argparse.Namespace) -> int:
    from selfcal.calibration.tracker.calibrate import calibrate_tracker
    from selfcal.calibration.tracker.calibration_file import write_tracker_calibration
    from selfcal.calibration.tracker.identify import stated_noise_note
    from selfcal.calibration.tracker.spread import spread_line
    from selfcal.io.atomic import write_text_atomic
    from selfcal.kinematics.tool_error import accuracy_line

    _check_sigmas(("--sigma-mm", args.sigma_mm), ("--sigma-deg", args.sigma_deg))
    if args.spread < 0:
        raise CliError(f"--spread {args.spread}: give a number of resamplings >= 0",
                       fix="e.g. --spread 50")  # fmt: skip
    hold = tuple(h for h in (args.hold or "").replace(" ", "").split(",") if h)
    run = calibrate_tracker(args.measurements, args.robot, args.joint_units,
                            distances=args.distances, sigma_mm=args.sigma_mm,
                            sigma_deg=args.sigma_deg, hold=hold, trust_units=args.trust_units,
                            spread=args.spread)  # fmt: skip
    out = _out_dir(args.out or f"runs/identify-{Path(args.measurements).stem}")  # after the input
    res, cal, fair, cv = run.result, run.calibration, run.nominal, run.cross_validation
    meas, table = run.measurements, run.table
    path = write_tracker_calibration(out / "calibration.json", cal)
    note_written(args, path)
    if meas.m:
        write_text_atomic(out / "residuals.csv", _residuals_csv(table, res, meas))
        note_written(args, out / "residuals.csv")
    kinds = " + ".join(res.kinds)
    if (note := stated_noise_note(res, args.sigma_mm)) is not None:
        get_logger(__name__).warning("%s", note)
    if args.json:
        print(json.dumps(_identify_json(res, meas, cal, path)))
        return 0
    if meas.m:
        what = "poses" if meas.R is not None else "positions"
        deg = meas.R is not None
        print(f"fit RMS {res.rms_mm:.4f} mm over {meas.m} {what}" + _deg(res.rms_deg, deg))
        print(f"nominal fit RMS {fair.rms_mm:.4f} mm{_deg(fair.rms_deg, deg)} ({NOMINAL})")
    if meas.k:
        print(f"distance RMS {res.rms_distance_mm:.4f} mm over {meas.k} distances (nominal "
              f"{fair.rms_distance_mm:.4f} mm)")  # fmt: skip
    print(
        f"{kinds}: rank {res.rank}/{res.n_params} ({int(res.estimated.sum())} estimated), "
        f"condition number {res.condition_number:.3g}, "
        f"sigma0 {res.sigma0:.3g} (1 when --sigma-mm is the noise)"
    )
    held = ", ".join(f"{k} ({v})" for k, v in res.held_reason.items()) or "none"
    print(f"held at nominal: {held}")
    if cv is not None:
        _print_cv(cv)
    else:
        print(
            "no cross-validation (fewer than 2 configurations of position / pose rows, or no "
            "fold could be fitted); the "
            "fit RMS of more parameters is always lower: judge the calibration on held-out "
            f"rows, `selfcal predict {out} --measurements HELD_OUT.csv`"
        )
    tool = ", ".join(f"{v:.3f}" for v in cal.tool_point_mm)
    print(f"tool point in the nominal flange frame: ({tool}) mm")
    if run.accuracy is not None:
        line = accuracy_line(run.accuracy.summary)
        print(f"predicted: {line} (`selfcal report {out}` draws the map)")
    if run.spread is not None:
        print(spread_line(run.spread.to_json()))
    if table.ignored:
        print(f"ignored columns of {table.path}: {', '.join(table.ignored)}")
    for w in res.warnings:
        get_logger(__name__).warning("%s", w)
    print(f"wrote {path}")
    return 0


NOMINAL = "the robot file's chain, tracker frame and tool fitted the same way"


def _deg(v: float, show: bool) -> str:
    return f", {v:.4f} deg" if show else ""


def _print_cv(cv) -> None:
    """The k-fold held-out line of ``identify`` (the calibration beside the fair nominal) and,
    when the data do not support the calibration, the warning."""
    from selfcal.calibration.tracker.cross_validation import cross_validation_line

    print(cross_validation_line(cv.to_json()))
    if not cv.supported:
        get_logger(__name__).warning(
            "the data do not support the kinematic calibration: it predicts held-out rows no "
            "better than the nominal chain with the tracker frame and tool fitted (`nominal` in "
            "calibration.json); measure more, better spread configurations"
        )


def _identify_json(res, meas: TrackerMeasurements, cal, path: Path) -> dict:
    """``selfcal identify --json``: the fit's headline numbers (mm, deg) and the k-fold held-out
    check (``calibration.json``'s ``fit.cross_validation``, null without one)."""
    return {
        "calibration": str(path),
        "kinds": list(res.kinds),
        "rms_mm": res.rms_mm if meas.m else None,
        "rms_deg": res.rms_deg if meas.R is not None else None,
        "rms_distance_mm": res.rms_distance_mm if meas.k else None,
        "rank": res.rank,
        "n_params": res.n_params,
        "condition_number": res.condition_number,
        "sigma0": res.sigma0,
        "held": dict(res.held_reason),
        "tool_point_mm": [float(v) for v in cal.tool_point_mm],
        "nominal": {k: v for k, v in cal.to_json()["nominal"].items() if k.startswith("rms_")},
        "cross_validation": cal.fit.get("cross_validation"),
        "warnings": list(res.warnings),
    }


def cmd_predict(args: argparse.Namespace) -> int:
    from selfcal.calibration.tracker.calibration_file import read_tracker_calibration
    from selfcal.io.tracker import positions_csv, read_joints, read_measurements, write_positions

    src = Path(args.calibration)
    path = src / "calibration.json" if src.is_dir() else src
    if not path.is_file():
        raise CliError(
            f"{path} not found",
            fix="give the folder `selfcal identify --out DIR` wrote, or its calibration.json",
        )
    if (args.joints is None) == (args.measurements is None):
        raise CliError(
            "give either --joints FILE (predict) or --measurements FILE (predict and compare)",
            fix="see `selfcal predict --help`",
        )
    cal = read_tracker_calibration(path)
    guess = not args.trust_units
    extra: dict[str, np.ndarray] = {}
    if args.measurements:
        meas, _ = read_measurements(args.measurements, cal, args.joint_units, guess=guess)
        q = meas.q
        extra = _held_out(cal, meas)
    else:
        q = read_joints(args.joints, cal, args.joint_units, guess=guess)
    T = cal.predict_poses(q)
    if args.out:
        write_positions(args.out, T, orientation=cal.poses, extra=extra)
        note_written(args, args.out)
        print(f"wrote {len(T)} {'poses' if cal.poses else 'positions'} to {args.out}",
              file=sys.stderr)  # fmt: skip
    else:
        sys.stdout.write(positions_csv(T, orientation=cal.poses, extra=extra))
    return 0


def _held_out(cal, meas: TrackerMeasurements) -> dict[str, np.ndarray]:
    """The per-row errors of the calibration and of its fair nominal against held-out
    measurements (columns of the output), with their RMS printed on stderr."""
    from selfcal.calibration.tracker.nominal import pose_errors

    R = meas.R if cal.poses else None  # a position fit does not identify the tool orientation
    models = {"": cal.predict_poses(meas.q)}
    if cal.nominal is not None:
        models["nominal_"] = cal.nominal.predict_poses(meas.q)
    out: dict[str, np.ndarray] = {}
    rms: dict[str, str] = {}
    for key, T in models.items():
        pos, ang = pose_errors(T, meas.xyz, R)
        out[f"{key}error_mm"] = pos
        rms[key] = f"{np.sqrt(np.mean(pos**2)):.4f} mm"
        if ang is not None:
            out[f"{key}error_deg"] = ang
            rms[key] += f", {np.sqrt(np.mean(ang**2)):.4f} deg"
    what = "poses" if R is not None else "positions"
    line = f"held-out RMS over {meas.m} {what}: calibrated {rms['']}"
    if "nominal_" not in rms:
        line += "; no nominal in this calibration.json (written before it was recorded)"
    else:
        line += f", nominal {rms['nominal_']} ({NOMINAL})"
        if np.sqrt(np.mean(out["error_mm"] ** 2)) >= np.sqrt(np.mean(out["nominal_error_mm"] ** 2)):
            line += "; the calibration does not predict better than the nominal chain"
    print(line, file=sys.stderr)
    return {k: out[k] for k in sorted(out, key=lambda k: (k.endswith("deg"), k))}


def register(sub) -> None:
    """Add ``identify`` and ``predict`` to the ``selfcal`` sub-command parsers ``sub``."""
    from selfcal.choices import JOINT_UNITS

    sp = sub.add_parser(
        "identify",
        help="fit the kinematics to tracker measurements -> DIR/calibration.json",
        description="fit the kinematics, the tracker frame and the tool point to tracker "
        "measurements of a tool point (positions, poses, distances)",
        epilog=IDENTIFY_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.set_defaults(func=cmd_identify)
    sp.add_argument("measurements", help="MEASUREMENTS.csv (see below)")
    sp.add_argument("--robot", required=True, help="robot name, robot TOML or URDF path")
    sp.add_argument("--joint-units", required=True, choices=JOINT_UNITS, help=UNITS_HELP)
    sp.add_argument(
        "--out",
        default=None,
        help="output folder (default runs/identify-<measurements file name>)",
    )
    sp.add_argument("--distances", default=None, help="distances CSV (see below)")
    sp.add_argument(
        "--sigma-mm", type=float, default=0.1, help="position / distance noise, mm (0.1)"
    )
    sp.add_argument(
        "--sigma-deg", type=float, default=0.01, help="orientation noise of poses, deg (0.01)"
    )
    sp.add_argument("--hold", default=None, help="parameters held at nominal, e.g. beta1,ly1")
    sp.add_argument("--trust-units", action="store_true", help=TRUST_HELP)
    sp.add_argument(
        "--spread",
        type=int,
        default=0,
        metavar="N",
        help="also the run-to-run spread of the tool point over N bootstrap resamplings of the "
        "rows (mm over the workspace, calibration.json accuracy.spread; docs/tool-accuracy.md)",
    )
    add_json(sp)

    sp = sub.add_parser(
        "predict",
        help="tool-point positions in the tracker frame for new joint rows (CSV x_mm,y_mm,z_mm)",
        description="predict the tool point (tracker frame, mm) for every row of a joints file "
        "with a calibration written by `selfcal identify`, and the tool orientation (qw,qx,qy,qz) "
        "when it was fitted to poses; with --measurements, also the error of the calibration and "
        "of the fair nominal per row; CSV on stdout or --out",
    )
    sp.set_defaults(func=cmd_predict)
    sp.add_argument("calibration", help="the DIR of `selfcal identify` (or its calibration.json)")
    sp.add_argument(
        "--joints",
        default=None,
        help="joints file: header j1..jn, or n numbers per row, comma- or whitespace-separated",
    )
    sp.add_argument(
        "--measurements",
        default=None,
        metavar="FILE",
        help="held-out measurements in the format `selfcal identify` reads (instead of "
        "--joints): adds each row's error of the calibration and of the fair nominal (the "
        "robot file's chain, tracker frame and tool fitted) as columns error_mm, "
        "nominal_error_mm (and error_deg, nominal_error_deg for a fit of poses) and prints "
        "their RMS",
    )
    sp.add_argument("--joint-units", required=True, choices=JOINT_UNITS, help=UNITS_HELP)
    sp.add_argument("--out", default=None, help="predicted.csv (default: stdout)")
    sp.add_argument("--trust-units", action="store_true", help=TRUST_HELP)
