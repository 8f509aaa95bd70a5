"""``selfcal plan --add K DATASET`` (issue #30): the postures to add to a recorded dataset
(:mod:`selfcal.calibration.board.plan.add`), written as PLAN/joints.csv, trajectory.yaml,
replay.csv, target.toml, scenario.toml, plan.json and plan.png."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from selfcal.cli.plan_args import (
    check_common,
    deviation,
    keep_out_boxes,
    plan_inputs,
    trajectory_joint_names,
)
from selfcal.console.common import CliError, note_written, writing

if TYPE_CHECKING:
    from selfcal.calibration.board.plan.add import AddedPostures

__all__ = ["add_count", "cmd_add", "corner_noise", "halved_words"]


def add_count(args: argparse.Namespace) -> tuple[int, str]:
    """``--add K DATASET``'s K (a whole number >= 1) and DATASET, for a board dataset and a
    tracker calibration alike.

    Raises:
        CliError: K not a whole number, or below 1.
    """
    k_text, root = args.add
    try:
        count = int(k_text)
    except ValueError:
        raise CliError(f"--add {k_text} {root}: K must be a whole number of postures") from None
    if count < 1:
        raise CliError(f"--add {count} {root}: add at least 1 posture",
                       fix=f"e.g. --add 5 {root}")  # fmt: skip
    return count, root


def cmd_add(args: argparse.Namespace) -> int:
    """``selfcal plan --add K DATASET``: the K postures that most lower the dataset's predicted
    tool-point error (mm at the edges), written to PLAN/ with the forecast before and after."""
    from selfcal.acquisition.backends import robot_reference
    from selfcal.calibration.board.plan.add import HALVE_MORE, dataset_setup, plan_additions
    from selfcal.calibration.board.plan.ground import PlanOptions
    from selfcal.cli.plan_add_ground import add_ground
    from selfcal.cli.plan_forecast import DrawSet, forecast_draws, write_figure
    from selfcal.cli.plan_scenario import cell_fields, scenario_text
    from selfcal.cli.plan_text import criterion, forecast_note, measured_gain, reference_words
    from selfcal.console.progress import Progress
    from selfcal.estimation.joint_report import encoder_sigma
    from selfcal.io.atomic import write_text_atomic
    from selfcal.io.board_calibration import read_board_calibration
    from selfcal.io.dataset import Dataset
    from selfcal.io.plan_files import joints_csv, trajectory_yaml, write_plan
    from selfcal.io.target_toml import target_document

    count, root = add_count(args)
    check_common(args, count)
    _refuse_other_routes(root)
    dplan = dataset_setup(root, keep_out_boxes(args))
    setup = dplan.setup
    robot = setup.robot
    names = trajectory_joint_names(args, robot.joint_names)
    js = encoder_sigma(robot)
    noise = corner_noise(args, root)
    opts = PlanOptions(seed=args.seed, candidates=args.candidates,
                       pixel_sigma_px=args.pixel_sigma, joint_sigma=js, deviation=deviation(args))  # fmt: skip
    opts, ws, dev = add_ground(args, root, dplan, opts)  # the dataset's, not the defaults
    with Progress("plan", enabled=not (args.quiet or args.json)).step(
        f"choosing {count} postures to add"
    ) as st:
        add = plan_additions(dplan, count, opts, ws.q, more=HALVE_MORE)
        st.result(f"from {add.candidates} candidates")
    m = len(dplan.q)
    before = reference_words(add.reference_before, add.before_m)
    measured = (None if add.reference_before.beaten_by(add.before_m) else
                measured_gain(read_board_calibration(root).selection, *_held_out(root)))  # fmt: skip
    if measured is not None:  # the forecast's verdict beside this arm's measured gain
        before += forecast_note(measured, f"+-{args.deviation_mm:.3g} mm, "
                                          f"+-{args.deviation_deg:.3g} deg")  # fmt: skip
    fc = forecast_draws(args, setup, add.workspace, [
        DrawSet("before", f"the dataset's {m} postures recorded anew", dplan.q, dplan.seen),
        DrawSet("after", f"with the {len(add.q)} added", np.concatenate([dplan.q, add.q]),
                dplan.seen)], js, opts.deviation)  # fmt: skip
    where, cell = cell_fields(setup)
    ref = robot_reference(str(Dataset.open(root).robot_source))
    out = Path(args.out)
    q_all = np.concatenate([dplan.q, add.q])
    with writing(args, out):
        write_text_atomic(out / "joints.csv", joints_csv(add.q, robot.edge_unit))
        write_text_atomic(out / "trajectory.yaml", trajectory_yaml(
            names, add.q, robot.home, speed=args.speed_deg_s * robot.edge_unit,
            dwell_s=args.dwell_s))  # fmt: skip
        write_text_atomic(out / "replay.csv", joints_csv(q_all, robot.edge_unit))
        doc_t = target_document(setup.board)  # flat: strings, numbers and lists of numbers
        write_text_atomic(out / "target.toml", "# The board of " + str(root) + "\n" + "".join(
            f"{k} = {json.dumps(v)}\n" for k, v in doc_t.items()))  # fmt: skip
        write_text_atomic(out / "scenario.toml", scenario_text(ref, setup.camera, count=len(q_all),
                                                              joints="replay.csv", pixel_sigma=args.pixel_sigma,
                                                              deviation=opts.deviation, **where))  # fmt: skip
        write_figure(fc, add.reference, f"{robot.name}: {root} ({m} frames) before and after "
                     f"adding {len(add.q)} postures, predicted over {fc.draws} draws of the arm "
                     "and the noise", out / "plan.png")  # fmt: skip
        body = {
            "dataset": str(root),
            "dataset_frames": len(dplan.q),
            "robot": ref,
            "count": len(add.q),
            "predicted_before_tool_rms_mm": round(add.before_m * 1000, 4),
            "predicted_tool_rms_mm": round(add.after_m * 1000, 4),
            "kinematic_parameters_before": add.kept_before,
            "kinematic_parameters_after": add.kept_after,
            "kinematic_parameters_note": "beyond the placement (the board pose and the "
            "hand-eye, always estimated), as selfcal calibrate's line counts them",
            "criterion": criterion(len(add.workspace), args.pixel_sigma, js, args)
            + "; summed over the dataset and each training set of the selection's "
            "cross-validation; after: with the parameters the selection's cross-validation "
            "is forecast to keep (the swaps: by the RMS over draws, the selection deciding in each)",
            "forecast": {
                "chosen": add.forecast.label,
                "folds": add.forecast.folds,
                **(
                    {"folds_counted": list(add.forecast.counted)}
                    if add.forecast.counted and not all(add.forecast.counted)
                    else {}
                ),
                "candidates": [
                    {"label": lab, "fold_rms_px": [round(v, 4) for v in rms]}
                    for lab, rms in zip(add.forecast.labels, add.forecast.fold_rms_px)
                ],
            },
            "workspace": ws.to_json(),
            "deviation": dev,
            "pixel_sigma": noise,
            "nominal": add.reference.to_json(),
            "nominal_before": add.reference_before.to_json(),
            "verdict_before": before,
            "measured_before": None
            if measured is None
            else {
                "cross_validated_px": measured.get("cv_px"),
                "held_out_px": measured.get("held_out_px"),
                "note": "what the dataset's calibration measured against its fair nominal on "
                "its own images (calibrated, nominal), given where the forecast before says no "
                "clear gain: the forecast is of arms drawn within the deviation, the "
                "measurement of this arm",
            },
            "beats_nominal": add.reference.beaten_by(add.after_m),
            "verdict": reference_words(add.reference, add.after_m),
            "halved_with": _halved_json(add),
            "forecast_draws": fc.section(),
            "candidates": add.candidates,
            "candidates_from": add.drawn_from,
            "path_deg": round(float(np.degrees(add.path_rad)), 3),
            "seed": args.seed,
            **cell,
            **plan_inputs(args, setup.boxes, robot.edge_unit, add.q),
        }
        doc = write_plan(out / "plan.json", "add", body)
    note_written(args, out)
    line = (f"add {len(add.q)} postures to {root} ({len(dplan.q)} frames): predicted tool-point "
            f"error {add.before_m * 1000:.3f} -> {add.after_m * 1000:.3f} mm RMS (kinematic "
            f"parameters beyond the placement estimated {add.kept_before} -> {add.kept_after}) over {ws.words}; "
            f"joint path {np.degrees(add.path_rad):.0f} deg\n{noise['words']}\nthe held parameters' "
            f"{dev['words']}"
            "\nbefore, " + before + "\nafter, " + doc["verdict"] + "\n" + fc.line())  # fmt: skip
    if short := halved_words(add, str(root)):
        line += "\n" + short
    print(json.dumps(doc) if args.json else line)
    return 0


def _refuse_other_routes(root: str) -> None:
    """Refuse a dataset whose calibration.json is not a board calibration with joints, naming
    what it is: --add plans joint postures from a board calibration's chain, and a pose
    dataset's or a marker field's calibration read as one said "not a
    scorbot-selfcal-board-calibration file -- re-run `selfcal calibrate DATASET`", which writes
    the same file again."""
    from selfcal.calibration.handeye.calibration_file import is_handeye
    from selfcal.io.board_calibration import FORMAT, calibration_kind

    p = Path(root) / "calibration.json"
    if not p.is_file() or calibration_kind(p) == "board":
        return  # missing or a board calibration: dataset_setup says what to do
    if is_handeye(p):
        raise CliError(
            f"{p} is a hand-eye calibration from flange poses (`selfcal import --poses`): "
            "--add plans joint postures from a board calibration of joint readings, and a "
            "pose dataset has no joints to plan",
            fix="plan new postures with `selfcal plan --robot ROBOT --target TARGET.toml "
            "--mount eye-in-hand|eye-to-hand ...`, or import the images with the joint "
            "readings (`selfcal import --robot ROBOT --joints FILE ...`), calibrate that "
            "dataset and give it to --add",
        )
    raise CliError(
        f"{p} is not a board calibration ({FORMAT}): --add plans the postures to add to a "
        "dataset of images of a known board with joint readings, calibrated by `selfcal "
        "calibrate`",
        fix="plan a marker field's postures with `selfcal plan --target FIELD.toml ...` "
        "(docs/plan.md), or give --add a board dataset's folder",
    )


def corner_noise(args: argparse.Namespace, root: str | Path) -> dict:
    """The corner noise ``--add`` forecasts with (px per coordinate; ``args.pixel_sigma`` set to
    it): ``--pixel-sigma`` when given, else the one the dataset's calibration estimated from its
    residuals (``calibration.json``'s ``bounds.pixel_sigma_px``), else the default 0.5 px;
    plan.json's ``pixel_sigma`` (``px``, ``source``: given, calibration or default; ``words``).
    The default's 0.5 px against a calibration that fits to 0.04 px made the folds' measured
    misfit look like noise and the sized deviation its floor."""
    from selfcal.io.board_calibration import read_board_calibration

    if getattr(args, "pixel_sigma_given", True):
        source, words = "given", "as given"
    else:
        path = Path(root) / "calibration.json"
        bounds = read_board_calibration(path).bounds
        if bounds is not None and bounds.pixel_sigma_px > 0:
            args.pixel_sigma = bounds.pixel_sigma_px
            source = "calibration"
            words = (f"the calibration's, estimated from its residuals ({path}: "
                     "bounds.pixel_sigma_px); --pixel-sigma overrides it")  # fmt: skip
        else:
            source = "default"
            words = (f"the default: {path} records no corner noise (no bounds); --pixel-sigma "
                     "sets it")  # fmt: skip
    return {"px": round(args.pixel_sigma, 6), "source": source,
            "words": f"corner noise {args.pixel_sigma:.3g} px, {words}"}  # fmt: skip


def _held_out(root: str | Path) -> tuple[tuple[float, float] | None, str]:
    """The held-out check of the calibration in ``root`` (calibrated, nominal px) from
    ``root/evaluation.json`` when that evaluates this calibration (else None), and its path."""
    from selfcal.calibration.board.evaluate import evaluation_of

    path, ev = evaluation_of(root, warn=False)
    if ev is None:
        return None, str(path)
    return (ev.rms["calibrated"], ev.rms["nominal"]), str(path)


def _halved_json(add: AddedPostures) -> dict:
    """plan.json's ``halved_with``: the fewest postures predicted to halve the error before
    (``count`` null: none up to ``tried``) by the medians of the forecast's draws, the median
    before and theirs after (mm)."""
    h = add.halving
    assert h is not None  # cmd_add asks for it
    return {"count": h.count, "tried_up_to": h.tried, "by": HALVED_BY,
            "median_before_mm": round(h.before_m * 1000, 4),
            "median_after_mm": None if h.count is None else round(h.after_m * 1000, 4)}  # fmt: skip


HALVED_BY = ("the medians of the tool-point error over the forecast's draws (forecast_draws: the "
             "same count and seed), before and after, not the first line's prediction")  # fmt: skip
"""What plan.json's ``halved_with`` judges by."""


def halved_words(add: AddedPostures, root: str) -> str:
    """The line for a plan not predicted to halve the dataset's error by the medians of the
    forecast's draws: how many postures are (with the command that plans them) or none up to
    the largest count tried; empty when the plan's own count is."""
    h = add.halving
    assert h is not None  # cmd_add asks for it
    k = len(add.q)
    if h.count == k:
        return ""
    short = (f"not predicted to halve the error with {k} added postures (the forecast's draws' "
             f"median {h.before_m * 1000:.3f} before)")  # fmt: skip
    if h.count is None:
        return f"{short}, nor with any count up to {h.tried} (each planned as {k} are)"
    return (f"{short}; {h.count} are predicted to ({h.before_m * 1000:.3f} -> "
            f"{h.after_m * 1000:.3f} mm, the draws' medians): selfcal plan --add {h.count} "
            f"{root}")  # fmt: skip
