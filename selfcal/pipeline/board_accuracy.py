"""The predicted tool-point accuracy and the cross-validated reprojection in ``selfcal report``
of a board calibration (issue #29).

Rebuilds the prediction from ``calibration.json``'s ``accuracy`` block
(:mod:`selfcal.calibration.board.accuracy`): the one line "tool point within X mm (95 %) inside
the calibrated region, Y mm at its edge", the regions' summary, the model error, the
leave-one-configuration-out reprojection of the calibrated model and the fair nominal (px and
mm at the board), and the workspace map ``figures/workspace_accuracy.png``
(:mod:`selfcal.plots.workspace_map`); and the run-to-run spread of the tool point over the
folds (:mod:`selfcal.calibration.board.spread`) when the block has it.
"""

from __future__ import annotations

from pathlib import Path

from selfcal.calibration.accuracy import Z_MODEL_ERROR
from selfcal.calibration.board.accuracy import (
    board_error_model_from_json,
    board_postures_from_json,
)
from selfcal.calibration.board.held_prior import held_sentence
from selfcal.calibration.board.plan.drawn_check import drawn_words
from selfcal.calibration.spread import spread_line
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.kinematics.tool_error import accuracy_line
from selfcal.pipeline.accuracy_table import rebuilt_regions, region_table, rms_words
from selfcal.plots.job_figures import write_figure
from selfcal.plots.workspace_map import workspace_map_figure

__all__ = [
    "FIGURE",
    "accuracy_markdown",
    "accuracy_summary",
    "board_accuracy_section",
    "cross_validation_line",
    "rms_words",
    "spread_against_prediction",
    "spread_markdown",
    "zero_model_error_words",
]

FIGURE = "workspace_accuracy.png"


def board_accuracy_section(root: Path, cal: BoardCalibrationResult, *,
                           figures: bool) -> tuple[dict | None, list[Path]]:  # fmt: skip
    """The report's ``accuracy`` section of the board calibration ``cal`` in ``root`` and the
    figure drawn (with ``figures``); None without the block (a file written before it).

    Raises:
        InputError: the block is malformed (named, with the fix).
    """
    block = cal.accuracy
    if block is None:
        return None, []
    where = str(Path(root) / "calibration.json")
    em = board_error_model_from_json(block, cal.model, where)
    q_cal = board_postures_from_json(block, cal.model.n, where)
    sample, regions = rebuilt_regions(block, em, q_cal, where,
                                      fix="re-run `selfcal calibrate` to write it again")  # fmt: skip
    line = accuracy_line(regions)
    section = {
        "line": line,
        "what": block.get("what"),
        "tool_point": block.get("tool_point"),
        "model_error": block.get("model_error"),
        "model_error_note": block.get("model_error_note"),
        "distance_unit": distance_unit(block),
        "regions": regions,
        "cross_validation": block.get("cross_validation"),
        "held_deviation": block.get("held_deviation"),
        "spread": block.get("spread"),
        "bootstrap_spread": block.get("bootstrap_spread"),
        "drawn_reference": block.get("drawn_reference"),
    }
    drawn = []
    if figures:
        frame = "camera frame" if cal.eye_to_hand else "board frame"
        drawn.append(write_figure(workspace_map_figure(em, sample, q_cal, line, frame), root,
                                  FIGURE))  # fmt: skip
    return section, drawn


def distance_unit(block: dict) -> str:
    """What an ``accuracy`` block's distances (``reach_distance``, ``measured_to_distance``) are
    fractions of, in words: the joints' ranges with a revolute joint's at most a turn (its
    ``joint_spans_si``, :func:`selfcal.kinematics.tool_error.joint_spans`; 1 = one joint moved
    across all its distinct postures), or in an older block the limits' full ranges."""
    if "joint_spans_si" in block:
        return "the joints' ranges, a revolute joint's at most a turn"
    return "the joints' full ranges between their limits"


def cross_validation_line(cv: dict | None) -> str | None:
    """One sentence of the cross-validated reprojection (None without it): the RMS over every
    fold's held-out corners together (the folds that count, ``folds_counting`` when not all do;
    ``folds_counted`` in a block of session 29's code),
    which is not the selection table's figure (each
    candidate's geometric mean over the folds' RMS,
    :func:`selfcal.pipeline.report_fit.selection_markdown`): the sentence says which it is, as
    the two differ when one fold predicts much worse than the others."""
    if not cv or not cv.get("calibrated") or not cv.get("nominal"):
        return None
    c, n = cv["calibrated"], cv["nominal"]
    corners = f"the {c['corners']} " if c.get("corners") else "the "
    counted = cv.get("folds_counting", cv.get("folds_counted"))  # absent: every fold counts
    which = ("all folds" if counted is None else
             f"the {counted} folds that count (a fold leaving out more than half of the frames "
             "does not)")  # fmt: skip
    return (
        f"cross-validated over {cv['configurations']} configurations in {cv['folds']} folds, "
        f"RMS over {corners}held-out corners of {which} together (the parameter selection's "
        "table gives each fold's RMS and their geometric mean): "
        f"calibrated {c['reprojection_rms_px']:.3f} px ({c['at_board_rms_mm']:.3f} mm at the "
        f"board), fair nominal {n['reprojection_rms_px']:.3f} px "
        f"({n['at_board_rms_mm']:.3f} mm)"
    )


