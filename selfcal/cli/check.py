"""``selfcal check CALIBRATION_DIR NEW_DATA``: has the robot changed since its calibration?

A few new measurements at any postures against a calibration: "unchanged" (exit 0) or "changed
by X mm at the tool" (exit :data:`EXIT_CHANGED`), so that a robot cell can run it every morning.
By the calibration's route: a tracker calibration (``selfcal identify``) takes new tracker rows
(:func:`selfcal.calibration.tracker.drift.check_tracker`), a board calibration with joints
(``selfcal calibrate`` on images of a board) a dataset of new images
(:func:`selfcal.calibration.drift.images.check_images`); both are the public API's too. This
picks the route and prints the verdict; any other calibration is refused.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from selfcal.console.common import CliError, add_json

__all__ = ["register", "cmd_check", "EXIT_CANNOT_TELL", "EXIT_CHANGED"]

EXIT_CHANGED = 5
"""The exit code of a check that finds the robot changed (not an error: the check worked)."""
EXIT_CANNOT_TELL = 6
"""The exit code of a board check that cannot tell: the new images miss the calibration's
prediction, but not by more than its own folds missed the configurations they left out
(:mod:`selfcal.calibration.drift.fold_error`), or they fit it only with the own corner noise
of images noisier than the calibration's frames, which would hide a change the check does not
model (:mod:`selfcal.calibration.drift.noisy`); not an error."""

HELP = f"""\
NEW_DATA by the calibration's route:
  tracker (`selfcal identify`): tracker measurements in the format identify reads (header
    j1..jn,x_mm,y_mm,z_mm; quaternion columns are ignored: the check compares positions), any
    postures, a few rows; --joint-units required.
  board (`selfcal calibrate` on images of a board and joint readings, eye-in-hand or
    eye-to-hand; not a hand-eye calibration from flange poses, see `selfcal evaluate`): a dataset
    folder in the format calibrate reads (dataset.json, joints.csv, the images; e.g. from
    `selfcal import --joints`), a few images of the same board, not moved, at any postures;
    the first camera's images are checked. It also says what changed (the camera, a mount,
    the board's pose, a joint's offset) when only one of them explains the new images.
