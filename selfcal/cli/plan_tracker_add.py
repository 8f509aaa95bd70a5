"""``selfcal plan --add K DIR`` for a tracker calibration (DIR the folder ``selfcal identify``
wrote; issue #30): the K postures that most lower its predicted tool-point error, the command of
:mod:`selfcal.calibration.tracker.add`; writes PLAN/joints.csv, trajectory.yaml and plan.json
(kind ``tracker-add``)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from selfcal.cli.plan_add import add_count
from selfcal.cli.plan_args import (
    check_common,
    keep_out_boxes,
    plan_inputs,
    trajectory_joint_names,
    write_postures,
)
from selfcal.cli.plan_tracker import CAMERA_OPTIONS, greedy_note
from selfcal.console.common import CliError, note_written, writing

__all__ = ["TAKES_FROM_CALIBRATION", "is_tracker_dataset", "fair_words", "cmd_tracker_add"]

TAKES_FROM_CALIBRATION = (
    ("--robot", "robot"),
    ("--count", "count"),
    ("--tool-point", "tool_point"),
    *CAMERA_OPTIONS,
)
"""What a new plan takes and ``--add`` to a tracker calibration refuses: the calibration gives
the robot and the tool point, K the count, and no camera or board is planned for."""


def _calibration_path(root: str) -> Path:
    p = Path(root)
    return p / "calibration.json" if p.is_dir() else p


def is_tracker_dataset(root: str) -> bool:
    """Whether ``--add``'s ``root`` (a folder or its ``calibration.json``) holds a tracker
    calibration (``selfcal identify``'s)."""
    from selfcal.calibration.tracker.calibration_file import is_tracker_calibration

    p = _calibration_path(root)
    return p.is_file() and is_tracker_calibration(p)


def _check(args: argparse.Namespace) -> int:
    """The refusals (the option or the dataset named, with the fix); K."""
    count, root = add_count(args)
    if not is_tracker_dataset(root):
        raise CliError(
            f"--measure tracker --add {count} {root}: {_calibration_path(root)} is not a "
            "tracker calibration (the calibration.json `selfcal identify` writes)",
            fix="give --add the folder `selfcal identify MEASUREMENTS.csv ... --out DIR` wrote, "
            "or leave out --measure tracker to add postures to a board dataset",
        )
    given = [o for o, k in TAKES_FROM_CALIBRATION if getattr(args, k) not in (None, [])]
    if given:
        raise CliError(
            f"--add {count} {root}: a tracker calibration gives the robot and the tool point and "
            f"K the count, and no camera or board is planned for: {', '.join(given)} would not "
            "be used",
            fix=f"leave out {', '.join(given)} with --add",
        )
    if args.sigma_mm is not None and not args.sigma_mm > 0:
        raise CliError(f"--sigma-mm {args.sigma_mm}: the tracker's noise must be > 0 mm")
    check_common(args, count)
    return count


def fair_words(fair_m: float, predicted_m: float, rows: str) -> str:
    """The fair nominal of ``rows`` (words) predicted at ``fair_m`` (m) and whether a
    calibration predicted at ``predicted_m`` (m) beats it clearly (at most
    :data:`selfcal.calibration.board.plan.reference.CLEAR_MARGIN` times it, the board plan's
    rule)."""
    from selfcal.calibration.board.plan.reference import CLEAR_MARGIN  # scipy: not at CLI start

    head = (f"the fair nominal of {rows} (the chain as drawn, the tracker frame and the tool "
            f"point fitted) {fair_m * 1000:.3f} mm")  # fmt: skip
    ratio = predicted_m / fair_m
    if ratio <= CLEAR_MARGIN:
        return f"{head}: the calibration is predicted at {ratio:.2f} times it"
    return (f"{head}: the calibration is NOT predicted to beat it by a clear margin ({ratio:.2f} "
            f"times it, a clear gain is at most {CLEAR_MARGIN:g})")  # fmt: skip


def cmd_tracker_add(args: argparse.Namespace, deviation) -> int:
    """Plan, write and print (module docstring); ``deviation`` the arm's deviation from its
    drawing the held parameters err by (:class:`selfcal.calibration.board.deviation.Deviation`)."""
    from selfcal.calibration.board.plan.reference import CLEAR_MARGIN
    from selfcal.calibration.tracker.add import plan_tracker_additions, tracker_dataset
    from selfcal.io.plan_files import write_plan

    count = _check(args)
    root = args.add[1]
    sigma = None if args.sigma_mm is None else args.sigma_mm / 1000.0
    data = tracker_dataset(root, keep_out_boxes(args), sigma)
    robot = data.setup.robot
    names = trajectory_joint_names(args, robot.joint_names)
    add = plan_tracker_additions(data, count, seed=args.seed, candidates=args.candidates,
                                 deviation=deviation)  # fmt: skip
    m, k = len(data.q), len(add.q)
    sigma_mm = data.setup.sigma_m * 1000
    noise = (f"tracker noise {sigma_mm:.3g} mm per coordinate, "
             + ("as given" if data.sigma_source == "given" else
                f"the calibration's ({data.path}: sigmas.position_mm); --sigma-mm overrides it"))  # fmt: skip
    dev = (f"the held parameters' deviation +-{args.deviation_mm:g} mm, "
           f"+-{args.deviation_deg:g} deg, "
           + ("as given" if args.deviation_given else
              "the default (--deviation-mm, --deviation-deg set it)"))  # fmt: skip
    not_counted = (f"{data.distances} distance rows of the calibration not counted (before and "
                   "after both leave them out: both pessimistic)" if data.distances else "")  # fmt: skip
    gain = add.before_m / add.after_m if add.after_m > 0 else float("inf")
    out = Path(args.out)
    with writing(args, out):
        write_postures(args, out, names, add.q, robot)
        body = {
            "dataset": str(data.path),
            "dataset_rows": m,
            "robot": data.calibration.robot_source,
            "count": k,
            "predicted_before_tool_rms_mm": round(add.before_m * 1000, 4),
            "predicted_tool_rms_mm": round(add.after_m * 1000, 4),
            "predicted_gain": round(gain, 3),
            "random_tool_rms_mm": round(add.random_m * 1000, 4),
            "greedy_tool_rms_mm": round(add.greedy_m * 1000, 4),
            "chosen_by": add.chosen_by,
            "fair_nominal_before_tool_rms_mm": round(add.fair_before_m * 1000, 4),
            "fair_nominal_tool_rms_mm": round(add.fair_after_m * 1000, 4),
            "verdict_before": fair_words(add.fair_before_m, add.before_m, f"the {m} rows"),
            "verdict": fair_words(add.fair_after_m, add.after_m, f"the {m + k} rows"),
            "clear_margin": CLEAR_MARGIN,
            "kinematic_parameters_before": add.kept_before,
            "kinematic_parameters_after": add.kept_after,
            "minimal_parameters": add.parameters,
            "criterion": (
                "tracker route (positions of the tool point, exact joints) covariance; before: "
                "the calibration's rows with the parameters it estimated, after: with the added "
                "postures and the parameters the route's rank and conditioning tests keep at "
                "all of them; the others held at the drawing, deviating uniformly within "
                f"+-{args.deviation_mm:g} mm and +-{args.deviation_deg:g} deg: RMS of the tool "
                f"point's position error over {len(add.workspace)} random workspace postures "
                f"in the tracker frame, tracker noise {sigma_mm:g} mm per coordinate"
            ),
            "sigma_mm": {"mm": sigma_mm, "source": data.sigma_source, "words": noise},
            "distances_not_counted": data.distances,
            "candidates": add.candidates,
            "path_deg": round(float(np.degrees(add.path_rad)), 3),
            "seed": args.seed,
            "tool_point_mm": np.round(data.setup.tool_point_m * 1000, 6).tolist(),
            **plan_inputs(args, data.setup.boxes, robot.edge_unit, add.q),
        }
        doc = write_plan(out / "plan.json", "tracker-add", body)
    note_written(args, out)
    line = (f"add {k} postures to {root} ({m} rows): predicted tool-point error "
            f"{add.before_m * 1000:.3f} -> {add.after_m * 1000:.3f} mm RMS, {gain:.1f} times "
            f"lower (parameters estimated {add.kept_before} -> {add.kept_after} of "
            f"{add.parameters}; {k} random postures instead: {add.random_m * 1000:.3f} mm) over "
            f"{len(add.workspace)} workspace postures in the tracker frame; joint path "
            f"{np.degrees(add.path_rad):.0f} deg\n{noise}\n{dev}\nbefore, "
            f"{doc['verdict_before']}\nafter, {doc['verdict']}")  # fmt: skip
    if note := greedy_note(add.chosen_by, add.greedy_m, "the added postures are"):
        line += "\n" + note
    if not_counted:
        line += "\n" + not_counted
    print(json.dumps(doc) if args.json else line)
    return 0
