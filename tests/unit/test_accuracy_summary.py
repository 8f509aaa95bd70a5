"""The printed summary of a board calibration's predicted tool-point accuracy (issue #29): the
prediction's line and, beside it, the cross-validated held-out reprojection of the calibrated
model and the fair nominal, in ``selfcal report``'s line and in the eye-to-hand run's."""

from __future__ import annotations

from pathlib import Path

from selfcal.pipeline.board_accuracy import accuracy_markdown
from selfcal.pipeline.report_text import report_summary
from selfcal.pipeline.static_report import PREDICTED_WHERE, static_summary

LINE = "tool point within 0.412 mm (95 %) inside the calibrated region, 0.807 mm at its edge"
CV = {
    "configurations": 6,
    "folds": 6,
    "calibrated": {"reprojection_rms_px": 0.3212, "at_board_rms_mm": 0.3004, "corners": 900},
    "nominal": {"reprojection_rms_px": 4.2049, "at_board_rms_mm": 3.951, "corners": 900},
}
WORDS = "cross-validated RMS over the held-out corners: 0.321 px (0.300 mm at the board) against the fair nominal's 4.205 px"


def _fit(accuracy: dict | None) -> dict:
    rep = {
        "kind": "fit",
        "fit": {"reprojection_rms_px": 0.25},
        "held_out": {"reprojection_rms_px": {"calibrated": 0.3, "nominal": 4.0}, "images": 6,
                     "source": "leave-poses-out"},
    }  # fmt: skip
    return rep if accuracy is None else {**rep, "accuracy": accuracy}


def _eye_to_hand(accuracy: dict | None) -> dict:
    pose = {"position_mm": {"rms": 0.23}}
    rep = {
        "kind": "eye-to-hand-truth",
        "camera": {"fx": {"z": 1.2}},
        "mounts": [{"max_abs_z": 2.1}],
        "validation": {"poses": 6, "board_pose_in_camera": {"calibrated": pose,
                                                            "nominal": pose}},
    }  # fmt: skip
    return rep if accuracy is None else {**rep, "accuracy": accuracy}


def test_the_report_line_gives_the_cross_validated_error_beside_the_prediction():
    line = report_summary(_fit({"line": LINE, "cross_validation": CV}), Path("cal"))
    assert f"{LINE}; {WORDS}; " in line


def test_without_a_cross_validation_the_line_is_the_prediction_alone():
    line = report_summary(_fit({"line": LINE, "cross_validation": None}), Path("cal"))
    assert f"; {LINE}; cal/report.json" in line and "cross-validated" not in line


def test_the_eye_to_hand_run_prints_the_prediction_and_the_cross_validation():
    line = static_summary(_eye_to_hand({"line": LINE, "cross_validation": CV}), Path("run"))
    assert line.startswith("eye-to-hand: camera parameters within 1.20 sigma")
    assert f"; predicted {PREDICTED_WHERE}: {LINE}; {WORDS}; details in run/report.md" in line


def test_the_eye_to_hand_line_of_a_report_without_the_block_is_unchanged():
    line = static_summary(_eye_to_hand(None), Path("run"))
    assert "tool point" not in line and line.endswith("calibrated 0.230 mm RMS; details in "
                                                      "run/report.md")  # fmt: skip


