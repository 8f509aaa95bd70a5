"""The table of the predicted tool-point accuracy per region in ``report.md`` (issue #29): the
tracker route's (:mod:`selfcal.pipeline.tracker_report`) and the board route's
(:mod:`selfcal.pipeline.board_accuracy`), from a
:func:`selfcal.kinematics.tool_error.workspace_summary`."""

from __future__ import annotations

__all__ = ["region_table"]


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
