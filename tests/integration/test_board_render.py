"""Rendered mono + ChArUco: a board in the MuJoCo scene (selfcal/sim/board_scene.py), photographed by one
camera from 12 viewpoints, detected and calibrated (selfcal/calibration/board/calibrate.py).

Acceptance (issue #12, without lens distortion until the lens model lands): every camera
parameter within 3 sigma of the truth, and against OpenCV on the same images: intrinsics within
2 sigma of ``cv2.calibrateCamera``'s and a reprojection RMS no higher. Measured (mujoco, EGL,
image noise 3 grey levels, seed 13): detected corners 0.06 px RMS from the analytic projection;
errors / sigma fx -0.24, mu -0.09, cx -1.61, cy -0.05 (over seeds 11-16 the largest was 2.75);
RMS 0.059 px, equal to OpenCV's to 1e-9 px (the same least-squares problem).
"""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

from selfcal.calibration.board.calibrate import calibrate_board
from selfcal.camera import Pinhole
from selfcal.sim.board_scene import board_scene_spec
from selfcal.sim.mj_camera import T_world_cam_cv, add_camera, intrinsics_from_model
from selfcal.sim.render import StereoRenderer
from selfcal.target import AprilGrid, Board, Charuco, Chessboard, CirclesGrid
from selfcal.target.board_views import random_board_poses
from selfcal.transforms import inv_pose, make_pose

W, H = 640, 480
BOARD = Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")
# printed face up on the table (board z, into the board, points down), principal point off centre
T_WORLD_BOARD = make_pose(np.diag([1.0, -1.0, -1.0]), np.array([0.3, 0.1, 0.0]))
CAMERA = Pinhole(800.0, 1.0, (W - 1) / 2 + 12, (H - 1) / 2 - 8, W, H)
NAMES = ("fx", "mu", "cx", "cy")


def render_views(board: Board, poses: list[np.ndarray], image_sigma: float, seed: int):
    """(images, the camera MuJoCo renders with, true T_cam_board (n, 4, 4)) of ``board`` lying
    at ``T_WORLD_BOARD`` seen by ``CAMERA`` from ``poses`` (T_cam_board)."""
    spec = board_scene_spec(board, T_WORLD_BOARD, (W, H))
    names = tuple(f"cam{i}" for i in range(len(poses)))
    for name, T in zip(names, poses, strict=True):
        add_camera(spec.worldbody, name, CAMERA, T_WORLD_BOARD @ inv_pose(T))
    model = spec.compile()
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    with StereoRenderer(model, W, H, camera_names=names) as r:
        images = r.render_all(data, image_sigma=image_sigma, rng=np.random.default_rng(seed))
    truth = intrinsics_from_model(model, names[0])
    T_cam_board = np.stack(
        [inv_pose(T_world_cam_cv(model, data, n)) @ T_WORLD_BOARD for n in names]
    )
    return images, truth, T_cam_board


@pytest.fixture(scope="module")
def rendered():
    """The 12 rendered views of the ChArUco, the true camera and board poses, and each view's
    detection (detected once for the two tests that read them)."""
    images, truth, T_cam_board = render_views(BOARD, random_board_poses(BOARD, 12, seed=13),
                                              3.0, 13)  # fmt: skip
    return [BOARD.detect(img) for img in images], truth, T_cam_board


@pytest.mark.parametrize(
    "board",
    [
        Chessboard((9, 6), 0.025),
        BOARD,
        CirclesGrid((4, 11), 0.02, 0.012),
        AprilGrid((6, 6), 0.025, 0.3),
    ],
    ids=lambda b: type(b).__name__,
)
def test_every_board_type_is_seen_where_it_is_in_the_scene(board):
    """Four views (tilts up to 30 deg) of each board type: a whole-board detector finds every
    feature of the views that hold the whole board, the others their visible part; corners
    agree with the analytic projection. Measured RMS (max) px: chessboard 0.064 (0.12), ChArUco
    0.058 (0.14), circles 0.069 (0.11), AprilGrid 0.078 (0.25); mean below 0.006 px."""
    images, truth, T_cam_board = render_views(
        board, random_board_poses(board, 4, seed=5, tilt_deg=30.0), 0.0, 5
    )
    _, pts = board.layout()
    e = []
    for img, T in zip(images, T_cam_board, strict=True):
        f = board.detect(img)
        if truth.in_image(truth.project(pts @ T[:3, :3].T + T[:3, 3]), 5.0).all():
            assert len(f) >= 0.9 * board.n_features  # the whole board is in view
        if len(f):
            e.append(f.uv - truth.project(board.points(f.ids) @ T[:3, :3].T + T[:3, 3]))
    e = np.concatenate(e)
    assert len(e) >= 2 * board.n_features  # two of the four views hold the whole board
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.2
    assert np.abs(e.mean(axis=0)).max() < 0.02


def test_rendered_corners_match_the_projection(rendered):
    found, truth, T_cam_board = rendered
    e = []
    for f, T in zip(found, T_cam_board, strict=True):
        assert len(f) >= 0.6 * BOARD.n_features
        X = BOARD.points(f.ids)
        e.append(f.uv - truth.project(X @ T[:3, :3].T + T[:3, 3]))
    e = np.concatenate(e)
    # measured 0.060 px RMS, mean (-0.0006, +0.0013) px
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.2
    assert np.abs(e.mean(axis=0)).max() < 0.005


def test_mono_charuco_calibration_reaches_the_truth_and_opencv(rendered):
    found, truth, T_cam_board = rendered
    res = calibrate_board(BOARD, found, W, H)
    for n in NAMES:
        assert abs(getattr(res.camera, n) - getattr(truth, n)) < 3 * res.std[n], n
    cv = res.opencv
    for n in ("fx", "fy", "cx", "cy"):
        assert abs(getattr(res.camera, n) - getattr(cv.camera, n)) < 2 * cv.std[n], n
    assert res.rms_all_px <= cv.rms_px * (1 + 1e-6)
    # the board poses, in metres: the board's geometry gives the scale (measured: positions
    # within 0.12 mm, rotations within 0.024 deg)
    np.testing.assert_allclose(res.T_cam_board[:, :3, 3], T_cam_board[:, :3, 3], atol=4e-4)
