"""The predicted tool-point accuracy of a simulated board run against the truth, in the
prediction's own terms (issue #29).

``selfcal run``'s validation figure (:mod:`selfcal.pipeline.board_run`) is the scenario's tool
tip after the best rigid alignment of the calibrated tips onto the true ones: the alignment
removes whatever error is common to every posture (the board's pose in the base, a shift of the
whole chain). The predicted accuracy (``calibration.json`` ``accuracy``,
:mod:`selfcal.calibration.board.accuracy`) is the flange's error in the board frame (eye-to-hand
the first camera's) with no alignment, and report.md's headline quotes the largest 95 % bound
of a region's joint vectors, not an RMS. Set side by side, a 7-joint arm's run read "calibrated
0.025 mm RMS" against "within 0.275 mm (95 %)" (11x), though its prediction is 1.4x the true
error of the point it predicts. This module gives the comparison that is fair: the true error
of the prediction's own point, in its own frame, unaligned, at the validation postures, against
the predicted RMS and 95 % bounds there. Truth is read here only (simulated runs). mm.
"""

from __future__ import annotations

import numpy as np

from selfcal.calibration.board.accuracy import board_error_model_from_json
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.io.truth import Truth
from selfcal.kinematics.alignment import express_in_frame
from selfcal.kinematics.forward import fk_tool
from selfcal.transforms import inv_pose

__all__ = ["predicted_against_truth", "predicted_against_truth_words", "predicted_point_markdown"]


def predicted_against_truth(cal: BoardCalibrationResult, truth: Truth,
                            q: np.ndarray) -> dict | None:  # fmt: skip
    """At the validation joints ``q`` (m, n) rad / m: the true error of ``cal``'s predicted
    point (its ``accuracy`` block's tool point, in the board frame or eye-to-hand the first
    camera's; no alignment) against ``truth``'s chain, and what the block predicts there. None
    without the block, a board pose in the truth, an eye-to-hand chain (its truth's camera frame
    is not written) or postures. Keys (mm): ``true_rms_mm``, ``true_max_mm``,
    ``predicted_rms_mm`` (RMS over the postures of each one's predicted RMS), ``within_95``
    (how many postures' true error is within their predicted 95 % bound), ``poses``,
    ``tool_point`` (the block's words), ``what``."""
    block = cal.accuracy
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if block is None or truth.T_world_board is None or cal.eye_to_hand or not q.size:
        return None
    em = board_error_model_from_json(block, cal.model, "calibration.json")
    tip = np.asarray(block.get("T_tool_point_si", np.eye(4)), dtype=float)
    true_b = express_in_frame(truth.true_model, inv_pose(truth.T_world_board), like=cal.model)
    e = np.linalg.norm((fk_tool(cal.model, q) @ tip)[:, :3, 3]
                       - (fk_tool(true_b, q) @ tip)[:, :3, 3], axis=1) * 1e3  # fmt: skip
    p = em.predicted(q)
    return {
        "what": "the predicted accuracy's own point (accuracy.tool_point) in the board frame "
        "with no alignment, at the validation postures: its true error against the predicted "
        "RMS and 95 % bound there (the tool-tip figure is after the best rigid alignment, which "
        "removes the error common to every posture)",
        "tool_point": block.get("tool_point") or "the flange",
        "poses": len(q),
        "true_rms_mm": float(np.sqrt(np.mean(e**2))),
        "true_max_mm": float(e.max()),
        "predicted_rms_mm": float(np.sqrt(np.mean(p["position_rms_mm"] ** 2))),
        "within_95": int(np.sum(e <= p["position_95_mm"])),
    }


def predicted_against_truth_words(got: dict | None) -> str | None:
    """One sentence of :func:`predicted_against_truth`'s ``got`` for report.md and ``selfcal
    run`` (None without it)."""
    if not got:
        return None
    ratio = got["predicted_rms_mm"] / max(got["true_rms_mm"], 1e-12)
    return (f"the predicted accuracy's point ({got['tool_point']}) in the board frame, no "
            f"alignment, at the {got['poses']} validation postures: true error "
            f"{got['true_rms_mm']:.3f} mm RMS (max {got['true_max_mm']:.3f}) against the "
            f"predicted {got['predicted_rms_mm']:.3f} mm RMS ({ratio:.2f}x), "
            f"{got['within_95']}/{got['poses']} within their predicted 95 % bound")  # fmt: skip


def predicted_point_markdown(got: dict | None) -> list[str]:
    """report.md's paragraph of :func:`predicted_against_truth`'s ``got`` below the validation
    table's aligned tool-tip figures (empty without it)."""
    words = predicted_against_truth_words(got)
    if words is None:
        return []
    return ["", f"The tool-tip figures are after the best rigid alignment; {words} (the figure "
            "to set beside the predicted tool-point accuracy below)."]  # fmt: skip
