"""The predicted tool-point accuracy of a marker-field calibration in ``selfcal report`` and
``selfcal run`` (issue #29).

Rebuilds the prediction from ``calibration.json``'s ``accuracy`` block
(:mod:`selfcal.calibration.field.accuracy`) as the board's report does
(:mod:`selfcal.pipeline.board_accuracy`): the one line "tool point within X mm (95 %) inside the
calibrated region, Y mm at its edge" with, while the field route measures no model error, that
it does not (:func:`selfcal.calibration.field.accuracy.field_accuracy_line`); the regions'
summary and table; and the workspace map ``figures/workspace_accuracy.png``
(:mod:`selfcal.plots.workspace_map`), as a figure job the caller draws (``selfcal run`` draws
its figures side by side in a worker, :mod:`selfcal.plots.figure_pool`).
"""

from __future__ import annotations

from pathlib import Path

from selfcal.calibration.accuracy import postures_from_json
from selfcal.calibration.field.accuracy import field_accuracy_line, field_error_model_from_json
from selfcal.io.calibration import CalibrationResult
from selfcal.pipeline.accuracy_table import rebuilt_regions, region_table, rms_words
from selfcal.plots.figure_pool import Job
from selfcal.plots.workspace_map import workspace_map_figure

__all__ = ["FIGURE", "field_accuracy_markdown", "field_accuracy_section"]

FIGURE = "workspace_accuracy.png"
_FIX = "re-run `selfcal calibrate DIR` to write DIR/calibration.json again"


def field_accuracy_section(root: Path, cal: CalibrationResult) -> tuple[dict | None, Job | None]:
    """The report's ``accuracy`` section of the field calibration ``cal`` in ``root`` and the
    job that draws its workspace map (``(builder, args, root, name)``); (None, None) without the
    block (a file written before it, or without bounds).

    Raises:
        InputError: the block is malformed (named, with the fix).
    """
    block = cal.accuracy
    if block is None:
        return None, None
    where = str(Path(root) / "calibration.json")
    em = field_error_model_from_json(block, cal.model, where)
    q_cal = postures_from_json(block, cal.model.n, where, fix=_FIX)
    sample, regions = rebuilt_regions(block, em, q_cal, where, fix=_FIX)
    line = field_accuracy_line(regions, block)
    section = {
        "route": "field",
        "line": line,
        "what": block.get("what"),
        "tool_point": block.get("tool_point"),
        "frame": block.get("frame"),
        "model_error": block.get("model_error"),
        "model_error_note": block.get("model_error_note"),
        "regions": regions,
    }
    job: Job = (workspace_map_figure, (em, sample, q_cal, line, "base frame"), Path(root), FIGURE)
    return section, job


def field_accuracy_markdown(section: dict) -> list[str]:
    """The report.md lines of :func:`field_accuracy_section`'s section: its line, what its
    figures are, the frame, and the table per region."""
    rms = rms_words(section["regions"])
    frame = section.get("frame") or "the chain's base frame"
    return [
        "",
        "## Predicted tool-point accuracy",
        "",
        f"{section['line'][0].upper()}{section['line'][1:]}. The tool point is "
        f"{section.get('tool_point') or 'the tool point'}, in {frame}. "
        + (f"{rms} " if rms else "")
        + "See docs/tool-accuracy.md.",
        "",
        *region_table(section["regions"], orientation=True),
    ]
