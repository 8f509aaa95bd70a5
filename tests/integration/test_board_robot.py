"""Robot calibration with a board (selfcal/calibration/board/robot.py) on the analytic path.

The default scenario's postures and true robot (simulated acquisition without rendering,
quantised joint read-back), one camera (the left one) and a ChArUco board lying on the table
where the marker field is; the board's corners are projected with the true camera and poses plus
0.1 px Gaussian noise. No known distance is given: the board's geometry gives the scale, and its
frame is the world. Measured (seed 0): camera errors / sigma fx +1.05, mu -1.17, cx -0.42,
cy -1.59; tool-tip RMS over the validation postures 0.094 mm after the refinement (0.46 mm after
the two-stage fit, 7.2 mm with the nominal kinematics), reprojection RMS 0.139 px.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from selfcal.benchmarks.board.views import board_pose, board_views
from selfcal.calibration.board.robot import calibrate_robot_with_board
from selfcal.config.scenario import load_scenario
from selfcal.estimation.joint_report import encoder_sigma
from selfcal.io.dataset import Dataset
from selfcal.io.truth import read_truth
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc
from selfcal.pipeline.run import run_acquire
from selfcal.robot.definition import load_robot
from selfcal.target import Charuco
from selfcal.transforms import inv_pose

BOARD = Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    out = tmp_path_factory.mktemp("board_robot")
    run_acquire(load_scenario(overrides={"noise": {"render": False}}), out, quiet=True)
    ds, truth = Dataset.open(out), read_truth(out / "truth.json")
    T_world_board = board_pose(truth, BOARD)
    feats, _ = board_views(truth, ds.indices, truth.intrinsics_left, T_world_board, 0.1, 0, BOARD)
    return ds, truth, T_world_board, feats


def test_camera_hand_eye_and_kinematics_from_a_board(scene):
    ds, truth, T_world_board, feats = scene
    robot = load_robot(ds.info.robot_model)
    nominal = nominal_mcpc(robot).with_tool(robot.T_flange_cam)
    W, H = ds.info.resolution
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # frames that do not see the board; identification notes
        res = calibrate_robot_with_board(
            BOARD, feats, np.radians(ds.joints_deg), nominal, W, H,
            joint_sigma=encoder_sigma(robot),
        )  # fmt: skip
    cam = truth.intrinsics_left
    for n in ("fx", "mu", "cx", "cy"):
        assert abs(getattr(res.camera, n) - getattr(cam, n)) < 3 * res.camera_std[n], n
    q = np.radians(ds.info.validation_joints_deg)
    assert len(q) >= 5

    def tip_errors_mm(model):
        tips = (fk_tool(model, q) @ truth.T_cam_tip)[:, :3, 3]
        true = inv_pose(T_world_board)[None] @ fk_tool(truth.true_model, q) @ truth.T_cam_tip
        return 1000 * np.linalg.norm(tips - true[:, :3, 3], axis=1)

    refined = np.sqrt(np.mean(tip_errors_mm(res.model) ** 2))
    two_stage = np.sqrt(np.mean(tip_errors_mm(res.identification.model) ** 2))
    assert refined < 0.3  # measured 0.094 mm
    assert refined < 0.5 * two_stage  # measured 0.46 mm
    assert res.rms_px < 0.2  # measured 0.139 px: the 0.1 px per coordinate noise