def accuracy_summary(section: dict) -> str:
    """The words ``selfcal report`` and ``selfcal run`` print of :func:`board_accuracy_section`'s
    section: its line, and beside it the cross-validated held-out reprojection of the calibrated
    model (px, mm at the board) against the fair nominal's (px), when the block has it."""
    cv = section.get("cross_validation") or {}
    c, n = cv.get("calibrated"), cv.get("nominal")
    if not c or not n:
        return section["line"]
    return (
        f"{section['line']}; cross-validated RMS over the held-out corners: {c['reprojection_rms_px']:.3f} px "
        f"({c['at_board_rms_mm']:.3f} mm at the board) against the fair nominal's "
        f"{n['reprojection_rms_px']:.3f} px"
    )


def _growth_words(me: dict, unit: str) -> str:
    """How the model error ``me`` (the block's ``model_error``) grows with a posture's distance
    (fractions of ``unit``, :func:`distance_unit`) from the calibration postures, in words
    (:mod:`selfcal.calibration.growth`)."""
    at = f" at their mean distance from the other postures ({me['reach_distance']:.3f} of {unit})"
    if me.get("growth_shown") is None:  # an older file: the growth was assumed
        return f"{at}, growing in proportion to a posture's distance from the calibration postures"
    text = (
        f"{at}, its variance growing with the squared distance from the calibration postures "
        f"({me['constant_share']:.0%} of it there constant)"
    )
    far = (
        f"; beyond {me['measured_to_distance']:.3f} of {unit} from the calibration "
        "postures it is not measured (held at its value there)"
    )
    if me["growth_shown"]:
        return f"{text} as the folds show{far}"
    return f"{text} at the most the folds allow (their 95 % upper bound: they did not show it grow){far}"


def spread_markdown(boot: dict, jack: dict | None) -> list[str]:
    """The report's lines on ``selfcal calibrate --spread N``'s bootstrap block ``boot``: its
    line and, per region, its spread (mm: RMS over the region's joint vectors, 95th percentile,
    largest) beside the jackknife's ``jack`` (absent in an older block: "-")."""
    text = spread_line(boot)
    what = ""
    if boot.get("selection") == "held":
        what = (" It is the estimation spread of the calibration's chosen model over resampled "
                "configurations: every refit fits the chosen kinematic parameters.")  # fmt: skip
    rows = ["", text[0].upper() + text[1:] + ' (docs/tool-accuracy.md "Run-to-run spread").'
            + what, "",
            "| region | bootstrap RMS | bootstrap 95 % | bootstrap max | jackknife RMS | "
            "jackknife max |", "|---|---|---|---|---|---|"]  # fmt: skip
    for name, got in boot["regions"].items():
        other = ((jack or {}).get("regions") or {}).get(name) or {}
        cells = [got["spread_mm_rms"], got["spread_mm_p95"], got["spread_mm_max"],
                 other.get("spread_mm_rms"), other.get("spread_mm_max")]  # fmt: skip
        words = ["-" if v is None else f"{v:.3f} mm" for v in cells]
        rows.append(f"| {name.replace('_', ' ')} | " + " | ".join(words) + " |")
    return rows


