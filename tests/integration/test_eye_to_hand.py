"""Eye-to-hand with joints (issue #28 item 1): a static camera, the board on the flange, on the
board route's own machinery with the chain inverted (selfcal/calibration/board/robot.py,
``eye_to_hand=True``).

The cell is selfcal/sim/static_camera.py's: a UR5e whose minimal parameters (board mount
included) are perturbed by up to 1 mm / 0.1 deg, the ChArUco of models/targets/charuco.toml on
its flange, a 640 x 480 pinhole 0.6 m in front of it at the cell's home (the wrist turned so the
board faces away from the arm); 6 arm configurations x 5 wrist orientations. The features are projected analytically (the rendered run is
tests/integration/test_eye_to_hand_rendered.py). The truth never enters the calibration; it is
compared afterwards: noise-free, the board's poses at postures not used and the mounts agree to
1e-6 (measured 1e-15 m / 2e-13 deg); with 0.1 px of corner noise the camera, base -> camera and
flange -> board fall within 3 sigma of the Cramer-Rao covariance at the estimate (measured
|z| <= 1.7).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.bounds import board_cramer_rao
from selfcal.calibration.board.mounts import mounts
from selfcal.calibration.board.robot import calibrate_robot_with_board
from selfcal.camera import Pinhole
from selfcal.io.target_toml import load_target
from selfcal.kinematics.forward import fk_tool
from selfcal.kinematics.mcpc import nominal_mcpc, param_names
from selfcal.robot.definition import load_robot
from selfcal.sim.static_camera import plan_static_postures, project_views, static_camera_truth

FREE = ("fx", "mu", "cx", "cy")


@pytest.fixture(scope="module")
def cell():
    robot = load_robot("ur5e")
    board = load_target("models/targets/charuco.toml")
    cam = Pinhole(900.0, 1.0, 326.0, 233.0, 640, 480, FREE)
    truth = static_camera_truth(robot, board, cam, seed=1)
    return truth, plan_static_postures(truth, 6, 5, seed=0)


def _calibrate(truth, q, feats):
    nominal = nominal_mcpc(truth.robot).with_tool(truth.T_flange_board_nominal)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the two-stage identification's notes
        return calibrate_robot_with_board(truth.board, feats, q, nominal, 640, 480, free=FREE,
                                          eye_to_hand=True)  # fmt: skip


def _errors(a, b) -> tuple[np.ndarray, np.ndarray]:
    """(rotation vector rad, translation m) of ``a`` against ``b`` in the parent's axes."""
    return Rotation.from_matrix(a[:3, :3] @ b[:3, :3].T).as_rotvec(), a[:3, 3] - b[:3, 3]


@pytest.mark.slow  # 3-6 s: the cross-validation of four candidates over six folds
def test_noise_free_eye_to_hand_is_exact(cell):
    truth, q = cell
    res = _calibrate(truth, q, project_views(truth, q))
    assert res.rms_px < 1e-9
    for n in FREE:
        assert getattr(res.camera, n) == pytest.approx(getattr(truth.camera, n), rel=1e-9), n
    held_out = plan_static_postures(truth, 3, 2, seed=5)  # not used by the fit
    np.testing.assert_allclose(fk_tool(res.model, held_out), truth.T_cam_board(held_out),
                               atol=1e-6)  # fmt: skip
    for est, true in zip(mounts(res.model, truth.robot, eye_to_hand=True),
                         mounts(truth.chain(), truth.robot, eye_to_hand=True), strict=True):  # fmt: skip
        w, t = _errors(est.T, true.T)
        assert np.abs(w).max() < 1e-6 and np.abs(t).max() < 1e-6, est.what
    assert [m.what for m in mounts(res.model, truth.robot, eye_to_hand=True)] == [
        "base -> camera", "flange -> board"]  # fmt: skip


@pytest.mark.slow
def test_noisy_eye_to_hand_within_three_sigma(cell):
    truth, q = cell
    feats = project_views(truth, q, 0.1, np.random.default_rng(3))
    res = _calibrate(truth, q, feats)
    assert res.rms_px < 0.2  # 0.1 px per coordinate: 0.14 px 2-D
    sel = res.selection
    flat = np.arange(6 * (truth.robot.n + 1))
    by_name = dict(zip(param_names(flat), flat.tolist(), strict=True))
    free_idx = np.array([by_name[n] for n in sel.identified if not n.startswith("offset_j")])
    offsets = np.array([int(n[8:]) - 1 for n in sel.identified if n.startswith("offset_j")], int)
    cr = board_cramer_rao(truth.board, [res.camera], res.model, q, [feats], 0.1,
                          free_idx=free_idx, offset_joints=offsets, eye_to_hand=True)  # fmt: skip
    for n in FREE:
        z = (getattr(res.camera, n) - getattr(truth.camera, n)) / cr.camera_std[0][n]
        assert abs(z) < 3, (n, z)
    est = mounts(res.model, truth.robot, eye_to_hand=True, covariance=cr.covariance)
    for e, t in zip(est, mounts(truth.chain(), truth.robot, eye_to_hand=True), strict=True):
        w, d = _errors(e.T, t.T)
        assert e.sigma_rotation_rad is not None and e.sigma_xyz_m is not None
        z = np.r_[w / e.sigma_rotation_rad, d / e.sigma_xyz_m]
        assert np.all(np.abs(z) < 3), (e.what, z)
