"""The predicted tool-point accuracy per region in ``report.md`` (issue #29), what every route's
report shares: the tracker route's (:mod:`selfcal.pipeline.tracker_report`), the board route's
(:mod:`selfcal.pipeline.board_accuracy`) and the field route's
(:mod:`selfcal.pipeline.field_accuracy`): the regions rebuilt from a ``calibration.json``
``accuracy`` block (:func:`rebuilt_regions`), their table (:func:`region_table`) and what the
line's figures are (:func:`rms_words`), from a
:func:`selfcal.kinematics.tool_error.workspace_summary`."""

from __future__ import annotations

import numpy as np

from selfcal.calibration.accuracy import SAMPLE_COUNT
from selfcal.errors import InputError
from selfcal.kinematics.tool_error import (
    ToolErrorModel,
    WorkspaceSample,
    workspace_sample,
    workspace_summary,
)

__all__ = ["rebuilt_regions", "region_table", "rms_words"]


def rebuilt_regions(block: dict, em: ToolErrorModel, q_cal: np.ndarray, where: str, *,
                    fix: str) -> tuple[WorkspaceSample, dict]:  # fmt: skip
    """The workspace sample of an ``accuracy`` block (its ``joint_limits_si``, the calibration
    postures ``q_cal`` (m, n) rad / m) and the regions' summary of the error model ``em`` rebuilt
    from it, as the calibration wrote them (:data:`SAMPLE_COUNT` joint vectors per region).

    Raises:
        InputError: ``joint_limits_si`` is not n finite rows of [low, high] (``where``, ``fix``).
    """
    n = em.model.n
    limits = np.asarray(block.get("joint_limits_si", []), dtype=float)
    if limits.shape != (n, 2) or not np.all(np.isfinite(limits)):
        raise InputError(f"{where}: accuracy.joint_limits_si must be {n} rows of [low, high]",
                         fix=fix)  # fmt: skip
    sample = workspace_sample(q_cal, limits, count=SAMPLE_COUNT)
    return sample, workspace_summary(em, sample, q_cal)


def region_table(regions: dict, *, orientation: bool = False) -> list[str]:
    """Markdown lines: per region (the calibration postures, inside, edge, workspace) its point
    count, median and largest 95 % bound and RMS (mm), with ``orientation`` the largest 95 %
    orientation bound (deg)."""
    cols = ["region", "points", "median 95 % (mm)", "largest 95 % (mm)", "RMS (mm)"]
    cols += ["largest 95 % orientation (deg)"] if orientation else []
    rows = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    for name in ("calibration_postures", "inside", "edge", "workspace"):
        r = regions[name]
        if not r.get("points"):
            rows.append(f"| {name} | 0 | | | |" + (" |" if orientation else ""))
            continue
        row = (f"| {name} | {r['points']} | {r['position_95_mm_median']:.4f} | "
               f"{r['position_95_mm_max']:.4f} | {r['position_rms_mm']:.4f} |")  # fmt: skip
        if orientation:
            row += f" {r.get('orientation_95_deg_max', float('nan')):.4f} |"
        rows.append(row)
    return rows


def rms_words(regions: dict) -> str:
    """What the accuracy line's figures are, and the predicted RMS beside them (one sentence,
    empty without the inside region): the line quotes the largest of a region's joint vectors'
    95 % bounds of the error's norm, which a measured RMS is not to be set against (a 7-joint
    arm's line read 0.275 mm where the predicted RMS inside was 0.098 mm)."""
    inside = regions.get("inside") or {}
    if inside.get("position_rms_mm") is None:
        return ""
    at = regions.get("calibration_postures") or {}
    there = ("" if at.get("position_rms_mm") is None else
             f", {at['position_rms_mm']:.3f} mm at the calibration postures")  # fmt: skip
    return (f"Those are the largest of each region's joint vectors' 95 % bounds of the error's "
            f"norm; the predicted RMS error is {inside['position_rms_mm']:.3f} mm inside the "
            f"calibrated region{there} (the figure to set beside a measured RMS).")  # fmt: skip