def test_report_md_says_when_the_model_error_grows_away_from_the_postures():
    regions = {k: {"points": 0} for k in ("calibration_postures", "inside", "edge", "workspace")}
    me = {"position_mm": 0.03, "rotation_deg": 0.004, "rows": 30, "folds": 5}
    section = {"line": "tool point within 0.3 mm (95 %)", "regions": regions, "model_error": me}
    flat = "\n".join(accuracy_markdown(section))
    grown = "\n".join(accuracy_markdown({**section, "model_error": {**me, "reach_distance": 0.12}}))
    assert "Model error 0.0300 mm" in flat and "growing" not in flat
    assert "(0.120 of the joints' ranges), growing in proportion" in grown
    # how the folds saw it grow (selfcal/calibration/growth.py): shown, or only bounded
    read = {**me, "reach_distance": 0.12, "constant_share": 0.25, "measured_to_distance": 0.31}
    shown = "\n".join(accuracy_markdown({**section, "model_error": {**read, "growth_shown": True}}))
    assert "(25% of it there constant) as the folds show; beyond 0.310 of the joints'" in shown
    bound = "\n".join(accuracy_markdown({**section, "model_error": {**read,
                                                                    "growth_shown": False}}))  # fmt: skip
    assert "at the most the folds allow" in bound
    assert (
        "beyond 0.310 of the joints' ranges from the calibration postures it is not measured"
        in bound
    )
    assert "held at its value there" in bound and "held at its value there" in shown
    # none found: how far the folds tested the model is said all the same
    none = {**me, "position_mm": 0.0, "measured_to_distance": 0.07}
    untested = "\n".join(accuracy_markdown({**section, "model_error": none}))
    assert ("Model error 0.0000 mm" in untested and "beyond 0.070 of the joints' ranges from the "
            "calibration postures no fold tested the model" in untested)  # fmt: skip
    assert "no fold tested" not in flat
    # tested only at the training postures (0): a limit too, said as one
    zero = "\n".join(accuracy_markdown({**section, "model_error": {**none,
                                                                   "measured_to_distance": 0.0}}))  # fmt: skip
    assert "beyond 0.000 of the joints' ranges from the calibration postures no fold" in zero


def test_report_md_says_why_the_model_error_is_zero():
    """report.md said "model error 0.0000 mm" beside a cross-validated 1.768 px against the
    fit's 0.600 px with no reason (photoneo, new user's trip, session 25). The reason: the
    board route counts the folds' excess as the held parameters' deviation, whose share's point
    estimate is the ratio of the same sums (selfcal/calibration/board/accuracy.py
    `model_error`), so none is left unless the excess passes the whole prior; the line now says
    so, or that the folds show no excess, or that what is left is within 2 standard errors."""
    regions = {k: {"points": 0} for k in ("calibration_postures", "inside", "edge", "workspace")}
    me = {"position_mm": 0.0, "rotation_deg": 0.0, "rows": 20, "folds": 5,
          "measured_to_distance": 0.172}  # fmt: skip
    held = {"share": 0.0203, "share_basis": "folds", "share_folds": 5, "share_estimate": 0.0141,
            "translation_mm": 1.0, "rotation_deg": 0.5}  # fmt: skip
    cv = {"configurations": 5, "folds": 5,
          "calibrated": {"reprojection_rms_px": 1.768, "at_board_rms_mm": 0.41},
          "nominal": {"reprojection_rms_px": 1.96, "at_board_rms_mm": 0.45}}  # fmt: skip
    section = {"line": "tool point within 6.7 mm (95 %)", "regions": regions, "model_error": me,
               "held_deviation": held, "cross_validation": cv}  # fmt: skip
    text = "\n".join(accuracy_markdown(section))
    assert ("Model error 0.0000 mm and 0.0000 deg per coordinate from 20 cross-validated frames "
            "(5 folds): none left, as the folds' excess over what the estimate's errors and the "
            "noise give their held-out frames (cross-validated 1.768 px) is counted as the held "
            "parameters' deviation from the drawing (below), whose share (0.0141 of the prior) "
            "is the ratio of the same sums") in text  # fmt: skip
    assert "beyond 0.172 of the joints' ranges" in text  # the limit still said after it
    none = "\n".join(
        accuracy_markdown({**section, "held_deviation": {**held, "share_estimate": -0.2}})
    )
    assert "none, as the folds' held-out frames (cross-validated 1.768 px) show no excess" in none
    small = "\n".join(
        accuracy_markdown({**section, "held_deviation": {**held, "share_estimate": 1.4}})
    )
    assert "none counted, as what the folds' held-out frames" in small
    assert "within 2 standard errors of it" in small
    found = "\n".join(accuracy_markdown({**section, "model_error": {**me, "position_mm": 0.03}}))
    assert "Model error 0.0300 mm" in found and "none" not in found
