"""``selfcal check CALIBRATION_DIR NEW_DATA``: has the robot changed since its calibration?

A few new tracker measurements at any postures against a tracker calibration: "unchanged"
(exit 0) or "changed by X mm at the tool" (exit :data:`EXIT_CHANGED`), so that a robot cell can
run it every morning. :func:`selfcal.calibration.tracker.drift.check_tracker` does the check
(the public API's too); this prints its verdict. Image data are not checked yet.
"""

from __future__ import annotations

import argparse
import json

from selfcal.console.common import CliError, add_json

__all__ = ["register", "cmd_check", "EXIT_CHANGED"]

EXIT_CHANGED = 5
"""The exit code of a check that finds the robot changed (not an error: the check worked)."""

HELP = f"""\
NEW_DATA: tracker measurements in the format `selfcal identify` reads (header j1..jn,x_mm,y_mm,
z_mm; quaternion columns are ignored: the check compares positions), any postures, a few rows.
The residuals against the calibration are tested against what the calibration predicts for
them (its estimation error at these postures and its model error, from calibration.json's
accuracy block, and the tracker noise --sigma-mm given to identify); exit 0: unchanged, exit {EXIT_CHANGED}: changed (p < alpha).
See docs/tool-accuracy.md."""


def cmd_check(args: argparse.Namespace) -> int:
    from selfcal.calibration.tracker.drift import check_tracker

    if not 0.0 < args.alpha < 1.0:
        raise CliError(f"--alpha {args.alpha} is not a probability", fix="e.g. --alpha 0.01")
    res = check_tracker(args.calibration, args.new_data, args.joint_units, alpha=args.alpha,
                        trust_units=args.trust_units)  # fmt: skip
    if args.json:
        print(json.dumps(res.to_json()))
    else:
        print(res.line())
    return EXIT_CHANGED if res.changed else 0


def register(sub) -> None:
    """Add ``check`` to the ``selfcal`` sub-command parsers ``sub``."""
    from selfcal.choices import JOINT_UNITS
    from selfcal.cli.tracker import TRUST_HELP, UNITS_HELP

    sp = sub.add_parser(
        "check",
        help=f"drift check: new tracker measurements against a calibration; exit 0 unchanged, "
        f"{EXIT_CHANGED} changed",
        description="has the robot changed since its calibration? a few new tracker "
        "measurements at any postures against the calibration of `selfcal identify`",
        epilog=HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sp.set_defaults(func=cmd_check)
    sp.add_argument("calibration", help="the DIR of `selfcal identify` (or its calibration.json)")
    sp.add_argument("new_data", help="NEW_DATA.csv: new tracker measurements (see below)")
    sp.add_argument("--joint-units", required=True, choices=JOINT_UNITS, help=UNITS_HELP)
    sp.add_argument("--alpha", type=float, default=0.01,
                    help="false-alarm probability on an unchanged robot (0.01)")  # fmt: skip
    sp.add_argument("--trust-units", action="store_true", help=TRUST_HELP)
    add_json(sp)
