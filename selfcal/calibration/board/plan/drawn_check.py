"""Whether a board calibration is predicted to beat the chain as drawn (issue #29, ``selfcal
calibrate``'s ``accuracy.drawn_reference``).

``selfcal plan`` warns when a plan is not predicted to beat the error without calibrating the
kinematics (:mod:`selfcal.calibration.board.plan.reference`); a calibration without truth
said nothing of it (a pan-tilt with a wrist camera turns the camera about nearly one point, so
the mount's translation is poorly determined and the calibration may land farther than the
drawing). Here the same references are computed for the calibration's own frames and cell (the
cell ``selfcal plan --add`` plans in, :func:`selfcal.calibration.board.plan.add.calibration_plan`;
the deviation the calibration was given, default
:class:`selfcal.calibration.board.deviation.Deviation`, as plan's) over the accuracy block's
own "inside" sample (:func:`selfcal.kinematics.tool_error.workspace_sample` of the calibration
postures, the sample whose predicted RMS ``regions.inside.position_rms_mm`` is), and that RMS
is set against them: the calibration is predicted to beat the chain as drawn when its RMS is at
most :data:`selfcal.calibration.board.plan.reference.CLEAR_MARGIN` times the drawing's. The
calibration's figure is the accuracy block's, in its world frame with no alignment; the
drawing's is after the best rigid alignment (plan's), which can only lower an error: the
comparison leans against the calibration by what the placement's own error adds.

Nothing is said where the chain as drawn is no reference (the robot file's camera mount far
from the calibrated one: :func:`selfcal.calibration.board.plan.add.drawn_mount_words`), nor for
a calibration of more than one camera or without the accuracy block's RMS. Units: m inside, mm
in the block.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from selfcal.calibration.accuracy import SAMPLE_COUNT
from selfcal.calibration.board.accuracy import board_postures_from_json
from selfcal.calibration.board.deviation import Deviation
from selfcal.calibration.board.plan.add import calibration_plan, drawn_mount_words
from selfcal.calibration.board.plan.ground import PlanOptions
from selfcal.calibration.board.plan.information import board_model, frame_information
from selfcal.calibration.board.plan.reference import CLEAR_MARGIN, nominal_reference
from selfcal.errors import InputError
from selfcal.estimation.joint_report import aligned_tool_weight
from selfcal.kinematics.tool_error import workspace_sample

if TYPE_CHECKING:
    from collections.abc import Sequence

    from selfcal.calibration.board.dataset import BoardDatasetCalibration
    from selfcal.io.board_calibration import BoardCalibrationResult
    from selfcal.target.base import Features

__all__ = ["KEY", "drawn_reference", "drawn_words", "with_drawn_reference"]

KEY = "drawn_reference"
"""The key of calibration.json's ``accuracy`` block this module writes."""


def drawn_reference(
    root: str | Path,
    cal: BoardCalibrationResult,
    features: Sequence[Features],
    q: np.ndarray,
    deviation: Deviation | None = None,
) -> dict | None:
    """The block (module docstring) of the one-camera calibration ``cal`` of the dataset
    ``root``, its first camera's ``features`` of every frame and the frames' read-back joints
    ``q`` (m, n) rad; None when nothing is to be said (no accuracy RMS, a rig, a cell that
    cannot be rebuilt). Keys: ``calibrated_tool_rms_mm`` (the accuracy block's inside RMS),
    ``drawn_tool_rms_mm`` (None when the drawing is no reference, with
    ``drawn_not_a_reference`` saying why), ``fair_nominal_tool_rms_mm``, ``clear_margin``,
    ``beats_drawn`` (None without a reference) and ``note``."""
    block = cal.accuracy or {}
    inside = (block.get("regions") or {}).get("inside") or {}
    rms_mm = inside.get("position_rms_mm")
    limits = np.asarray(block.get("joint_limits_si", []), dtype=float)
    if rms_mm is None or len(cal.cameras) != 1 or limits.shape != (cal.model.n, 2):
        return None
    dev = Deviation() if deviation is None else deviation
    try:
        plan = calibration_plan(root, cal, features, q)
    except InputError:  # a chain whose base frame cannot be rebuilt: no plan's cell
        return None
    setup = plan.setup
    model = board_model(setup)
    q_cal = board_postures_from_json(block, cal.model.n, f"{root}/calibration.json")
    sample = workspace_sample(q_cal, limits, count=SAMPLE_COUNT).inside
    G = aligned_tool_weight(model, sample, setup.T_tool_tip)
    opts = PlanOptions(deviation=dev)
    F = frame_information(setup, plan.q, opts.pixel_sigma_px, opts.joint_sigma, plan.seen)
    ref = nominal_reference(model, F.sum(axis=0), G, setup.camera.n_free,
                            dev.drawn_variance(model.joint_types),
                            eye_to_hand=setup.eye_to_hand,
                            drawn_why=drawn_mount_words(plan, dev))  # fmt: skip
    out = ref.to_json()
    drawn_mm = out["drawn_tool_rms_mm"]
    return {
        "calibrated_tool_rms_mm": round(float(rms_mm), 4),
        "drawn_tool_rms_mm": drawn_mm,
        "drawn_not_a_reference": out["drawn_not_a_reference"],
        "fair_nominal_tool_rms_mm": out["fair_nominal_tool_rms_mm"],
        "clear_margin": CLEAR_MARGIN,
        "beats_drawn": None if drawn_mm is None else bool(rms_mm <= CLEAR_MARGIN * drawn_mm),
        "note": (
            "the calibration's predicted tool-point RMS inside the calibrated region "
            "(regions.inside) against what selfcal plan computes without calibrating the "
            "kinematics for the same frames and the same sample: " + out["note"]
        ),
    }


def with_drawn_reference(
    root: str | Path,
    cal: BoardCalibrationResult,
    detailed: BoardDatasetCalibration,
    deviation: Deviation | None = None,
) -> BoardCalibrationResult:
    """``cal`` (the result of ``detailed``, the calibration of the dataset ``root``, or it with
    more accuracy keys) with :func:`drawn_reference`'s block as ``accuracy[KEY]``; ``cal`` as
    it is when nothing is to be said. The one place both ``selfcal calibrate`` and the API's
    ``selfcal.calibrate`` add it."""
    if cal.accuracy is None:
        return cal
    drawn = drawn_reference(root, cal, detailed.features[0], detailed.q, deviation)
    if drawn is None:
        return cal
    return dataclasses.replace(cal, accuracy={**cal.accuracy, KEY: drawn})


def drawn_words(block: dict | None) -> str | None:
    """The sentence of calibrate's summary and report.md when the calibration is not predicted
    to beat the chain as drawn (``block`` :func:`drawn_reference`'s), with both figures and the
    fix; None when it is, or when the drawing is no reference."""
    if not block or block.get("beats_drawn") is not False:
        return None
    cal, drawn = block["calibrated_tool_rms_mm"], block["drawn_tool_rms_mm"]
    return (
        f"NOT predicted to beat the chain as drawn: the calibrated tool point's predicted RMS "
        f"inside the calibrated region is {cal:.3f} mm against the drawing's {drawn:.3f} mm "
        f"({cal / drawn:.2f} times it, a clear gain is at most {block['clear_margin']:g}); the "
        "drawing may be the better model: record postures that turn the camera about other "
        "axes (`selfcal plan --add K DATASET` chooses them) and calibrate again, or keep the "
        "drawing"
    )
