"""``selfcal report DIR`` of a tracker calibration (``selfcal identify``'s DIR): the predicted
tool-point accuracy over the workspace (issue #29).

Rebuilds the prediction from ``DIR/calibration.json``'s ``accuracy`` block
(:mod:`selfcal.calibration.tracker.accuracy`) and writes ``DIR/report.json``, ``DIR/report.md``
and the workspace map ``DIR/figures/workspace_accuracy.png``
(:mod:`selfcal.plots.workspace_map`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from selfcal.calibration.tracker.accuracy import (
    SAMPLE_COUNT,
    error_model_from_json,
    postures_from_json,
)
from selfcal.calibration.tracker.calibration_file import read_tracker_calibration
from selfcal.calibration.tracker.cross_validation import cross_validation_line
from selfcal.calibration.tracker.spread import spread_line
from selfcal.errors import InputError
from selfcal.io.atomic import write_text_atomic
from selfcal.io.jsonfile import write_json_atomic
from selfcal.kinematics.tool_error import accuracy_line, workspace_sample, workspace_summary
from selfcal.pipeline.accuracy_table import region_table
from selfcal.plots.job_figures import write_figure
from selfcal.plots.workspace_map import workspace_map_figure

__all__ = ["tracker_report", "tracker_report_summary"]

FIGURE = "workspace_accuracy.png"


def tracker_report(root: Path, *, figures: bool = True) -> dict:
    """The report of the tracker calibration in ``root`` (module docstring); returns report.json.

    Raises:
        InputError: the calibration has no ``accuracy`` block (written before it, or fitted to
            distances alone) or the block is malformed.
    """
    path = Path(root) / "calibration.json"
    cal = read_tracker_calibration(path)
    block = cal.accuracy
    if block is None:
        raise InputError(
            f"{path} has no predicted accuracy (written before it, or fitted to distances "
            "alone, which do not place the tracker frame)",
            fix=f"re-run `selfcal identify` with position or pose rows into {root}",
        )
    em = error_model_from_json(block, cal.model, cal.T_meas_fit, cal.names, cal.poses, str(path))
    q_cal = postures_from_json(block, cal.n, str(path))
    sample = workspace_sample(q_cal, cal.joint_limits, count=SAMPLE_COUNT)
    regions = workspace_summary(em, sample, q_cal)
    line = accuracy_line(regions)
    report: dict[str, Any] = {
        "kind": "tracker",
        "status": "ok",
        "failures": [],
        "accuracy": {k: v for k, v in block.items() if k not in ("covariance_si",)} | {
            "regions": regions, "line": line},
        "cross_validation": cal.fit.get("cross_validation"),
        "figures": [],
    }  # fmt: skip
    if figures:
        out = write_figure(
            workspace_map_figure(em, sample, q_cal, line, "tracker frame"), root, FIGURE
        )
        report["figures"] = [str(out.relative_to(root))]
    write_json_atomic(Path(root) / "report.json", report)
    write_text_atomic(Path(root) / "report.md", _markdown(report))
    return report


def _markdown(report: dict) -> str:
    acc = report["accuracy"]
    me = acc.get("model_error") or {}
    figs = "".join(f"\n![{f}]({f})\n" for f in report["figures"])
    note = acc.get("model_error_note") or (
        f"model error {me.get('position_mm', 0.0):.4f} mm per coordinate from {me.get('rows')} "
        f"cross-validated rows ({me.get('folds')} folds)"
    )
    spread = acc.get("spread")
    if spread:
        note += f".\n\n{spread_line(spread)}"
    cv = cross_validation_line(report.get("cross_validation"))
    if cv is not None:
        note += (f".\n\n{cv[0].upper()}{cv[1:]} (the fair nominal: the robot file's chain with "
                 "the tracker frame and tool fitted; each fitted to the other folds' rows)")  # fmt: skip
    return (
        "# Tracker calibration: predicted tool-point accuracy\n\n"
        f"{report['accuracy']['line']}\n\n{note}. See docs/tool-accuracy.md.\n\n"
        + "\n".join(region_table(acc["regions"]))
        + "\n"
        + figs
    )


def tracker_report_summary(report: dict, root: Path) -> str:
    """The line ``selfcal report`` prints for a tracker calibration: the predicted accuracy and
    the k-fold held-out RMS beside the fair nominal's, when the calibration has it."""
    cv = cross_validation_line(report.get("cross_validation"))
    more = "" if cv is None else f"; {cv}"
    return f"report: {report['accuracy']['line']}{more}; {Path(root) / 'report.json'}"
