"""The cell ``selfcal plan --add`` plans in, read out of a board calibration: what differs
between the two mounts (:mod:`selfcal.calibration.board.plan.add` holds what they share).

- eye-in-hand (the camera on the flange, the board still): the board where the calibration
  placed it (base -> board) and the camera where it placed it on the flange (the robot file's
  ``T_flange_cam`` replaced); the view rule :data:`ADD_RULE`. How far the robot file's camera
  mount lies from the calibrated one is kept: the chain as drawn goes by the file's mount;
- eye-to-hand (the camera still, the board on the flange): the camera where the calibration
  placed it in the base (base -> camera) and the board where it placed it on the flange
  (flange -> board), both read out of the chain as ``calibration.json``'s ``mounts`` are
  (:func:`selfcal.calibration.board.mounts.mounts`); the view rule the eye-to-hand plan's
  (:data:`selfcal.calibration.board.plan.views.EYE_TO_HAND_RULE`, which asks no marker cell
  size either). The robot file's camera mount plays no part (the chain as drawn is the flange
  itself, which the board mount's deviation does not move:
  :mod:`selfcal.calibration.board.plan.reference`), so its distance is zero.

Units: m, rad.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.mounts import mounts
from selfcal.calibration.board.plan.views import PlanSetup, ViewRule
from selfcal.camera import CameraModel
from selfcal.io.board_calibration import BoardCalibrationResult
from selfcal.robot.definition import RobotDef
from selfcal.target.boards import Board
from selfcal.transforms import inv_pose

__all__ = ["ADD_RULE", "calibrated_cell"]

ADD_RULE = ViewRule(min_module_px=0.0)
"""The view rule of the postures added to an eye-in-hand dataset: a new plan's without its
marker cell limit. With the limit, the simulated wrist-only benchmark's third truth (``python -m
selfcal.benchmarks.plan.add``, tests/integration/test_plan_add_wrist.py) calibrated its 6 + 5
frames to 4.52 mm (the camera 6.4 sigma from its truth) where its 6 frames gave 2.13 mm; without
it 0.87 mm. Why the nearer views the limit asks make that calibration fail is not found."""


def calibrated_cell(
    cal: BoardCalibrationResult,
    robot: RobotDef,
    camera: CameraModel,
    board: Board,
    boxes: np.ndarray,
) -> tuple[PlanSetup, tuple[float, float]]:
    """The plan's cell of the one-camera board calibration ``cal`` of ``robot`` (module
    docstring): the :class:`PlanSetup` with the calibrated ``camera``, the ``board`` and the
    keep-out ``boxes`` (b, 6) m in the base frame, and how far the robot file's camera mount
    lies from the calibrated one (rotation rad, translation m; eye-to-hand zero)."""
    if cal.eye_to_hand:
        T_base_cam, T_flange_board = (m.T for m in mounts(cal.model, robot, eye_to_hand=True))
        cell = PlanSetup.eye_to_hand_setup(robot, camera, board, T_base_cam, T_flange_board,
                                           boxes)  # fmt: skip
        return cell, (0.0, 0.0)
    T_flange_cam, T_base_board = (m.T for m in mounts(cal.model, robot, eye_to_hand=False))
    d = inv_pose(robot.T_flange_cam) @ T_flange_cam
    off = (float(Rotation.from_matrix(d[:3, :3]).magnitude()),
           float(np.linalg.norm(T_flange_cam[:3, 3] - robot.T_flange_cam[:3, 3])))  # fmt: skip
    robot = dataclasses.replace(robot, T_flange_cam=T_flange_cam)
    return PlanSetup(robot, camera, board, T_base_board, boxes, ADD_RULE), off