def zero_model_error_words(me: dict, held: dict | None, cv: dict | None) -> str:
    """Why the model error ``me`` (the block's ``model_error``) is zero, in words (empty when it
    is not): the folds' excess is counted as the held parameters' deviation ``held`` (the
    block's ``held_deviation``), whose share is the ratio of the same sums, so nothing is left
    unless the excess passes the whole prior (:mod:`selfcal.calibration.board.accuracy`); or the
    folds show no excess; or what is left is within :data:`Z_MODEL_ERROR` standard errors.
    ``cv``: the block's ``cross_validation`` (its calibrated figure is quoted)."""
    if me.get("position_mm") is None or me["position_mm"] > 0:
        return ""
    held = held or {}
    est = held.get("share_estimate")
    c = (cv or {}).get("calibrated") or {}
    px = (f" (cross-validated {c['reprojection_rms_px']:.3f} px)"
          if c.get("reprojection_rms_px") is not None else "")  # fmt: skip
    if held.get("share_basis") == "folds" and est is not None and 0 < est <= 1:
        return (f": none left, as the folds' excess over what the estimate's errors and the "
                f"noise give their held-out frames{px} is counted as the held parameters' "
                f"deviation from the drawing (below), whose share ({est:.3g} of the prior) is "
                "the ratio of the same sums: a model error is counted only where that excess "
                "passes the whole prior")  # fmt: skip
    if held.get("share_basis") == "folds" and est is not None and est <= 0:
        return (f": none, as the folds' held-out frames{px} show no excess over what the "
                "estimate's errors and the noise give them")  # fmt: skip
    return (f": none counted, as what the folds' held-out frames{px} show beyond the "
            "estimate's errors, the noise and the held parameters' deviation is within "
            f"{Z_MODEL_ERROR:g} standard errors of it")  # fmt: skip


def spread_against_prediction(spread: dict, regions: dict, cv: dict | None) -> str:
    """The jackknife spread's RMS inside the calibrated region beside the predicted RMS error
    there (one sentence with a leading space, empty without either): the spread line quotes the
    largest joint vector's spread, and the jackknife over-states the estimation error when each
    fold removes a large share of the information (few configurations for many parameters,
    docs/tool-accuracy.md), as a 7-joint arm's 12 configurations did 2.4 times."""
    got = ((spread.get("regions") or {}).get("inside") or {}).get("spread_mm_rms")
    predicted = (regions.get("inside") or {}).get("position_rms_mm")
    if got is None or not predicted:
        return ""
    ratio = got / predicted
    text = (f" Its RMS over the calibrated region is {got:.3f} mm, {ratio:.2f}x the predicted "
            f"RMS error there ({predicted:.3f} mm)")  # fmt: skip
    if ratio <= 1.5:
        return text + "."
    n = (cv or {}).get("configurations")
    few = "" if n is None else f" ({n} configurations in {spread.get('resamplings')} folds)"
    return (text + ": the jackknife's variance is biased upward when each fold removes a large "
            f"share of the information{few}, so it can over-state the calibration's own "
            "spread; the predicted RMS is the estimate of its error.")  # fmt: skip


def accuracy_markdown(section: dict) -> list[str]:
    """The report.md lines of :func:`board_accuracy_section`'s section."""
    me = section.get("model_error") or {}
    note = section.get("model_error_note") or (
        f"model error {me.get('position_mm', 0.0):.4f} mm and {me.get('rotation_deg', 0.0):.4f} "
        f"deg per coordinate from {me.get('rows')} cross-validated frames ({me.get('folds')} "
        "folds)"
        + zero_model_error_words(
            me, section.get("held_deviation"), section.get("cross_validation")
        )  # fmt: skip
    )
    note = note[:1].upper() + note[1:]
    unit = section.get("distance_unit") or "the joints' ranges"
    if not section.get("model_error_note") and me.get("reach_distance"):
        note += _growth_words(me, unit)
    elif not section.get("model_error_note") and me.get("measured_to_distance") is not None:
        note += (
            f"; beyond {me['measured_to_distance']:.3f} of {unit} from the calibration "
            "postures no fold tested the model: a model error there is not measured"
        )
    held = held_sentence(section.get("held_deviation"))
    held = "" if held is None else f" {held[0].upper()}{held[1:]}."
    rms = rms_words(section["regions"])
    rms = f"{rms} " if rms else ""
    out = [
        "",
        "## Predicted tool-point accuracy",
        "",
        f"{section['line']} ({section.get('tool_point') or 'the tool point'}). {rms}{note}."
        f"{held} See docs/tool-accuracy.md.",
        "",
        *region_table(section["regions"], orientation=True),
    ]
    drawn = drawn_words(section.get("drawn_reference"))
    if drawn is not None:
        out += ["", drawn[0].upper() + drawn[1:] + ' (docs/own-data.md "Is the calibration '
                'predicted to beat the chain as drawn?").']  # fmt: skip
    spread = section.get("spread")
    if spread:
        text = spread_line(spread)
        out += ["", text[0].upper() + text[1:] + ' (docs/tool-accuracy.md "Run-to-run spread").'
                + spread_against_prediction(spread, section["regions"],
                                            section.get("cross_validation"))]  # fmt: skip
    boot = section.get("bootstrap_spread")
    if boot:
        out += spread_markdown(boot, spread)
    cv = cross_validation_line(section.get("cross_validation"))
    if cv is not None:
        out += ["", "## Cross-validated reprojection", "", cv[0].upper() + cv[1:] + "."]
    return out