The residuals against the calibration are tested against what the calibration predicts for
them (its estimation error at these postures and its model error, from calibration.json's
accuracy block, and the noise of its fit); exit 0: unchanged, exit {EXIT_CHANGED}: changed (p < alpha).
A board check that fails is tested again with the calibration's own folds' error at the arm
configurations they left out (accuracy.model_error's held-out tool poses beyond their estimate
and noise) as each new view's model error: still failing, "changed" (exit 5); else "cannot
tell" (exit {EXIT_CANNOT_TELL}): the images miss the prediction by no more than the calibration
missed configurations it did not see (on real arms the check's prediction there has said changed
for unchanged ones, docs/real-data.md); check at the calibration's own postures instead.
An image with more corner noise than the calibration's frames (outside every change the check
considers) is tested with its own noise; a check that then does not fail says "cannot tell" (exit
{EXIT_CANNOT_TELL}), naming those images and their noise: a noisier image, or a change the check
does not model (a lens term the calibration holds, the focus, the board), which that noise hides.
New images that are the calibration's own frames (the same joint readings and board detections,
whatever their file names) are left out of the test and counted; when all are, nothing can be
tested and the check stops with exit 2 (record new images).
A board check's second line (--json: mount_shift_power) gives its power for the images tested:
how often images like these find a 0.2 mm move of the camera's (eye-to-hand the board's) mount
on the flange, from the calibration's covariance, and about how many such images find it in 95 %
of checks. See docs/tool-accuracy.md."""


def cmd_check(args: argparse.Namespace) -> int:
    from pathlib import Path

    from selfcal.calibration.handeye.calibration_file import is_handeye
    from selfcal.calibration.tracker.calibration_file import is_tracker_calibration
    from selfcal.io.board_calibration import calibration_kind

    if not 0.0 < args.alpha < 1.0:
        raise CliError(f"--alpha {args.alpha} is not a probability", fix="e.g. --alpha 0.01")
    src = Path(args.calibration)
    path = src / "calibration.json" if src.is_dir() else src
    if not path.is_file():
        raise CliError(f"{path} not found", fix="give the DIR `selfcal identify` or `selfcal "
                       "calibrate` wrote (or its calibration.json)")  # fmt: skip
    res: Any
    if is_tracker_calibration(path):
        from selfcal.calibration.tracker.drift import check_tracker

        if args.joint_units is None:
            raise CliError(f"{path} is a tracker calibration: --joint-units is required",
                           fix="add --joint-units deg (or rad) as given to identify")  # fmt: skip
        res = check_tracker(path, args.new_data, args.joint_units, alpha=args.alpha,
                            trust_units=args.trust_units)  # fmt: skip
    elif calibration_kind(path) == "board":
        from selfcal.calibration.drift.images import check_images

        given = [o for o, v in (("--joint-units", args.joint_units),
                                ("--trust-units", args.trust_units)) if v]  # fmt: skip
        if given:
            raise CliError(f"{path} is a board calibration, checked without {' and '.join(given)}"
                           " (the tracker route's options; a dataset's joints.csv names its "
                           "units)",
                           fix=f"drop {' and '.join(given)}")  # fmt: skip
        res = check_images(path, args.new_data, alpha=args.alpha)
    elif is_handeye(path):
        raise CliError(
            f"{path} is a hand-eye calibration from flange poses (`selfcal import --poses`): "
            "`selfcal check` does not test those (it checks joint-based board calibrations and "
            "tracker calibrations)",
            fix=f"import the new images with their flange poses the same way and run `selfcal "
            f"evaluate {src} NEW_DATASET`: it predicts them from their poses beside the fair "
            "nominal",
        )
    else:
        raise CliError(
            f"{path} is neither a tracker calibration nor a board calibration: `selfcal check` "
            "checks those two (the field route's calibration, of the marker field, is not "
            "checked)",
            fix="check a calibration of `selfcal identify` (tracker rows) or of `selfcal "
            "calibrate` on images of a board",
        )
    if args.json:
        print(json.dumps(res.to_json()))
    else:
        print(res.line())
        if getattr(res, "power", None) is not None:
            print(res.power.line())
    if getattr(res, "undecided", False):
        return EXIT_CANNOT_TELL
    return EXIT_CHANGED if res.changed else 0


def register(sub) -> None:
    """Add ``check`` to the ``selfcal`` sub-command parsers ``sub``."""
    from selfcal.choices import JOINT_UNITS
    from selfcal.cli.tracker import TRUST_HELP, UNITS_HELP

    sp = sub.add_parser(
        "check",
        help=f"drift check: new tracker rows or images against a calibration; exit 0 unchanged, "
        f"{EXIT_CHANGED} changed, {EXIT_CANNOT_TELL} cannot tell",
        description="has the robot changed since its calibration? a few new tracker "
        "measurements (against the calibration of `selfcal identify`) or images of the board "
        "(against a board calibration of `selfcal calibrate`) at any postures",
        epilog=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.set_defaults(func=cmd_check)
    sp.add_argument("calibration", help="the DIR of `selfcal identify` or `selfcal calibrate` "
                    "(or its calibration.json)")  # fmt: skip
    sp.add_argument("new_data", help="new tracker measurements (a CSV) or a dataset folder of "
                    "new images (see below)")  # fmt: skip
    sp.add_argument("--joint-units", choices=JOINT_UNITS,
                    help=f"tracker calibrations (required there): {UNITS_HELP}")  # fmt: skip
    sp.add_argument("--alpha", type=float, default=0.01,
                    help="false-alarm probability on an unchanged robot (0.01)")  # fmt: skip
    sp.add_argument("--trust-units", action="store_true", help=f"tracker: {TRUST_HELP}")
    add_json(sp)
